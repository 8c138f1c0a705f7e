#pragma once
// From a sensed part (world frame of the calibration: table z = 0, z up, mm) to a pick command in
// the robot base frame: the top-face centre mapped by robot_from_world, the tool pointing down,
// the yaw turned by the frame's rotation about z.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "robot/pick_command.h"

namespace hnnstereo::robot {

/// What the robot side needs of one sensed part (OBJECTS.json: id, centroid, height, yaw_deg).
struct SensedObject {
  int id = 0;
  Eigen::Vector3d top_centre_world = Eigen::Vector3d::Zero();  ///< mm, world frame
  double height_mm = 0.0;                                      ///< top face above the table
  double yaw_deg = 0.0;  ///< in the table plane, (-90, 90]; 0 for round parts (yaw is free)
  /// Touching parts sensing could not separate (OBJECTS.json "merged": true): its pose may lie
  /// between two parts, so the safety gate refuses it.
  bool merged = false;
};

struct PickPlanningOptions {
  double approach_mm = 50.0;     ///< approach from this far above the pick pose
  double retreat_mm = 50.0;      ///< lift this far after gripping
  double speed_fraction = 0.2;   ///< of the robot's maximum; the safety gate clamps it
  std::string Check() const;
};

/// Wraps an angle (degrees) into (-90, 90]: a parallel gripper is symmetric under a half turn.
double WrapYawDeg(double yaw_deg);

/// The pick command for `object`: position = robot_from_world * top_centre_world; yaw = the
/// part's yaw plus the frame's rotation about z (wrapped); orientation = Rz(yaw) Rx(180 deg)
/// (tool z pointing down onto the top face). Sequence and capture time as given.
PickCommand PlanPick(const SensedObject& object, const Eigen::Isometry3d& robot_from_world,
                     const PickPlanningOptions& options, std::uint32_t sequence,
                     double capture_time_s);

/// Tallest first (the thesis's pick order), ties by id.
void SortTallestFirst(std::vector<SensedObject>* objects);

/// Reads the objects of an OBJECTS.json text (the `pick` output). Throws std::invalid_argument
/// with a one-line reason on malformed JSON or missing fields.
std::vector<SensedObject> SensedObjectsFromJson(const std::string& json_text);

}  // namespace hnnstereo::robot
