#pragma once
// The match pipeline on grey images, shared by `hnnstereo match` and the library facade (one
// code path): undistort when the calibration carries lens distortion, MatchStereo, the preset's
// refinements, then the matches back in the pixels of the images as given.

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "api/matcher_settings.h"
#include "calib/calibration.h"
#include "host/opencl_runtime.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/setup_checks.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::api {

/// `calibration` may be null for a rectified pair (options.candidates.rectified). `runtime` may
/// be null (the opencl engine then falls back to cpu with a notice in the report). Throws as
/// vision::MatchStereo does.
vision::MatchReport RunMatchPipeline(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                     const calib::StereoCalibration* calibration,
                                     const vision::MatcherOptions& options,
                                     const vision::RefinementOptions& refinement,
                                     ocl::Runtime* runtime);

/// REPORT.json (vision::MatchReportJson) plus the preset and whether the left-right check ran.
nlohmann::json MatchReportJson(const vision::MatchReport& report, const vision::MatcherOptions& options,
                               const std::string& preset, const vision::RefinementOptions& refinement);

/// The one device policy of the CLI, the facade and Python: the OpenCL runtime for `engine` ==
/// opencl on `device` (empty = HNNSTEREO_OPENCL_DEVICE / _PLATFORM or the first device);
/// nullptr for the other engines, or when no device exists and none was asked for (the reason
/// in `notice`; the cpu engine runs the same dynamics). Throws std::invalid_argument when a
/// device was asked for and does not exist, or `device` is given with another engine.
std::unique_ptr<ocl::Runtime> OpenRuntime(hnn::EngineKind engine, const std::string& device,
                                          std::string* notice);

/// The checks every match runs before any work, so `match`, the facade and Python refuse alike:
/// both images non-empty and the same size, the calibration's image size, two distinct views
/// (vision::DistinctViewsProblem) and, for a rectified pair, a disparity range inside the image
/// (vision::DisparityRangeProblem). `pair_name` names the images in messages ("--left and
/// --right"). Returns the pair comparison (its looks_swapped warns). Throws
/// std::invalid_argument.
vision::PairComparison CheckMatchSetup(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                       const calib::StereoCalibration* calibration,
                                       const vision::MatcherOptions& options,
                                       const std::string& pair_name);

}  // namespace hnnstereo::api
