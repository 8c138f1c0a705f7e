// The library facade (<hnnstereo/hnnstereo.h>) over the per-folder libraries.
#include "hnnstereo/hnnstereo.h"

#include <iostream>
#include <stdexcept>

#include "api/match_pipeline.h"
#include "api/matcher_settings.h"
#include "calib/calibration.h"
#include "common/image.h"
#include "vision/sensing/position_sensing.h"

#ifndef HNNSTEREO_VERSION
#define HNNSTEREO_VERSION "0.0.0"
#endif

namespace hnnstereo {

const char* Version() { return HNNSTEREO_VERSION; }

std::vector<std::string> MatcherOptionNames() { return api::OverrideNames(); }

std::vector<std::string> PresetNames() {
  std::vector<std::string> names;
  for (const vision::MatcherPreset& preset : vision::AllPresets()) names.push_back(preset.name);
  return names;
}

// ---- Calibration --------------------------------------------------------------------------

struct Calibration::Impl {
  calib::StereoCalibration calibration;
};

struct CalibrationAccess {
  static Calibration Make(calib::StereoCalibration calibration) {
    Calibration result;
    result.impl_ = std::make_shared<const Calibration::Impl>(Calibration::Impl{std::move(calibration)});
    return result;
  }
  static const calib::StereoCalibration& Get(const Calibration& calibration) {
    if (calibration.empty()) throw std::invalid_argument("the calibration is empty (load one with LoadCalibration)");
    return calibration.impl_->calibration;
  }
};

Calibration::Calibration() = default;
bool Calibration::empty() const { return impl_ == nullptr; }
Eigen::Matrix<double, 3, 4> Calibration::P1() const { return CalibrationAccess::Get(*this).P1; }
Eigen::Matrix<double, 3, 4> Calibration::P2() const { return CalibrationAccess::Get(*this).P2; }
Eigen::Matrix3d Calibration::F() const { return CalibrationAccess::Get(*this).F; }
Eigen::Vector3d Calibration::C1() const { return CalibrationAccess::Get(*this).C1; }
Eigen::Vector3d Calibration::C2() const { return CalibrationAccess::Get(*this).C2; }
int Calibration::image_width() const { return CalibrationAccess::Get(*this).image_width; }
int Calibration::image_height() const { return CalibrationAccess::Get(*this).image_height; }
bool Calibration::rectified() const { return CalibrationAccess::Get(*this).rectified; }
bool Calibration::has_distortion() const {
  const auto& intrinsics = CalibrationAccess::Get(*this).intrinsics;
  return intrinsics && !intrinsics->D1.empty();
}

Calibration LoadCalibration(const std::string& path) {
  return CalibrationAccess::Make(calib::LoadCalibration(path));
}

namespace {

// Both images as the CLI's working copies (CV_8U grey), same size.
std::pair<cv::Mat, cv::Mat> GreyPair(const cv::Mat& left, const cv::Mat& right) {
  if (left.empty()) throw std::invalid_argument("left image is empty");
  if (right.empty()) throw std::invalid_argument("right image is empty");
  if (left.dims != 2 || right.dims != 2) throw std::invalid_argument("images must be 2-D (rows x cols [x channels])");
  if (left.channels() > 4 || right.channels() > 4) {
    throw std::invalid_argument("images must have 1 (grey), 3 (BGR) or 4 (BGRA) channels");
  }
  cv::Mat left_grey = vision::GreyWorkingCopy(left);
  cv::Mat right_grey = vision::GreyWorkingCopy(right);
  if (left_grey.size() != right_grey.size()) {
    throw std::invalid_argument("left and right images differ in size: left is " +
                                std::to_string(left.cols) + "x" + std::to_string(left.rows) +
                                ", right is " + std::to_string(right.cols) + "x" +
                                std::to_string(right.rows));
  }
  return {left_grey, right_grey};
}

MatchResult ToResult(const vision::MatchReport& report, const api::MatcherSettings& settings) {
  MatchResult result;
  result.matches.reserve(report.matches.size());
  for (const vision::StereoMatch& m : report.matches) {
    result.matches.push_back({m.left.x(), m.left.y(), m.right.x(), m.right.y(), m.activation, m.confidence});
  }
  MatchReport& r = result.report;
  r.engine = report.solve.engine;
  r.device = report.solve.device;
  r.preset = settings.preset;
  r.notice = report.engine_notice;
  r.n_left = report.n_left;
  r.n_right = report.n_right;
  r.n_neurons = report.n_neurons;
  r.n_connections = report.n_connections;
  r.iterations = report.solve.iterations;
  r.energy_initial = report.solve.energy_initial;
  r.energy_final = report.solve.energy_final;
  const vision::TimingMs& t = report.timing_ms;
  r.timing_ms = {t.features, t.candidates, t.weights, t.solve, t.decode, t.total};
  r.json = api::MatchReportJson(report, settings.matcher, settings.preset, settings.refinement).dump();
  return result;
}

}  // namespace

// ---- Matcher ------------------------------------------------------------------------------

struct Matcher::Impl {
  api::MatcherSettings settings;
  std::unique_ptr<ocl::Runtime> runtime;
  std::string notice;
};

Matcher::Matcher() : Matcher("hnn-default") {}

Matcher::Matcher(const std::string& preset, const MatcherOverrides& overrides)
    : impl_(std::make_unique<Impl>()) {
  impl_->settings = api::ResolveMatcherSettings(preset, overrides, vision::MatcherOptions{});
  impl_->runtime = api::OpenRuntime(impl_->settings.matcher.engine, impl_->settings.device, &impl_->notice);
  if (!impl_->notice.empty()) std::cerr << "hnnstereo: notice: " << impl_->notice << "\n";
}

Matcher::~Matcher() = default;
Matcher::Matcher(Matcher&&) noexcept = default;
Matcher& Matcher::operator=(Matcher&&) noexcept = default;

const std::string& Matcher::preset() const { return impl_->settings.preset; }
std::string Matcher::device() const { return impl_->runtime ? impl_->runtime->description() : "cpu"; }
std::string Matcher::notice() const { return impl_->notice; }

MatchResult Matcher::Match(const cv::Mat& left, const cv::Mat& right, double max_disparity) {
  const auto [left_grey, right_grey] = GreyPair(left, right);
  api::MatcherSettings settings = impl_->settings;
  settings.matcher.candidates.rectified = true;
  settings.matcher.candidates.max_disparity = max_disparity;
  api::CheckMatchSetup(left_grey, right_grey, nullptr, settings.matcher, "left and right");
  if (auto error = settings.matcher.Check(); !error.empty()) {
    throw std::invalid_argument(api::InOptionNames(error, api::MatcherOptionNameTable()));
  }
  const vision::MatchReport report = api::RunMatchPipeline(
      left_grey, right_grey, nullptr, settings.matcher, settings.refinement, impl_->runtime.get());
  return ToResult(report, settings);
}

MatchResult Matcher::Match(const cv::Mat& left, const cv::Mat& right, const Calibration& calibration) {
  const calib::StereoCalibration& cal = CalibrationAccess::Get(calibration);
  const auto [left_grey, right_grey] = GreyPair(left, right);
  api::MatcherSettings settings = impl_->settings;
  if (cal.rectified) settings.matcher.candidates.rectified = true;
  api::CheckMatchSetup(left_grey, right_grey, &cal, settings.matcher, "left and right");
  api::UseFeatureNetworkUnlessRectified(settings.matcher.candidates.rectified, &settings);
  if (auto error = settings.matcher.Check(); !error.empty()) {
    throw std::invalid_argument(api::InOptionNames(error, api::MatcherOptionNameTable()));
  }
  const vision::MatchReport report = api::RunMatchPipeline(
      left_grey, right_grey, &cal, settings.matcher, settings.refinement, impl_->runtime.get());
  return ToResult(report, settings);
}

// ---- Position sensing ---------------------------------------------------------------------

SensingResult SensePositions(const cv::Mat& left, const cv::Mat& right, const Calibration& calibration,
                             const MatcherOverrides& overrides) {
  const calib::StereoCalibration& cal = CalibrationAccess::Get(calibration);
  const auto [left_grey, right_grey] = GreyPair(left, right);
  if (auto problem = cal.ImageSizeProblem(left_grey.cols, left_grey.rows); !problem.empty()) {
    throw std::invalid_argument("the calibration " + problem);
  }
  // `hnnstereo pick`'s settings (app/cell_sensing.cc): the same library resolution.
  const api::MatcherSettings settings =
      api::ResolvePickCellSettings(overrides, vision::PickCellMatcherOptions());
  vision::PositionSensingOptions options;
  options.matcher = settings.matcher;
  if (auto problem = options.Check(); !problem.empty()) throw std::invalid_argument(problem);
  SensingResult result;
  std::unique_ptr<ocl::Runtime> runtime =
      api::OpenRuntime(options.matcher.engine, settings.device, &result.notice);
  // A board calibration refers P to undistorted pixels: SensePositions senses through the lens.
  const vision::PositionSensingReport report =
      vision::SensePositions(left_grey, right_grey, cal, options, runtime.get());
  if (result.notice.empty()) result.notice = report.match.engine_notice;
  int id = 1;
  for (const vision::ObjectPose& pose : report.objects) {
    result.objects.push_back({id++, pose.centroid, pose.height_mm, pose.yaw_deg, pose.points});
  }
  result.json = vision::ObjectsJson(report, options).dump();
  return result;
}

}  // namespace hnnstereo
