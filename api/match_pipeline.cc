#include "api/match_pipeline.h"

#include <chrono>
#include <stdexcept>
#include <string>

#include "vision/stereo/lens_matching.h"
#include "vision/stereo/match_io.h"
#include "vision/stereo/setup_checks.h"

namespace hnnstereo::api {

vision::MatchReport RunMatchPipeline(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                     const calib::StereoCalibration* calibration,
                                     const vision::MatcherOptions& options,
                                     const vision::RefinementOptions& refinement,
                                     ocl::Runtime* runtime) {
  // A board calibration refers P and F to undistorted pixels: match through the lens as points
  // (vision::LensRoute::kPoints, as `pick`), or on undistorted images when a refinement searches
  // image rows (the left-right check, the row sub-pixel fit); then report the matches in the
  // pixels of the images as given.
  const std::shared_ptr<const vision::StereoLens> lens =
      calibration ? vision::LensOf(*calibration) : nullptr;
  const bool through_points = lens && !options.candidates.rectified &&
                              !refinement.left_right_check && !refinement.subpixel;
  cv::Mat left = left_grey, right = right_grey;
  vision::MatcherOptions matcher = options;
  if (through_points) {
    matcher = vision::MatcherThroughLens(options, left_grey, right_grey, lens);
  } else if (lens) {
    left = vision::UndistortImage(left_grey, lens->left.K, lens->left.D);
    right = vision::UndistortImage(right_grey, lens->right.K, lens->right.D);
  }
  vision::MatchReport report = vision::MatchStereo(left, right, calibration, matcher, runtime);
  // timing_ms.total covers the refinements too (as vision::MatchWithPreset counts them).
  const auto refine_start = std::chrono::steady_clock::now();
  if (through_points) {
    vision::RefineMatchesThroughLens(left, right, *calibration, matcher, refinement, *lens, &report);
  } else {
    vision::RefineMatches(left, right, calibration, matcher, refinement, &report, runtime);
  }
  report.timing_ms.total +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - refine_start).count();
  if (lens) vision::MatchesToCapturedPixels(*lens, &report);
  return report;
}

nlohmann::json MatchReportJson(const vision::MatchReport& report, const vision::MatcherOptions& options,
                               const std::string& preset, const vision::RefinementOptions& refinement) {
  nlohmann::json json = vision::MatchReportJson(report, options);
  json["preset"] = preset;
  json["left_right_check"] = refinement.left_right_check;
  return json;
}

std::unique_ptr<ocl::Runtime> OpenRuntime(hnn::EngineKind engine, const std::string& device,
                                          std::string* notice) {
  if (engine != hnn::EngineKind::kOpenCL) {
    if (!device.empty()) {
      throw std::invalid_argument("--device '" + device + "' is for --engine opencl (the " +
                                  std::string(vision::EngineName(engine)) + " engine runs on the host)");
    }
    return nullptr;
  }
  const ocl::DeviceSelection from_environment = ocl::DeviceSelection::FromEnvironment();
  ocl::DeviceSelection selection = from_environment;
  if (!device.empty()) selection.device = device;
  std::string why_not;
  auto runtime = ocl::Runtime::Create(selection, &why_not);
  if (runtime) return runtime;
  if (selection.empty()) {
    // Nothing was asked for: the cpu engine runs the same dynamics (the report says so).
    if (notice) *notice = why_not + "; using the cpu engine";
    return nullptr;
  }
  // A device that was asked for and does not exist is an error, never a silent fallback.
  std::string asked;
  if (!device.empty()) {
    asked = "--device '" + device + "'";
  } else if (!from_environment.device.empty()) {
    asked = "HNNSTEREO_OPENCL_DEVICE='" + from_environment.device + "'";
  }
  if (!from_environment.platform.empty()) {
    asked += std::string(asked.empty() ? "" : " with ") + "HNNSTEREO_OPENCL_PLATFORM='" +
             from_environment.platform + "'";
  }
  throw std::invalid_argument(asked + ": " + why_not + " (see 'hnnstereo devices'; --engine cpu "
                              "runs without OpenCL)");
}

vision::PairComparison CheckMatchSetup(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                       const calib::StereoCalibration* calibration,
                                       const vision::MatcherOptions& options,
                                       const std::string& pair_name) {
  if (left_grey.empty() || right_grey.empty()) {
    throw std::invalid_argument(pair_name + ": an image is empty");
  }
  if (left_grey.size() != right_grey.size()) {
    throw std::invalid_argument(pair_name + " differ in size (" + std::to_string(left_grey.cols) +
                                "x" + std::to_string(left_grey.rows) + " and " +
                                std::to_string(right_grey.cols) + "x" +
                                std::to_string(right_grey.rows) + ")");
  }
  if (calibration) {
    if (auto problem = calibration->ImageSizeProblem(left_grey.cols, left_grey.rows);
        !problem.empty()) {
      throw std::invalid_argument("the calibration " + problem);
    }
  }
  vision::PairComparison comparison = vision::ComparePair(left_grey, right_grey);
  if (auto problem = vision::DistinctViewsProblem(comparison, pair_name); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (options.candidates.rectified && !options.candidates.dense) {
    const std::string problem = vision::DisparityRangeProblem(
        options.candidates.min_disparity, options.candidates.max_disparity, left_grey.cols);
    if (!problem.empty()) throw std::invalid_argument(problem);
  }
  return comparison;
}

}  // namespace hnnstereo::api
