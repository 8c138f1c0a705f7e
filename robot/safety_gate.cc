#include "robot/safety_gate.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace hnnstereo::robot {
namespace {

bool Inside(const Eigen::Vector3d& p, const SafetyLimits& limits) {
  return (p.array() >= limits.workspace_min.array()).all() &&
         (p.array() <= limits.workspace_max.array()).all();
}

std::string Millimetres(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", value);
  return text;
}

std::string Point(const Eigen::Vector3d& p) {
  return "(" + Millimetres(p.x()) + ", " + Millimetres(p.y()) + ", " + Millimetres(p.z()) + ") mm";
}

// Which limit a point outside the box breaks, e.g. "x 5000.0 > max 1000.0".
std::string BrokenLimit(const Eigen::Vector3d& p, const SafetyLimits& limits) {
  static const char* const kAxis[3] = {"x", "y", "z"};
  for (int axis = 0; axis < 3; ++axis) {
    if (p[axis] < limits.workspace_min[axis]) {
      return std::string(kAxis[axis]) + " " + Millimetres(p[axis]) + " < min " +
             Millimetres(limits.workspace_min[axis]);
    }
    if (p[axis] > limits.workspace_max[axis]) {
      return std::string(kAxis[axis]) + " " + Millimetres(p[axis]) + " > max " +
             Millimetres(limits.workspace_max[axis]);
    }
  }
  return "inside";
}

}  // namespace

std::string SafetyLimits::Check() const {
  if (!workspace_min.allFinite() || !workspace_max.allFinite() ||
      !(workspace_min.array() < workspace_max.array()).all()) {
    return "workspace_min must be below workspace_max on every axis";
  }
  if (!(max_reach_mm > 0.0)) return "max_reach_mm must be positive";
  if (!(max_speed_fraction > 0.0 && max_speed_fraction <= 1.0)) {
    return "max_speed_fraction must be in (0, 1]";
  }
  return {};
}

SafetyGate::SafetyGate(SafetyLimits limits, bool frame_calibrated)
    : limits_(std::move(limits)), frame_calibrated_(frame_calibrated) {
  if (auto error = limits_.Check(); !error.empty()) throw std::invalid_argument(error);
}

std::optional<std::string> SafetyGate::Admit(PickCommand* command) {
  if (!frame_calibrated_) return "no frame calibration (robot_from_world): nothing is sent";
  if (auto error = command->Check(); !error.empty()) return error;
  if (command->merged) {
    return "object " + std::to_string(command->object_id) +
           " is touching parts sensing could not separate (merged): no single pick pose";
  }
  if (last_sequence_ && command->sequence <= *last_sequence_) {
    return "sequence " + std::to_string(command->sequence) + " is stale or duplicate (last " +
           std::to_string(*last_sequence_) + ")";
  }
  // The gripper approaches from above and retreats upwards along the tool's z (base z here).
  const Eigen::Vector3d approach = command->position_mm + Eigen::Vector3d(0, 0, command->approach_mm);
  const Eigen::Vector3d retreat = command->position_mm + Eigen::Vector3d(0, 0, command->retreat_mm);
  for (const auto& [name, point] : {std::pair{"pick", command->position_mm},
                                    std::pair{"approach", approach}, std::pair{"retreat", retreat}}) {
    if (!Inside(point, limits_)) {
      return std::string(name) + " pose is outside the workspace box: " + Point(point) + ", " +
             BrokenLimit(point, limits_);
    }
    if (point.norm() > limits_.max_reach_mm) {
      return std::string(name) + " pose is beyond reach: " + Point(point) + " is " +
             Millimetres(point.norm()) + " mm from the base > max reach " +
             Millimetres(limits_.max_reach_mm) + " mm";
    }
  }
  command->speed_fraction = std::min(command->speed_fraction, limits_.max_speed_fraction);
  last_sequence_ = command->sequence;
  return std::nullopt;
}

}  // namespace hnnstereo::robot
