#pragma once
// FRAME.yml (OpenCV FileStorage YAML, ARCHITECTURE.md): robot_from_world (4x4), workspace_min
// and workspace_max (3x1, mm, robot frame), rms_mm (residual of the fit that produced it), and
// optionally max_reach_mm (the arm's reach from the robot base origin).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "robot/safety_gate.h"

namespace hnnstereo::robot {

struct RobotFrame {
  Eigen::Isometry3d robot_from_world = Eigen::Isometry3d::Identity();
  Eigen::Vector3d workspace_min = SafetyLimits{}.workspace_min;
  Eigen::Vector3d workspace_max = SafetyLimits{}.workspace_max;
  double rms_mm = 0.0;
  /// The arm's reach from the robot base origin (mm): when set, the default of the safety gate's
  /// --max-reach (a --max-reach given wins); unset, SafetyLimits' default applies.
  std::optional<double> max_reach_mm;
  /// Empty when the rotation is orthonormal with determinant +1, the bottom row is 0 0 0 1, the
  /// workspace box is ordered and everything is finite; else a one-line reason.
  std::string Check() const;
};

/// Throws std::invalid_argument naming the file and the problem (missing, unreadable, a key
/// missing or of the wrong size, not a rigid transform).
RobotFrame LoadRobotFrame(const std::string& path);

/// Written atomically (a temporary file renamed onto `path`), as YAML whatever its extension.
void SaveRobotFrame(const std::string& path, const RobotFrame& frame);

/// The thesis cell's frame (THESIS.md section 5): x_r = 600 - X, y_r = 400 - Y, z_r = Z (mm),
/// a half turn about z. Its workspace box and reach cover the table of the rendered default
/// cell (vision/synth: parts within (100, 385) +- (130, 100) mm, up to 150 mm tall, plus the
/// approach and retreat), so that every part `render` places can be sent.
RobotFrame ThesisRobotFrame();

}  // namespace hnnstereo::robot
