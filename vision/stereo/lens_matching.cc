#include "vision/stereo/lens_matching.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

// ZNCC of two equal-size CV_32F windows (thesis eq. 6.9); 0 when either is flat.
double WindowZncc(const cv::Mat& a, const cv::Mat& b) {
  const cv::Scalar mean_a = cv::mean(a), mean_b = cv::mean(b);
  const cv::Mat da = a - mean_a[0], db = b - mean_b[0];
  const double norm = std::sqrt(da.dot(da) * db.dot(db));
  return norm > 1e-9 ? da.dot(db) / norm : 0.0;
}

cv::Mat WindowAt(const cv::Mat& image, int window, const Eigen::Vector2d& px) {
  cv::Mat patch;
  cv::getRectSubPix(image, cv::Size(window, window),
                    cv::Point2f(static_cast<float>(px.x()), static_cast<float>(px.y())), patch,
                    CV_32F);
  return patch;
}

Eigen::Vector2f Distorted(const CameraLens& lens, const Eigen::Vector2f& px) {
  return lens.Distort(px.cast<double>()).cast<float>();
}

}  // namespace

std::shared_ptr<const StereoLens> LensOf(const calib::StereoCalibration& calibration) {
  if (!calibration.intrinsics || calibration.intrinsics->D1.empty()) return nullptr;
  const calib::Intrinsics& in = *calibration.intrinsics;
  auto lens = std::make_shared<StereoLens>(StereoLens{{in.K1, in.D1}, {in.K2, in.D2}});
  for (const CameraLens* camera : {&lens->left, &lens->right}) {
    if (std::string problem = camera->Check(); !problem.empty()) {
      throw std::invalid_argument("the calibration's " + problem);
    }
  }
  return lens;
}

MatcherOptions MatcherThroughLens(MatcherOptions matcher, const cv::Mat& left,
                                  const cv::Mat& right, std::shared_ptr<const StereoLens> lens) {
  const uchar* left_pixels = left.data;
  const uchar* right_pixels = right.data;
  matcher.features.map_points = [lens, left_pixels, right_pixels](
                                    const cv::Mat& grey, std::vector<Eigen::Vector2f>* points) {
    const CameraLens* camera = grey.data == left_pixels    ? &lens->left
                               : grey.data == right_pixels ? &lens->right
                                                           : nullptr;
    if (camera == nullptr) {
      throw std::logic_error("MatcherThroughLens: features of an image that is not of the pair");
    }
    *points = UndistortPoints(*points, camera->K, camera->D);
  };
  matcher.data_term.lens = std::move(lens);
  return matcher;
}

void SubpixelAlongEpipolarLineThroughLens(const cv::Mat& left, const cv::Mat& right,
                                          const Eigen::Matrix3d& F, const StereoLens& lens,
                                          int window, StereoMatch* match) {
  const Eigen::Vector3d line = F * Eigen::Vector3d(match->left.x(), match->left.y(), 1.0);
  const double norm = line.head<2>().norm();
  if (!(norm > 0.0) || !line.allFinite()) return;
  const Eigen::Vector2d along = Eigen::Vector2d(-line.y(), line.x()) / norm;
  const Eigen::Vector2d foot = match->right.cast<double>();
  const cv::Mat left_window = WindowAt(left, window, lens.left.Distort(match->left.cast<double>()));
  double score[3];
  for (int k = -1; k <= 1; ++k) {
    score[k + 1] = WindowZncc(
        left_window, WindowAt(right, window, lens.right.Distort(foot + static_cast<double>(k) * along)));
  }
  const double curvature = score[0] - 2.0 * score[1] + score[2];
  if (curvature < 0.0) {
    const double offset = std::clamp(0.5 * (score[0] - score[2]) / curvature, -0.5, 0.5);
    match->right = (foot + offset * along).cast<float>();
  }
}

void RefineMatchesThroughLens(const cv::Mat& left, const cv::Mat& right,
                              const calib::StereoCalibration& calibration,
                              const MatcherOptions& matcher, const RefinementOptions& refinement,
                              const StereoLens& lens, MatchReport* report) {
  if (refinement.left_right_check || refinement.subpixel) {
    throw std::invalid_argument(
        "the point route of lens distortion refines along epipolar lines only (no left-right "
        "check, no row sub-pixel fit)");
  }
  // The snap is geometry alone (undistorted pixels): RefineMatches' own, without its fit.
  RefinementOptions snap = refinement;
  snap.epipolar_snap = refinement.epipolar_snap || refinement.epipolar_subpixel;
  snap.epipolar_subpixel = false;
  RefineMatches(left, right, &calibration, matcher, snap, report);
  if (!refinement.epipolar_subpixel) return;
  std::vector<StereoMatch>& matches = report->matches;
  cv::parallel_for_(cv::Range(0, static_cast<int>(matches.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      SubpixelAlongEpipolarLineThroughLens(left, right, calibration.F, lens, matcher.zncc_window,
                                           &matches[static_cast<std::size_t>(i)]);
    }
  });
}

void MatchesToCapturedPixels(const StereoLens& lens, MatchReport* report) {
  for (StereoMatch& match : report->matches) {
    match.left = Distorted(lens.left, match.left);
    match.right = Distorted(lens.right, match.right);
  }
  for (Eigen::Vector2f& point : report->left_features) point = Distorted(lens.left, point);
  for (Eigen::Vector2f& point : report->right_features) point = Distorted(lens.right, point);
}

}  // namespace hnnstereo::vision
