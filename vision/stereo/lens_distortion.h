#pragma once
// Lens distortion at the image edge: a chessboard calibration (K, D) refers its P and F to
// undistorted pixels, while outputs are in the pixels of the input images as given.

#include <Eigen/Core>
#include <opencv2/core.hpp>
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

}  // namespace hnnstereo::vision
