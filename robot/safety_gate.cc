#include "robot/safety_gate.h"

#include <algorithm>
#include <stdexcept>

namespace hnnstereo::robot {
namespace {

bool Inside(const Eigen::Vector3d& p, const SafetyLimits& limits) {
  return (p.array() >= limits.workspace_min.array()).all() &&
         (p.array() <= limits.workspace_max.array()).all();
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
    if (!Inside(point, limits_)) return std::string(name) + " pose is outside the workspace box";
    if (point.norm() > limits_.max_reach_mm) return std::string(name) + " pose is beyond reach";
  }
  command->speed_fraction = std::min(command->speed_fraction, limits_.max_speed_fraction);
  last_sequence_ = command->sequence;
  return std::nullopt;
}

}  // namespace hnnstereo::robot
