#pragma once
// Epipolar geometry as pure functions over Eigen (no I/O, no globals).
// Convention everywhere: x2^T F x1 = 0, image 1 = left; the right-image epipolar
// line of a left point x1 is l = F x1 (Hartley & Zisserman, "Multiple View Geometry", 9.2).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hnnstereo::calib {

/// Perpendicular distance in pixels from `right_point` to the epipolar line F * left_point
/// (thesis eq. 6.14, tau_ik). Returns +infinity when the line is degenerate (F x1 ~ 0).
double EpipolarDistancePx(const Eigen::Matrix3d& F, const Eigen::Vector2d& left_point,
                          const Eigen::Vector2d& right_point);

/// The right-image epipolar line (a, b, c) of `left_point`, scaled so that a^2 + b^2 = 1
/// (then a*x + b*y + c is a signed distance). Zero vector when degenerate.
Eigen::Vector3d EpipolarLineInRight(const Eigen::Matrix3d& F, const Eigen::Vector2d& left_point);

/// The camera centre C (P C = 0) as a Euclidean 3D point, from the right null vector of P.
Eigen::Vector3d CameraCentre(const Eigen::Matrix<double, 3, 4>& P);

/// F exactly from two projection matrices: F = [e2]_x P2 P1^+ (H&Z eq. 9.1), with e2 = P2 C1.
/// Scaled to unit Frobenius norm. x2^T F x1 = 0 for x1 = P1 X, x2 = P2 X.
Eigen::Matrix3d FundamentalFromProjections(const Eigen::Matrix<double, 3, 4>& P1,
                                           const Eigen::Matrix<double, 3, 4>& P2);

/// The 3x3 skew-symmetric matrix [v]_x with [v]_x w = v x w.
Eigen::Matrix3d CrossProductMatrix(const Eigen::Vector3d& v);

}  // namespace hnnstereo::calib
