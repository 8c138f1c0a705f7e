#include "vision/stereo/lens_distortion.h"

#include <Eigen/LU>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace hnnstereo::vision {
namespace {

cv::Mat CameraMatrix(const Eigen::Matrix3d& K) {
  cv::Mat camera;
  cv::eigen2cv(K, camera);
  return camera;
}

}  // namespace

cv::Mat UndistortImage(const cv::Mat& image, const Eigen::Matrix3d& K,
                       const std::vector<double>& distortion) {
  cv::Mat undistorted;
  cv::undistort(image, undistorted, CameraMatrix(K), cv::Mat(distortion, true), CameraMatrix(K));
  return undistorted;
}

cv::Mat RedistortImage(const cv::Mat& undistorted, const Eigen::Matrix3d& K,
                       const std::vector<double>& distortion) {
  std::vector<cv::Point2f> pixels;
  pixels.reserve(undistorted.total());
  for (int v = 0; v < undistorted.rows; ++v) {
    for (int u = 0; u < undistorted.cols; ++u) pixels.emplace_back(u, v);
  }
  std::vector<cv::Point2f> ideal;
  cv::undistortPoints(pixels, ideal, CameraMatrix(K), cv::Mat(distortion, true), cv::noArray(),
                      CameraMatrix(K), cv::TermCriteria(cv::TermCriteria::COUNT, 20, 0.0));
  const cv::Mat map(undistorted.rows, undistorted.cols, CV_32FC2, ideal.data());
  cv::Mat original;
  cv::remap(undistorted, original, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return original;
}

std::vector<Eigen::Vector2f> DistortPoints(const std::vector<Eigen::Vector2f>& undistorted,
                                           const Eigen::Matrix3d& K,
                                           const std::vector<double>& distortion) {
  if (undistorted.empty()) return {};
  // Normalised rays of the undistorted pixels, projected through (K, D) with no rotation.
  const Eigen::Matrix3d K_inv = K.inverse();
  std::vector<cv::Point3d> rays;
  rays.reserve(undistorted.size());
  for (const auto& p : undistorted) {
    const Eigen::Vector3d ray = K_inv * Eigen::Vector3d(p.x(), p.y(), 1.0);
    rays.emplace_back(ray.x() / ray.z(), ray.y() / ray.z(), 1.0);
  }
  std::vector<cv::Point2d> pixels;
  cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), CameraMatrix(K),
                    cv::Mat(distortion, true), pixels);
  std::vector<Eigen::Vector2f> out;
  out.reserve(pixels.size());
  for (const auto& p : pixels) out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  return out;
}

std::vector<Eigen::Vector2f> UndistortPoints(const std::vector<Eigen::Vector2f>& distorted,
                                             const Eigen::Matrix3d& K,
                                             const std::vector<double>& distortion) {
  if (distorted.empty()) return {};
  std::vector<cv::Point2d> pixels, undistorted;
  pixels.reserve(distorted.size());
  for (const auto& p : distorted) pixels.emplace_back(p.x(), p.y());
  cv::undistortPoints(pixels, undistorted, CameraMatrix(K), cv::Mat(distortion, true),
                      cv::noArray(), CameraMatrix(K));
  std::vector<Eigen::Vector2f> out;
  out.reserve(undistorted.size());
  for (const auto& p : undistorted) out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  return out;
}

std::string CameraLens::Check() const {
  if (D.size() == 4 || D.size() == 5 || D.size() == 8) return {};
  std::ostringstream out;
  out << "lens distortion needs 4, 5 or 8 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6]]), has "
      << D.size();
  return out.str();
}

Eigen::Vector2d CameraLens::Distort(const Eigen::Vector2d& undistorted_px) const {
  // Normalised coordinates (K with its skew), then OpenCV's radial (rational) and tangential
  // terms (cv::projectPoints).
  const double y = (undistorted_px.y() - K(1, 2)) / K(1, 1);
  const double x = (undistorted_px.x() - K(0, 2) - K(0, 1) * y) / K(0, 0);
  const auto d = [&](std::size_t i) { return i < D.size() ? D[i] : 0.0; };
  const double r2 = x * x + y * y, r4 = r2 * r2, r6 = r4 * r2;
  const double radial = (1.0 + d(0) * r2 + d(1) * r4 + d(4) * r6) /
                        (1.0 + d(5) * r2 + d(6) * r4 + d(7) * r6);
  const double xd = x * radial + 2.0 * d(2) * x * y + d(3) * (r2 + 2.0 * x * x);
  const double yd = y * radial + d(2) * (r2 + 2.0 * y * y) + 2.0 * d(3) * x * y;
  return {K(0, 0) * xd + K(0, 1) * yd + K(0, 2), K(1, 1) * yd + K(1, 2)};
}

Eigen::Matrix2d CameraLens::Jacobian(const Eigen::Vector2d& undistorted_px) const {
  constexpr double kHalfStep = 0.25;
  Eigen::Matrix2d J;
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::Vector2d step = kHalfStep * Eigen::Vector2d::Unit(axis);
    J.col(axis) = (Distort(undistorted_px + step) - Distort(undistorted_px - step)) / (2 * kHalfStep);
  }
  return J;
}

Eigen::Vector2d CameraLens::GradientAt(const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                       const Eigen::Vector2d& undistorted_px) const {
  const Eigen::Vector2d captured = GradientAtPixel(gradient_x, gradient_y, Distort(undistorted_px),
                                                   nullptr);
  return Jacobian(undistorted_px).transpose() * captured;
}

Eigen::Vector2d GradientAtPixel(const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                const Eigen::Vector2d& px, const CameraLens* lens) {
  if (lens != nullptr) return lens->GradientAt(gradient_x, gradient_y, px);
  if (!px.allFinite()) return Eigen::Vector2d::Zero();
  const long u = std::lround(px.x()), v = std::lround(px.y());
  if (u < 0 || v < 0 || u >= gradient_x.cols || v >= gradient_x.rows) return Eigen::Vector2d::Zero();
  const int iu = static_cast<int>(u), iv = static_cast<int>(v);
  return {gradient_x.at<float>(iv, iu), gradient_y.at<float>(iv, iu)};
}

std::string_view LensRouteName(LensRoute route) {
  return route == LensRoute::kPoints ? "points" : "images";
}

std::optional<LensRoute> ParseLensRoute(std::string_view name) {
  if (name == "points") return LensRoute::kPoints;
  if (name == "images") return LensRoute::kImages;
  return std::nullopt;
}

}  // namespace hnnstereo::vision
