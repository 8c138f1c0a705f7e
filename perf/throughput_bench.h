#pragma once
// The matching throughput harness behind `hnnstereo bench`: engines x problem sizes on one
// stereo pair, medians of warmed-up repeats, with OpenCV StereoSGBM timed on the same pair in
// the same run.

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "host/opencl_runtime.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::perf {

struct ThroughputBenchOptions {
  std::string left;              ///< left image of a rectified pair
  std::string right;             ///< right image
  std::string ground_truth;      ///< optional left disparity map (PNG/PGM) for a precision column
  double ground_truth_scale = 4; ///< stored value / scale = disparity (Middlebury 2003: 4)
  double max_disparity = 64;     ///< px
  /// --max-features of the sparse cases; 0 = every feature (the default match).
  std::vector<int> sparse_sizes = {500, 1000, 2000, 5000, 0};
  int dense_features = 60;       ///< features per image of the thesis-sized --dense case; 0 = none
  std::vector<hnn::EngineKind> engines = {hnn::EngineKind::kOpenCL, hnn::EngineKind::kCpu,
                                          hnn::EngineKind::kThesis};
  /// The opencl engine is run once per weight storage listed (engine label "opencl:<storage>"
  /// when more than one); the default runs it as the matcher options say.
  std::vector<hnn::WeightStorage> opencl_storages;
  bool measure_bandwidth = true;  ///< machine_read_gbps in the same run (the roofline)
  /// The thesis engine stores N x N weights: run it only on problems up to this many neurons.
  int thesis_max_neurons = 4000;
  /// Update limit of the thesis engine, in sweeps (x neurons): large enough that it stops by
  /// its own |dE| rule (the thesis's 20,000 updates were 100 sweeps of its 13 x 15 network).
  int thesis_max_sweeps = 200;
  /// Batch case: the pair cut into this many horizontal strips, one network each, solved by the
  /// opencl engine in one launch per step (SolveBatch) and one after another (Solve); 0 = none.
  int batch_networks = 8;
  int batch_features = 600;      ///< --max-features per strip image
  int repeats = 5;               ///< timed runs per case (median reported)
  int warmup = 1;                ///< untimed runs first (PoCL compiles per local size)
  vision::MatcherOptions matcher;  ///< base options (features, gating, energy, dynamics)
  /// Called after each run: (done, total, what).
  std::function<void(int, int, const std::string&)> progress;
  std::string Check() const;
};

/// Runs the benchmark and returns its JSON (see docs/benchmark.md for the fields).
nlohmann::json RunThroughputBench(const ThroughputBenchOptions& options, ocl::Runtime* runtime);

}  // namespace hnnstereo::perf
