#pragma once
// World (table) to robot-base frame: fitted from three or more touched points by the
// least-squares rigid transform (Umeyama 1991, without scale; the Kabsch solution), with its RMS.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

namespace hnnstereo::robot {

struct FrameFitOptions {
  double max_rms_mm = 2.0;  ///< refuse a fit whose residual RMS exceeds this (mm)
  /// Refuse degenerate point sets: the second singular value of the centred points must be at
  /// least this fraction of the first (collinear or coincident points cannot fix a rotation).
  double min_spread_ratio = 0.02;
  std::string Check() const;
};

struct FrameFitReport {
  Eigen::Isometry3d robot_from_world = Eigen::Isometry3d::Identity();
  double rms_mm = 0.0;             ///< residual RMS over the points
  double max_residual_mm = 0.0;
  int n_points = 0;
};

/// Fits robot_from_world with robot_points[i] ~ robot_from_world * world_points[i].
/// Throws std::invalid_argument with a one-line reason for fewer than 3 points, mismatched
/// sizes, non-finite values, a degenerate set, or an RMS over the limit.
FrameFitReport FitRobotFromWorld(const std::vector<Eigen::Vector3d>& world_points,
                                 const std::vector<Eigen::Vector3d>& robot_points,
                                 const FrameFitOptions& options = {});

}  // namespace hnnstereo::robot
