#pragma once
// A captured network: the matching problem with the energy and dynamics it was solved under, in
// a small binary file (`match --save-network`), so that the engines can be replayed and timed on
// any OpenCL device without the images, OpenCV or the rest of the pipeline
// (perf/replay_network.cc: `hnnstereo_replay`, the GPU benchmark of docs/benchmark.md).
//
// Format "HNNET1" (little-endian, every field written on its own, no struct images): magic,
// the EnergyOptions and DynamicsOptions fields in declaration order, kind, dense, n_columns,
// the left points, then the candidates (left, column, right point, epipolar distance,
// correlation). Written with calib::WriteFileAtomically by the caller.

#include <string>

#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"

namespace hnnstereo::hnn {

struct CapturedNetwork {
  MatchingProblem problem;
  EnergyOptions energy;
  DynamicsOptions dynamics;
};

/// The file's bytes.
std::string SerializeNetwork(const MatchingProblem& problem, const EnergyOptions& energy,
                             const DynamicsOptions& dynamics);

/// Parses the bytes of a network file. Throws std::invalid_argument with a one-line reason on
/// anything malformed (wrong magic, truncated, counts beyond the bytes, options or a problem
/// that fail their Check()).
CapturedNetwork ParseNetwork(const std::string& bytes);

}  // namespace hnnstereo::hnn
