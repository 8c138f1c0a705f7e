#pragma once
// Linear triangulation from two projection matrices (thesis 6.2.9; Hartley & Zisserman 12.2).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "calib/calibration.h"
#include "vision/stereo/stereo_matcher.h"

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

/// The 3D points of `matches` in the world frame of `calibration` (mm; a Middlebury calib.txt:
/// the left camera's frame). The matches are in the pixels of the images as given: with lens
/// distortion (intrinsics K1 D1 K2 D2) they are undistorted first, as P refers to undistorted
/// pixels. A match whose rays are degenerate, whose point lies behind a camera, or that
/// reprojects worse than `max_reprojection_error_px` (RMS over both images) gives no point;
/// `match_of_point` (optional) receives each point's index in `matches`.
std::vector<Eigen::Vector3d> MatchesInWorld(const calib::StereoCalibration& calibration,
                                            const std::vector<StereoMatch>& matches,
                                            double max_reprojection_error_px,
                                            std::vector<int>* match_of_point = nullptr);

}  // namespace hnnstereo::vision
