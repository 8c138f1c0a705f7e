#include "vision/stereo/lens_distortion.h"

#include <Eigen/LU>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

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

}  // namespace hnnstereo::vision
