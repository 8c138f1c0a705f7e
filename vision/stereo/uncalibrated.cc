#include "vision/stereo/uncalibrated.h"

#include <Eigen/SVD>
#include <chrono>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "calib/epipolar.h"
#include "vision/stereo/correlation.h"

namespace hnnstereo::vision {
namespace {

std::vector<Eigen::Vector2f> Corners(const cv::Mat& grey, const UncalibratedOptions& options) {
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(grey, corners, options.max_corners, options.corner_quality,
                          options.corner_min_distance_px);
  std::vector<Eigen::Vector2f> points;
  points.reserve(corners.size());
  for (const auto& c : corners) points.emplace_back(std::round(c.x), std::round(c.y));
  return points;
}

// For each point of `from`, the index of its best partner in `to` (or -1), by ZNCC within the
// search radius, with the confidence and ambiguity tests.
std::vector<int> BestPartners(const std::vector<Eigen::Vector2f>& from,
                              const std::vector<Eigen::Vector2f>& to, const ZnccMatcher& zncc,
                              bool from_is_left, double radius, const UncalibratedOptions& options) {
  std::vector<int> best(from.size(), -1);
  const double radius2 = radius * radius;
  for (std::size_t i = 0; i < from.size(); ++i) {
    float first = -2.0f, second = -2.0f;
    int first_index = -1;
    for (std::size_t k = 0; k < to.size(); ++k) {
      if ((from[i] - to[k]).cast<double>().squaredNorm() > radius2) continue;
      const float score = from_is_left ? zncc(from[i], to[k]) : zncc(to[k], from[i]);
      if (score > first) {
        second = first;
        first = score;
        first_index = static_cast<int>(k);
      } else if (score > second) {
        second = score;
      }
    }
    if (first >= options.min_correlation && first - second >= options.min_margin) {
      best[i] = first_index;
    }
  }
  return best;
}

}  // namespace

std::string UncalibratedOptions::Check() const {
  if (max_corners < 8) return "max_corners must be >= 8";
  if (zncc_window < 3 || zncc_window > 15 || zncc_window % 2 == 0) return "zncc_window must be odd, 3..15";
  if (!(max_shift_fraction > 0.0 && max_shift_fraction <= 1.0)) return "max_shift_fraction must be in (0, 1]";
  return ransac.Check();
}

calib::StereoCalibration CanonicalCamerasFromFundamental(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU);
  const Eigen::Vector3d e2 = svd.matrixU().col(2);  // F^T e2 = 0
  calib::StereoCalibration calibration;
  calibration.P1.setZero();
  calibration.P1.leftCols<3>().setIdentity();
  calibration.P2.leftCols<3>() = calib::CrossProductMatrix(e2) * F;
  calibration.P2.col(3) = e2;
  calibration.F = F / F.norm();
  calibration.C1 = calib::CameraCentre(calibration.P1);
  calibration.C2 = calib::CameraCentre(calibration.P2);
  calibration.units = "projective";
  return calibration;
}

UncalibratedReport EstimateEpipolarGeometry(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                            const UncalibratedOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  std::vector<Eigen::Vector2d> left_points, right_points;
  if (options.putative == PutativeMatches::kOrb) {
    // ORB keypoints and descriptors (Rublee et al. 2011), Lowe's ratio test, mutual best.
    cv::Ptr<cv::ORB> orb = cv::ORB::create(options.max_corners);
    std::vector<cv::KeyPoint> left_keys, right_keys;
    cv::Mat left_descriptors, right_descriptors;
    orb->detectAndCompute(left_grey, cv::noArray(), left_keys, left_descriptors);
    orb->detectAndCompute(right_grey, cv::noArray(), right_keys, right_descriptors);
    if (!left_descriptors.empty() && !right_descriptors.empty()) {
      cv::BFMatcher matcher(cv::NORM_HAMMING);
      std::vector<std::vector<cv::DMatch>> forward;
      std::vector<cv::DMatch> backward;
      matcher.knnMatch(left_descriptors, right_descriptors, forward, 2);
      matcher.match(right_descriptors, left_descriptors, backward);
      for (const auto& pair : forward) {
        if (pair.size() < 2 || pair[0].distance > options.orb_ratio * pair[1].distance) continue;
        if (backward[static_cast<std::size_t>(pair[0].trainIdx)].trainIdx != pair[0].queryIdx) continue;
        const cv::Point2f l = left_keys[static_cast<std::size_t>(pair[0].queryIdx)].pt;
        const cv::Point2f r = right_keys[static_cast<std::size_t>(pair[0].trainIdx)].pt;
        left_points.emplace_back(l.x, l.y);
        right_points.emplace_back(r.x, r.y);
      }
    }
  } else {
    const std::vector<Eigen::Vector2f> left = Corners(left_grey, options);
    const std::vector<Eigen::Vector2f> right = Corners(right_grey, options);
    const ZnccMatcher zncc(left_grey, right_grey, options.zncc_window);
    const double radius = options.max_shift_fraction * left_grey.cols;
    const std::vector<int> left_to_right = BestPartners(left, right, zncc, true, radius, options);
    const std::vector<int> right_to_left = BestPartners(right, left, zncc, false, radius, options);
    for (std::size_t i = 0; i < left.size(); ++i) {
      const int k = left_to_right[i];
      if (k < 0 || right_to_left[static_cast<std::size_t>(k)] != static_cast<int>(i)) continue;
      left_points.push_back(left[i].cast<double>());
      right_points.push_back(right[static_cast<std::size_t>(k)].cast<double>());
    }
  }
  UncalibratedReport report;
  report.n_putative = static_cast<int>(left_points.size());
  if (left_points.size() < 16) {
    throw std::runtime_error("cannot estimate F: only " + std::to_string(left_points.size()) +
                             " confident putative matches between the images (need 16); "
                             "give --calib or --rectified");
  }
  report.fundamental = calib::EstimateFundamentalRansac(left_points, right_points, options.ransac);
  if (!report.fundamental.success || report.fundamental.num_inliers < 12) {
    throw std::runtime_error("cannot estimate F from " + std::to_string(left_points.size()) +
                             " putative matches (" + report.fundamental.message +
                             "); give --calib or --rectified");
  }
  report.calibration = CanonicalCamerasFromFundamental(report.fundamental.F);
  report.calibration.image_width = left_grey.cols;
  report.calibration.image_height = left_grey.rows;
  report.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace hnnstereo::vision
