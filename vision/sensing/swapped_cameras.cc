#include "vision/sensing/swapped_cameras.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "vision/sensing/position_sensing.h"

namespace hnnstereo::vision {
namespace {

// Up to 24 strong-gradient pixels: the strongest of each 40 px cell, strongest first.
std::vector<Eigen::Vector2d> StrongPoints(const cv::Mat& grey) {
  cv::Mat gx, gy, magnitude;
  cv::Sobel(grey, gx, CV_32F, 1, 0);
  cv::Sobel(grey, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, magnitude);
  constexpr int kCell = 40, kBorder = 12;
  std::vector<std::pair<double, Eigen::Vector2d>> strongest;
  for (int y = kBorder; y + kCell <= grey.rows - kBorder; y += kCell) {
    for (int x = kBorder; x + kCell <= grey.cols - kBorder; x += kCell) {
      double best = 0.0;
      cv::Point at;
      cv::minMaxLoc(magnitude(cv::Rect(x, y, kCell, kCell)), nullptr, &best, nullptr, &at);
      if (best > 100.0) strongest.push_back({best, Eigen::Vector2d(x + at.x, y + at.y)});
    }
  }
  std::sort(strongest.begin(), strongest.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Eigen::Vector2d> points;
  for (std::size_t k = 0; k < strongest.size() && k < 24; ++k) points.push_back(strongest[k].second);
  return points;
}

}  // namespace

SwapComparison CompareWithSwappedCameras(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                         const calib::StereoCalibration& calibration,
                                         std::pair<double, double> z_range_mm) {
  if (left_grey.empty() || left_grey.type() != CV_8UC1 || right_grey.size() != left_grey.size()) {
    throw std::invalid_argument("CompareWithSwappedCameras needs two 8-bit grey images of one size");
  }
  ProbeOptions options;
  options.z_range_mm = z_range_mm;
  // Each direction probes the strongest points of its own first image.
  std::vector<double> given, other;
  for (const Eigen::Vector2d& point : StrongPoints(left_grey)) {
    const ProbeReport probe = ProbePoint(left_grey, right_grey, calibration, point, options);
    if (probe.positions_tested > 0) given.push_back(probe.found ? probe.zncc : 0.0);
  }
  for (const Eigen::Vector2d& point : StrongPoints(right_grey)) {
    // The hypothesis "the images were given the wrong way round": the right image is the one
    // that P1 saw.
    const ProbeReport probe = ProbePoint(right_grey, left_grey, calibration, point, options);
    if (probe.positions_tested > 0) other.push_back(probe.found ? probe.zncc : 0.0);
  }
  SwapComparison result;
  result.points = static_cast<int>(std::min(given.size(), other.size()));
  if (given.empty() || other.empty()) return result;
  auto median = [](std::vector<double> values) {
    std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
    return values[values.size() / 2];
  };
  result.as_given_zncc = median(given);
  result.swapped_zncc = median(other);
  result.looks_swapped = result.points >= 8 && result.swapped_zncc >= 0.7 &&
                         result.swapped_zncc >= result.as_given_zncc + 0.15;
  return result;
}

}  // namespace hnnstereo::vision
