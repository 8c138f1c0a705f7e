#pragma once
// Linear triangulation from two projection matrices (thesis 6.2.9; Hartley & Zisserman 12.2).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

namespace hnnstereo::vision {

struct TriangulatedPoint {
  Eigen::Vector3d point_in_world;
  double reprojection_error_px;  ///< RMS over both images
  bool in_front;                 ///< in front of both cameras
};

/// Linear least squares (two rows per camera, SVD). nullopt when the rays are degenerate.
std::optional<TriangulatedPoint> TriangulateLinear(const Eigen::Matrix<double, 3, 4>& P1,
                                                   const Eigen::Matrix<double, 3, 4>& P2,
                                                   const Eigen::Vector2d& left_point,
                                                   const Eigen::Vector2d& right_point);

}  // namespace hnnstereo::vision
