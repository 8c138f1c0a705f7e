#pragma once
// Brown-Conrady lens distortion for the synthetic cameras (`render --distortion`): an image is
// rendered so that a pinhole (ideal) point x_ideal appears at the distorted pixel OpenCV's model
// gives (cv::projectPoints with k1 k2 p1 p2 [k3]; Brown 1966, Conrady 1919). Each output pixel is
// mapped back to its ideal pixel (cv::undistortPoints iterated to 1e-12) and rendered there.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/calibration.h"

namespace hnnstereo::vision {

/// Empty when `distortion` is empty (no distortion) or 4-5 finite coefficients (k1, k2, p1, p2
/// [, k3]) with |k| <= 2 and |p| <= 0.1; otherwise a one-line reason.
std::string CheckDistortion(const std::vector<double>& distortion);

/// K of P = K [R | t] (RQ decomposition), positive diagonal, K(2,2) = 1.
Eigen::Matrix3d CameraMatrixOf(const calib::ProjectionMatrix& P);

/// The ideal (undistorted) pixels of distorted pixels, camera matrix K for both.
std::vector<cv::Point2d> IdealPixels(const std::vector<cv::Point2d>& distorted,
                                     const Eigen::Matrix3d& K,
                                     const std::vector<double>& distortion);

/// An ideal (pinhole) image resampled as the distorted camera sees it (bilinear; outside the
/// ideal image: the nearest border pixel). Returns `ideal` itself when `distortion` is empty.
cv::Mat DistortIdealImage(const cv::Mat& ideal, const Eigen::Matrix3d& K,
                          const std::vector<double>& distortion);

}  // namespace hnnstereo::vision
