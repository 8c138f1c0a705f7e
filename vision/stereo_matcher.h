#pragma once
// The whole match: features -> candidates -> weights -> dynamics -> decoded matches. One call
// that `match`, `bench` and `eval` share; a drop-in fast matcher for the pick cell.

#include <Eigen/Core>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "host/decode.h"
#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/opencl_runtime.h"
#include "host/solve_report.h"
#include "vision/candidates.h"
#include "vision/features.h"

namespace hnnstereo::vision {

std::string_view EngineName(hnn::EngineKind engine);
std::optional<hnn::EngineKind> ParseEngine(std::string_view name);

struct MatcherOptions {
  FeatureOptions features;          ///< same detector on both images
  CandidateOptions candidates;
  int zncc_window = 7;              ///< thesis: 7 (or 5)
  hnn::EnergyOptions energy;
  hnn::DynamicsOptions dynamics;
  hnn::DecodeOptions decode;
  hnn::EngineKind engine = hnn::EngineKind::kOpenCL;
  std::size_t memory_budget_bytes = hnn::kDefaultMemoryBudgetBytes;
  std::string Check() const;
};

struct StereoMatch {
  Eigen::Vector2f left;
  Eigen::Vector2f right;
  float activation;  ///< the winner's final V (saturates near 1: not a ranking)
  int left_index;
  int column;
  /// In [0, 1], higher = more likely correct; ranks matches (docs/accuracy.md, "Confidence").
  float confidence = 0.0f;
};

struct TimingMs {
  double features = 0, candidates = 0, weights = 0, solve = 0, decode = 0, total = 0;
};

struct MatchReport {
  std::vector<StereoMatch> matches;
  std::vector<Eigen::Vector2f> left_features, right_features;
  hnn::SolveReport solve;
  int n_left = 0, n_right = 0, n_neurons = 0;
  std::int64_t n_connections = 0;
  std::string engine_notice;  ///< e.g. why the opencl engine fell back to cpu
  TimingMs timing_ms;
};

/// Runs the matcher on CV_8U grey images of equal size. `calibration` may be null only for
/// rectified pairs. `runtime` is used by the opencl engine; when it is null that engine falls
/// back to cpu and says so in engine_notice. Throws std::invalid_argument / std::runtime_error
/// with a one-line reason (no features, no candidates, over the memory budget...).
MatchReport MatchStereo(const cv::Mat& left_grey, const cv::Mat& right_grey,
                        const calib::StereoCalibration* calibration, const MatcherOptions& options,
                        ocl::Runtime* runtime);

}  // namespace hnnstereo::vision
