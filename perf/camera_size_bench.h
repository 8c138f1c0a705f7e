#pragma once
// Camera-sized cases of `hnnstereo bench --camera-sizes`: the benchmark pair upsampled to each
// size (bicubic, disparity range scaled), the whole match of `match` (MatchStereo and the
// preset's refinements) against OpenCV StereoSGBM on the same pair in the same run, stage times,
// peak memory and the time per 1,000 left features - how the cost grows with the work.

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "host/opencl_runtime.h"
#include "vision/stereo/matcher_presets.h"

namespace hnnstereo::perf {

struct CameraSizeBenchOptions {
  std::vector<double> megapixels = {0.3, 1.3, 3.0, 5.0};  ///< sizes of the upsampled pair
  double max_disparity = 64;  ///< of the pair as given (px); scaled with each size
  int repeats = 3;            ///< timed runs per size (median reported), after one warm-up
  vision::MatcherPreset preset;
  /// Called after each run: (done, total, what).
  std::function<void(int, int, const std::string&)> progress;
  std::string Check() const;
};

/// Runs the cases on the CV_8U grey pair; JSON: "camera_sizes" rows and
/// "ms_per_1000_features_spread" (largest / smallest over the sizes).
nlohmann::json RunCameraSizeBench(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                  const CameraSizeBenchOptions& options, ocl::Runtime* runtime);

}  // namespace hnnstereo::perf
