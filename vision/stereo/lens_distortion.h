#pragma once
// Lens distortion: a board calibration (K, D) refers its P and F to undistorted pixels, while
// the images and every output are in the pixels of the images as captured. Both ways between
// them (images resampled, points mapped) and the lens model that maps a single point.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hnnstereo::vision {

/// The image resampled without lens distortion, keeping K as the camera matrix.
cv::Mat UndistortImage(const cv::Mat& image, const Eigen::Matrix3d& K,
                       const std::vector<double>& distortion);

/// An image in undistorted pixels (camera matrix K; e.g. an overlay drawn on UndistortImage's
/// output) resampled back to the pixels of the original image: each original pixel takes the
/// undistorted image at its UndistortPoints position (bilinear).
cv::Mat RedistortImage(const cv::Mat& undistorted, const Eigen::Matrix3d& K,
                       const std::vector<double>& distortion);

/// Undistorted pixels (camera matrix K) back to the distorted pixels of the original image.
std::vector<Eigen::Vector2f> DistortPoints(const std::vector<Eigen::Vector2f>& undistorted,
                                           const Eigen::Matrix3d& K,
                                           const std::vector<double>& distortion);

/// Distorted pixels of the original image to undistorted pixels (camera matrix K): the inverse
/// of DistortPoints (cv::undistortPoints' iterative solution).
std::vector<Eigen::Vector2f> UndistortPoints(const std::vector<Eigen::Vector2f>& distorted,
                                             const Eigen::Matrix3d& K,
                                             const std::vector<double>& distortion);

/// One camera's lens: camera matrix K and Brown-Conrady coefficients D in OpenCV's order (k1,
/// k2, p1, p2[, k3[, k4, k5, k6]]: 4, 5 or 8 of them; Check()). Maps the undistorted pixels
/// that P and F refer to (camera matrix K) to the pixels of the image as captured, in closed
/// form - the point route's way of reading the captured image at a match's point.
struct CameraLens {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  std::vector<double> D;
  /// Empty when the model is one Distort evaluates; otherwise why not.
  std::string Check() const;
  /// The captured pixel of an undistorted pixel (OpenCV's projectPoints model).
  Eigen::Vector2d Distort(const Eigen::Vector2d& undistorted_px) const;
};

/// The captured image's gradient (`gradient_x`, `gradient_y`, CV_32F, e.g. 3 x 3 Sobel) per
/// pixel of the undistorted frame of the same size (camera matrix K): at each pixel, the
/// gradient at the captured pixel nearest its ray (cv::initUndistortRectifyMap), times J^T,
/// J = d captured / d undistorted from the map's central differences (chain rule), so that it
/// dots with directions taken in undistorted pixels. A lookup table, not a resampling: no
/// gradient is interpolated. Zero where the captured pixel lies outside the image. The outputs
/// may be the inputs.
void GradientsPerUndistortedPixel(const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                  const CameraLens& lens, cv::Mat* undistorted_x,
                                  cv::Mat* undistorted_y);

/// Both cameras' lenses (left, right), from a calibration's K1 D1, K2 D2.
struct StereoLens {
  CameraLens left, right;
};

/// How sensing treats a calibration with distortion (D1, D2).
enum class LensRoute {
  /// Features detected on the captured images, their points undistorted (UndistortPoints) for
  /// the epipolar gate, the network's geometry, triangulation and poses; every window and
  /// gradient read from the captured images at the captured pixels (StereoLens).
  kPoints,
  /// Both images resampled without distortion first (UndistortImage), then sensed as pinhole
  /// images.
  kImages,
};

/// "points" or "images".
std::string_view LensRouteName(LensRoute route);
std::optional<LensRoute> ParseLensRoute(std::string_view name);

}  // namespace hnnstereo::vision
