#include "vision/synth/lens_model.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace hnnstereo::vision {

std::string CheckDistortion(const std::vector<double>& distortion) {
  if (distortion.empty()) return {};
  std::ostringstream out;
  if (distortion.size() != 4 && distortion.size() != 5) {
    out << "--distortion needs k1,k2,p1,p2[,k3] (4 or 5 numbers, got " << distortion.size() << ")";
    return out.str();
  }
  for (std::size_t i = 0; i < distortion.size(); ++i) {
    const bool tangential = i == 2 || i == 3;
    if (!std::isfinite(distortion[i]) || std::abs(distortion[i]) > (tangential ? 0.1 : 2.0)) {
      out << "--distortion coefficient " << i + 1 << " must be finite and within +-"
          << (tangential ? "0.1 (p1, p2)" : "2 (k1, k2, k3)") << " (is " << distortion[i] << ")";
      return out.str();
    }
  }
  return {};
}

Eigen::Matrix3d CameraMatrixOf(const calib::ProjectionMatrix& P) {
  cv::Mat M, K, R;
  cv::eigen2cv(Eigen::Matrix3d(P.leftCols<3>()), M);
  cv::RQDecomp3x3(M, K, R);
  Eigen::Matrix3d camera;
  cv::cv2eigen(K, camera);
  for (int i = 0; i < 3; ++i) {
    if (camera(i, i) < 0.0) camera.col(i) *= -1.0;  // K R = (K S)(S R), S = diag(+-1)
  }
  return camera / camera(2, 2);
}

std::vector<cv::Point2d> IdealPixels(const std::vector<cv::Point2d>& distorted,
                                     const Eigen::Matrix3d& K,
                                     const std::vector<double>& distortion) {
  if (distorted.empty()) return {};
  cv::Mat camera;
  cv::eigen2cv(K, camera);
  std::vector<cv::Point2d> ideal;
  // 20 fixed-point steps, not OpenCV's default 5: each shrinks the error by about 2 |k1| r^2
  // (0.07 at the corners for k1 = -0.25), so the renderer's model is exact to float precision.
  cv::undistortPoints(distorted, ideal, camera, cv::Mat(distortion, true), cv::noArray(), camera,
                      cv::TermCriteria(cv::TermCriteria::COUNT, 20, 0.0));
  return ideal;
}

cv::Mat DistortIdealImage(const cv::Mat& ideal, const Eigen::Matrix3d& K,
                          const std::vector<double>& distortion) {
  if (distortion.empty()) return ideal;
  cv::Mat map_x(ideal.size(), CV_32F), map_y(ideal.size(), CV_32F);
  for (int v = 0; v < ideal.rows; ++v) {
    std::vector<cv::Point2d> row;
    for (int u = 0; u < ideal.cols; ++u) row.emplace_back(u, v);
    const std::vector<cv::Point2d> mapped = IdealPixels(row, K, distortion);
    for (int u = 0; u < ideal.cols; ++u) {
      map_x.at<float>(v, u) = static_cast<float>(mapped[static_cast<std::size_t>(u)].x);
      map_y.at<float>(v, u) = static_cast<float>(mapped[static_cast<std::size_t>(u)].y);
    }
  }
  cv::Mat distorted;
  cv::remap(ideal, distorted, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return distorted;
}

}  // namespace hnnstereo::vision
