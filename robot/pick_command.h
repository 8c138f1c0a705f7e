#pragma once
// The pick command handed to a robot: a pose in the robot base frame (mm, quaternion).
// The robot link issue builds frames, the safety gate and transports on this model.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>

namespace hnnstereo::robot {

enum class GripperAction { kNone, kOpen, kClose };

struct PickCommand {
  std::uint32_t sequence = 0;          ///< strictly increasing per link
  double capture_time_s = 0.0;         ///< when the images were taken (seconds, steady clock)
  int object_id = 0;
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();  ///< top-face centre, robot base frame
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  double yaw_deg = 0.0;                ///< in-plane orientation, (-90, 90]
  double approach_mm = 50.0;           ///< distance above the pick pose to approach from
  double retreat_mm = 50.0;            ///< distance to lift after gripping
  GripperAction gripper = GripperAction::kClose;
  double speed_fraction = 0.2;         ///< of the robot's maximum speed, (0, 1]
  /// The pose is of touching parts that sensing could not separate: the safety gate refuses it.
  bool merged = false;

  /// Empty when every field is finite and in range; otherwise a one-line reason.
  std::string Check() const;
};

}  // namespace hnnstereo::robot
