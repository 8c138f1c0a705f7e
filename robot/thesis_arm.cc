#include "robot/thesis_arm.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace hnnstereo::robot {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

bool Positive(double value) { return std::isfinite(value) && value > 0.0; }

int RoundPulses(double value) { return static_cast<int>(std::lround(value)); }

// A parallel gripper grips the same at roll and roll + 180 deg: fold into (-90, 90].
double FoldRollDeg(double roll_deg) {
  double folded = std::fmod(roll_deg, 180.0);  // (-180, 180)
  if (folded > 90.0) folded -= 180.0;
  if (folded <= -90.0) folded += 180.0;
  return folded;
}

std::string Mm(const Eigen::Vector3d& p) {
  std::ostringstream text;
  text.precision(1);
  text << std::fixed << "(" << p.x() << ", " << p.y() << ", " << p.z() << ") mm";
  return text.str();
}

}  // namespace

std::string ThesisArmGeometry::Check() const {
  if (!Positive(tool_length_mm) || !Positive(upper_arm_mm) || !Positive(forearm_mm)) {
    return "tool, upper-arm and forearm lengths must be positive";
  }
  if (!std::isfinite(shoulder_height_mm)) return "shoulder_height_mm must be finite";
  if (!Positive(joint_pulses_per_deg) || !Positive(wrist_pulses_per_deg)) {
    return "pulses per degree must be positive";
  }
  if (!std::isfinite(shoulder_zero_deg) || !std::isfinite(wrist_pitch_trim_deg)) {
    return "shoulder_zero_deg and wrist_pitch_trim_deg must be finite";
  }
  if (!Positive(waist_limit_deg) || !Positive(wrist_pitch_limit_deg) ||
      !Positive(wrist_roll_limit_deg)) {
    return "waist, wrist pitch and wrist roll limits must be positive";
  }
  if (!(shoulder_min_deg < shoulder_max_deg) || !(elbow_min_deg < elbow_max_deg)) {
    return "shoulder and elbow ranges must be ordered (min < max)";
  }
  return {};
}

std::string ThesisPickOptions::Check() const {
  if (!std::isfinite(above_mm) || !std::isfinite(grip_below_top_mm) || !std::isfinite(lift_mm) ||
      !drop_first_mm.allFinite() || !drop_step_mm.allFinite() ||
      !std::isfinite(drop_lift_z_mm) || !aside_mm.allFinite() || !std::isfinite(aside_roll_deg)) {
    return "every pick-sequence distance must be finite";
  }
  return {};
}

std::optional<ThesisJointAngles> ThesisInverseKinematics(const ThesisArmGeometry& geometry,
                                                         const ThesisToolPose& pose,
                                                         std::string* why) {
  auto refuse = [&](const std::string& reason) -> std::optional<ThesisJointAngles> {
    if (why != nullptr) *why = reason;
    return std::nullopt;
  };
  if (!pose.position_mm.allFinite() || !std::isfinite(pose.pitch_deg) ||
      !std::isfinite(pose.roll_deg)) {
    return refuse("pose is not finite");
  }
  const double x = pose.position_mm.x();
  const double y = pose.position_mm.y();
  const double rho = std::hypot(x, y);
  if (rho < 1e-6) return refuse("on the waist axis (waist angle undefined)");
  const double pitch = pose.pitch_deg / kDegPerRad;
  ThesisJointAngles angles;
  angles.waist_deg = std::atan2(y, x) * kDegPerRad;
  // Wrist centre, shoulder-relative: back along the tool axis (listing: px, py, pz -= 25).
  const double wrist_rho = rho - geometry.tool_length_mm * std::sin(pitch);
  const double wrist_z =
      pose.position_mm.z() - geometry.tool_length_mm * std::cos(pitch) - geometry.shoulder_height_mm;
  if (wrist_rho <= 0.0) return refuse("wrist centre behind the waist axis");
  const double reach = std::hypot(wrist_rho, wrist_z);
  const double l1 = geometry.upper_arm_mm;
  const double l2 = geometry.forearm_mm;
  if (reach > l1 + l2) {
    return refuse("out of reach (wrist " + std::to_string(static_cast<int>(reach)) +
                  " mm from the shoulder, arm " + std::to_string(static_cast<int>(l1 + l2)) +
                  " mm)");
  }
  if (reach < std::abs(l1 - l2)) return refuse("too close to the shoulder");
  const double lambda = std::atan2(wrist_z, wrist_rho);
  const double beta = std::acos(
      std::clamp((reach * reach + l1 * l1 - l2 * l2) / (2.0 * l1 * reach), -1.0, 1.0));
  // Law of cosines, not the listing's asin (see the header).
  const double alpha = std::acos(
      std::clamp((reach * reach + l2 * l2 - l1 * l1) / (2.0 * l2 * reach), -1.0, 1.0));
  angles.shoulder_deg = (beta + lambda) * kDegPerRad;
  angles.elbow_deg = (alpha + beta) * kDegPerRad;
  angles.wrist_pitch_deg =
      pose.pitch_deg - 90.0 + (lambda - alpha) * kDegPerRad + geometry.wrist_pitch_trim_deg;
  angles.wrist_roll_deg = FoldRollDeg(pose.roll_deg - angles.waist_deg);

  auto degrees = [](double value) {
    std::ostringstream text;
    text.precision(1);
    text << std::fixed << value << " deg";
    return text.str();
  };
  if (std::abs(angles.waist_deg) > geometry.waist_limit_deg) {
    return refuse("waist " + degrees(angles.waist_deg) + " beyond +-" +
                  degrees(geometry.waist_limit_deg));
  }
  if (angles.shoulder_deg < geometry.shoulder_min_deg ||
      angles.shoulder_deg > geometry.shoulder_max_deg) {
    return refuse("shoulder " + degrees(angles.shoulder_deg) + " outside " +
                  degrees(geometry.shoulder_min_deg) + ".." + degrees(geometry.shoulder_max_deg));
  }
  if (angles.elbow_deg < geometry.elbow_min_deg || angles.elbow_deg > geometry.elbow_max_deg) {
    return refuse("elbow " + degrees(angles.elbow_deg) + " outside " +
                  degrees(geometry.elbow_min_deg) + ".." + degrees(geometry.elbow_max_deg));
  }
  if (std::abs(angles.wrist_pitch_deg) > geometry.wrist_pitch_limit_deg) {
    return refuse("wrist pitch " + degrees(angles.wrist_pitch_deg) + " beyond +-" +
                  degrees(geometry.wrist_pitch_limit_deg));
  }
  if (std::abs(angles.wrist_roll_deg) > geometry.wrist_roll_limit_deg) {
    return refuse("wrist roll " + degrees(angles.wrist_roll_deg) + " beyond +-" +
                  degrees(geometry.wrist_roll_limit_deg));
  }
  return angles;
}

ThesisToolPose ThesisForwardKinematics(const ThesisArmGeometry& geometry,
                                       const ThesisJointAngles& angles) {
  const double sigma = angles.shoulder_deg / kDegPerRad;
  const double forearm = (angles.shoulder_deg - angles.elbow_deg) / kDegPerRad;  // lambda - alpha
  const double wrist_rho =
      geometry.upper_arm_mm * std::cos(sigma) + geometry.forearm_mm * std::cos(forearm);
  const double wrist_z = geometry.shoulder_height_mm + geometry.upper_arm_mm * std::sin(sigma) +
                         geometry.forearm_mm * std::sin(forearm);
  ThesisToolPose pose;
  pose.pitch_deg =
      angles.wrist_pitch_deg - geometry.wrist_pitch_trim_deg + 90.0 - forearm * kDegPerRad;
  const double pitch = pose.pitch_deg / kDegPerRad;
  const double rho = wrist_rho + geometry.tool_length_mm * std::sin(pitch);
  const double waist = angles.waist_deg / kDegPerRad;
  pose.position_mm = Eigen::Vector3d(rho * std::cos(waist), rho * std::sin(waist),
                                     wrist_z + geometry.tool_length_mm * std::cos(pitch));
  pose.roll_deg = angles.wrist_roll_deg + angles.waist_deg;
  return pose;
}

ThesisPulses ThesisPulsesFromAngles(const ThesisArmGeometry& geometry,
                                    const ThesisJointAngles& angles) {
  const double k = geometry.joint_pulses_per_deg;
  const double kw = geometry.wrist_pulses_per_deg;
  const double wrist_zero = geometry.wrist_zero_pulses;
  return {RoundPulses(-k * angles.waist_deg),
          RoundPulses(k * (angles.shoulder_deg - geometry.shoulder_zero_deg)),
          RoundPulses(geometry.elbow_zero_pulses - k * angles.elbow_deg),
          RoundPulses(wrist_zero - kw * (angles.wrist_pitch_deg + angles.wrist_roll_deg)),
          RoundPulses(wrist_zero + kw * (angles.wrist_pitch_deg - angles.wrist_roll_deg)),
          0};
}

ThesisJointAngles ThesisAnglesFromPulses(const ThesisArmGeometry& geometry,
                                         const ThesisPulses& pulses) {
  const double k = geometry.joint_pulses_per_deg;
  const double kw = geometry.wrist_pulses_per_deg;
  const double a3 = pulses[3];
  const double a4 = pulses[4];
  ThesisJointAngles angles;
  angles.waist_deg = -pulses[0] / k;
  angles.shoulder_deg = pulses[1] / k + geometry.shoulder_zero_deg;
  angles.elbow_deg = (geometry.elbow_zero_pulses - pulses[2]) / k;
  angles.wrist_pitch_deg = (a4 - a3) / (2.0 * kw);
  angles.wrist_roll_deg = (2.0 * geometry.wrist_zero_pulses - a3 - a4) / (2.0 * kw);
  return angles;
}

std::string ThesisPositionLine(const ThesisPulses& pulses) {
  std::string line = "PS 1";
  for (int value : pulses) {
    line += ',';
    line += std::to_string(value);
  }
  return line;
}

int ThesisSpeedStep(double speed_fraction) {
  if (!std::isfinite(speed_fraction)) return 0;
  return static_cast<int>(std::clamp(std::lround(9.0 * speed_fraction), 0L, 9L));
}

namespace {

// Solves every pose first so that nothing of a refused pick is ever returned (or written).
void SolvePoses(const ThesisArmGeometry& geometry,
                const std::vector<std::pair<std::string, ThesisToolPose>>& poses,
                std::vector<ThesisPulses>* pulses) {
  if (auto error = geometry.Check(); !error.empty()) {
    throw std::invalid_argument("thesis arm geometry: " + error);
  }
  for (const auto& [name, pose] : poses) {
    std::string why;
    const auto angles = ThesisInverseKinematics(geometry, pose, &why);
    if (!angles) {
      throw std::runtime_error("thesis arm cannot reach the " + name + " pose " +
                               Mm(pose.position_mm) + ": " + why);
    }
    pulses->push_back(ThesisPulsesFromAngles(geometry, *angles));
  }
}

}  // namespace

std::vector<std::string> ThesisPickLines(const ThesisArmGeometry& geometry,
                                         const ThesisPickOptions& options,
                                         const PickCommand& pick, int drop_index) {
  if (auto error = options.Check(); !error.empty()) {
    throw std::invalid_argument("thesis pick options: " + error);
  }
  if (auto error = pick.Check(); !error.empty()) throw std::runtime_error("pick: " + error);
  // The listing only picks with the tool pointing straight down (A = 180 deg).
  const Eigen::Vector3d tool_axis = pick.orientation * Eigen::Vector3d::UnitZ();
  if (tool_axis.z() > -std::cos(1.0 / kDegPerRad)) {
    throw std::runtime_error("thesis arm picks tool-down only; the command's tool axis is (" +
                             std::to_string(tool_axis.x()) + ", " + std::to_string(tool_axis.y()) +
                             ", " + std::to_string(tool_axis.z()) + ")");
  }
  const Eigen::Vector3d top = pick.position_mm;
  const double roll = pick.yaw_deg;
  auto at = [&](double x, double y, double z, double roll_deg) {
    ThesisToolPose pose;
    pose.position_mm = Eigen::Vector3d(x, y, z);
    pose.roll_deg = roll_deg;
    return pose;
  };
  const double grip_z = top.z() - options.grip_below_top_mm;
  const Eigen::Vector2d drop = options.drop_first_mm + drop_index * options.drop_step_mm;
  std::vector<ThesisPulses> pulses;
  SolvePoses(geometry,
            {{"approach", at(top.x(), top.y(), top.z() + options.above_mm, roll)},
             {"grip", at(top.x(), top.y(), grip_z, roll)},
             {"lift", at(top.x(), top.y(), top.z() + options.lift_mm, roll)},
             {"drop", at(drop.x(), drop.y(), grip_z, 0.0)},
             {"drop-lift", at(drop.x(), drop.y(), options.drop_lift_z_mm, 0.0)}},
            &pulses);
  return {"SP " + std::to_string(ThesisSpeedStep(pick.speed_fraction)),
          ThesisPositionLine(pulses[0]), "MO 1", "GO",
          ThesisPositionLine(pulses[1]), "MO 1", "GC", "GF 1",
          ThesisPositionLine(pulses[2]), "MO 1",
          ThesisPositionLine(pulses[3]), "MO 1", "GF 0", "GO",
          ThesisPositionLine(pulses[4]), "MO 1"};
}

std::vector<std::string> ThesisAsideLines(const ThesisArmGeometry& geometry,
                                          const ThesisPickOptions& options) {
  if (auto error = options.Check(); !error.empty()) {
    throw std::invalid_argument("thesis pick options: " + error);
  }
  ThesisToolPose aside;
  aside.position_mm = options.aside_mm;
  aside.roll_deg = options.aside_roll_deg;
  std::vector<ThesisPulses> pulses;
  SolvePoses(geometry, {{"aside", aside}}, &pulses);
  return {ThesisPositionLine(pulses[0]), "MO 1"};
}

}  // namespace hnnstereo::robot
