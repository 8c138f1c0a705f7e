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

void GradientsPerUndistortedPixel(const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                  const CameraLens& lens, cv::Mat* undistorted_x,
                                  cv::Mat* undistorted_y) {
  const cv::Size size = gradient_x.size();
  cv::Mat map_x, map_y;  // the captured pixel of each undistorted pixel
  cv::initUndistortRectifyMap(CameraMatrix(lens.K), cv::Mat(lens.D, true), cv::noArray(),
                              CameraMatrix(lens.K), size, CV_32FC1, map_x, map_y);
  // New buffers: the outputs may be the inputs.
  cv::Mat out_x(size, CV_32F, cv::Scalar(0)), out_y(size, CV_32F, cv::Scalar(0));
  cv::parallel_for_(cv::Range(0, size.height), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      const int v0 = std::max(v - 1, 0), v1 = std::min(v + 1, size.height - 1);
      for (int u = 0; u < size.width; ++u) {
        const long cu = std::lround(map_x.at<float>(v, u)), cv = std::lround(map_y.at<float>(v, u));
        if (cu < 0 || cv < 0 || cu >= size.width || cv >= size.height) continue;
        const float gx = gradient_x.at<float>(static_cast<int>(cv), static_cast<int>(cu));
        const float gy = gradient_y.at<float>(static_cast<int>(cv), static_cast<int>(cu));
        const int u0 = std::max(u - 1, 0), u1 = std::min(u + 1, size.width - 1);
        // Columns of J: the captured pixel's change per undistorted pixel in u, then in v.
        const float du = static_cast<float>(std::max(u1 - u0, 1));
        const float dv = static_cast<float>(std::max(v1 - v0, 1));
        const float j00 = (map_x.at<float>(v, u1) - map_x.at<float>(v, u0)) / du;
        const float j10 = (map_y.at<float>(v, u1) - map_y.at<float>(v, u0)) / du;
        const float j01 = (map_x.at<float>(v1, u) - map_x.at<float>(v0, u)) / dv;
        const float j11 = (map_y.at<float>(v1, u) - map_y.at<float>(v0, u)) / dv;
        out_x.at<float>(v, u) = j00 * gx + j10 * gy;
        out_y.at<float>(v, u) = j01 * gx + j11 * gy;
      }
    }
  });
  *undistorted_x = out_x;
  *undistorted_y = out_y;
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
