#include "api/match_pipeline.h"

#include <chrono>

#include "vision/stereo/lens_distortion.h"
#include "vision/stereo/match_io.h"

namespace hnnstereo::api {

vision::MatchReport RunMatchPipeline(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                     const calib::StereoCalibration* calibration,
                                     const vision::MatcherOptions& options,
                                     const vision::RefinementOptions& refinement,
                                     ocl::Runtime* runtime) {
  // A chessboard calibration refers P and F to undistorted pixels: match on undistorted images,
  // then report the matches in the pixels of the images as given.
  cv::Mat left = left_grey, right = right_grey;
  const calib::Intrinsics* lens =
      calibration && calibration->intrinsics && !calibration->intrinsics->D1.empty()
          ? &*calibration->intrinsics : nullptr;
  if (lens) {
    left = vision::UndistortImage(left_grey, lens->K1, lens->D1);
    right = vision::UndistortImage(right_grey, lens->K2, lens->D2);
  }
  vision::MatchReport report = vision::MatchStereo(left, right, calibration, options, runtime);
  // timing_ms.total covers the refinements too (as vision::MatchWithPreset counts them).
  const auto refine_start = std::chrono::steady_clock::now();
  vision::RefineMatches(left, right, calibration, options, refinement, &report);
  report.timing_ms.total +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - refine_start).count();
  if (lens) {
    std::vector<Eigen::Vector2f> lefts, rights;
    for (const auto& m : report.matches) {
      lefts.push_back(m.left);
      rights.push_back(m.right);
    }
    lefts = vision::DistortPoints(lefts, lens->K1, lens->D1);
    rights = vision::DistortPoints(rights, lens->K2, lens->D2);
    for (std::size_t t = 0; t < report.matches.size(); ++t) {
      report.matches[t].left = lefts[t];
      report.matches[t].right = rights[t];
    }
    report.left_features = vision::DistortPoints(report.left_features, lens->K1, lens->D1);
    report.right_features = vision::DistortPoints(report.right_features, lens->K2, lens->D2);
  }
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
  if (engine != hnn::EngineKind::kOpenCL) return nullptr;
  ocl::DeviceSelection selection = ocl::DeviceSelection::FromEnvironment();
  if (!device.empty()) selection.device = device;
  std::string why_not;
  auto runtime = ocl::Runtime::Create(selection, &why_not);
  if (!runtime && notice) *notice = why_not + "; using the cpu engine";
  return runtime;
}

}  // namespace hnnstereo::api
