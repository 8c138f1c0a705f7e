#pragma once
// The safety gate every pick command passes before any transport: non-finite values, approach,
// pick or retreat outside the workspace box, beyond reach, stale or duplicate sequence numbers,
// a pose of merged (touching, unseparated) parts and a missing frame calibration are refused
// (never sent); the speed is clamped.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "robot/pick_command.h"

namespace hnnstereo::robot {

struct SafetyLimits {
  Eigen::Vector3d workspace_min = Eigen::Vector3d(-400, -400, 0);  ///< robot frame, mm
  Eigen::Vector3d workspace_max = Eigen::Vector3d(400, 400, 500);  ///< robot frame, mm
  double max_reach_mm = 600.0;       ///< distance from the robot base origin
  double max_speed_fraction = 0.5;   ///< speeds above are clamped to this
  std::string Check() const;
};

class SafetyGate {
 public:
  /// `frame_calibrated` false refuses every command (no robot_from_world known).
  SafetyGate(SafetyLimits limits, bool frame_calibrated);

  /// nullopt: the (possibly speed-clamped) command may be sent; else the one-line reason it
  /// was refused. An accepted command's sequence number becomes the last one seen.
  std::optional<std::string> Admit(PickCommand* command);

 private:
  SafetyLimits limits_;
  bool frame_calibrated_;
  std::optional<std::uint32_t> last_sequence_;
};

}  // namespace hnnstereo::robot
