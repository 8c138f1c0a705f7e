#include "robot/frames.h"

#include <Eigen/SVD>
#include <cmath>
#include <stdexcept>

namespace hnnstereo::robot {

std::string FrameFitOptions::Check() const {
  if (!(max_rms_mm > 0.0)) return "max_rms_mm must be positive";
  if (!(min_spread_ratio >= 0.0 && min_spread_ratio < 1.0)) return "min_spread_ratio must be in [0, 1)";
  return {};
}

FrameFitReport FitRobotFromWorld(const std::vector<Eigen::Vector3d>& world_points,
                                 const std::vector<Eigen::Vector3d>& robot_points,
                                 const FrameFitOptions& options) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  if (world_points.size() != robot_points.size()) {
    throw std::invalid_argument("frame fit: " + std::to_string(world_points.size()) +
                                " world points but " + std::to_string(robot_points.size()) +
                                " robot points");
  }
  const auto n = static_cast<Eigen::Index>(world_points.size());
  if (n < 3) {
    throw std::invalid_argument("frame fit needs at least 3 touched points (got " +
                                std::to_string(n) + ")");
  }
  Eigen::Matrix3Xd world(3, n), robot(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    world.col(i) = world_points[static_cast<std::size_t>(i)];
    robot.col(i) = robot_points[static_cast<std::size_t>(i)];
  }
  if (!world.allFinite() || !robot.allFinite()) {
    throw std::invalid_argument("frame fit: a point is not finite");
  }
  const Eigen::Matrix3Xd centred = world.colwise() - world.rowwise().mean();
  const Eigen::Vector3d spread = Eigen::JacobiSVD<Eigen::Matrix3Xd>(centred).singularValues();
  if (!(spread(0) > 0.0) || spread(1) < options.min_spread_ratio * spread(0)) {
    throw std::invalid_argument(
        "frame fit: the touched points are collinear or coincident; touch at least 3 points "
        "spread over the work area");
  }
  FrameFitReport report;
  report.n_points = static_cast<int>(n);
  report.robot_from_world.matrix() = Eigen::umeyama(world, robot, /*with_scaling=*/false);
  double sum_squares = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double residual = (report.robot_from_world * world.col(i) - robot.col(i)).norm();
    sum_squares += residual * residual;
    report.max_residual_mm = std::max(report.max_residual_mm, residual);
  }
  report.rms_mm = std::sqrt(sum_squares / static_cast<double>(n));
  if (report.rms_mm > options.max_rms_mm) {
    throw std::invalid_argument("frame fit RMS " + std::to_string(report.rms_mm) +
                                " mm is over the limit of " + std::to_string(options.max_rms_mm) +
                                " mm; check that the points are paired in the same order");
  }
  return report;
}

}  // namespace hnnstereo::robot
