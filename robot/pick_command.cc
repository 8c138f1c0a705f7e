#include "robot/pick_command.h"

#include <cmath>

namespace hnnstereo::robot {

std::string PickCommand::Check() const {
  if (!position_mm.allFinite()) return "pick position is not finite";
  if (!orientation.coeffs().allFinite() || std::abs(orientation.norm() - 1.0) > 1e-6) {
    return "pick orientation is not a unit quaternion";
  }
  if (!std::isfinite(yaw_deg) || yaw_deg <= -90.0 || yaw_deg > 90.0) {
    return "yaw_deg must be in (-90, 90]";
  }
  if (!std::isfinite(approach_mm) || approach_mm < 0.0) return "approach_mm must be >= 0";
  if (!std::isfinite(retreat_mm) || retreat_mm < 0.0) return "retreat_mm must be >= 0";
  if (!std::isfinite(speed_fraction) || speed_fraction <= 0.0 || speed_fraction > 1.0) {
    return "speed_fraction must be in (0, 1]";
  }
  return {};
}

}  // namespace hnnstereo::robot
