#pragma once
// The thesis arm profile (THESIS.md section 5; robot.cpp, robot::moveto, in the thesis listing):
// a 5-axis Movemaster-class educational arm driven by joint pulses over RS-232. Pure geometry
// and text here - the serial transport (robot/serial_link.cc) only writes the lines.
//
// Kinematics, as the listing computes them (lengths in mm here, cm in the listing):
//   waist       theta1 = atan2(y, x)                        a0 = -40 * theta1
//   wrist point w = p - tool * (sin A * radial, cos A)      (A = 180 deg: tool pointing down)
//   shoulder    lambda = atan(w_z' / w_rho), w_z' = w_z - shoulder height
//               beta   = angle at the shoulder of the (upper arm, forearm, |w'|) triangle
//               sigma  = beta + lambda (upper-arm elevation)   a1 = 40 * (sigma - 35)
//   elbow       alpha  = angle at the wrist of that triangle
//               eps    = alpha + beta (forearm bend)         a2 = 1800 - 40 * eps
//   wrist       theta4 = A - 90 + (lambda - alpha) + 1.9     (pitch; 1.9 deg is the listing's trim)
//               theta5 = S - theta1                          (roll relative to the waist)
//               a3 = 1200 - 40/3 (theta4 + theta5),  a4 = 1200 + 40/3 (theta4 - theta5)
//   a5 = 0 (the command carries six numbers; the arm has five axes).
// Two deliberate differences from the listing, both documented in docs/robot_ascii.md:
// alpha comes from the law of cosines (the listing's asin((22/16) sin beta) picks the acute
// angle, wrong when |w'| < sqrt(22^2 - 16^2) = 15.1 cm), and pulses are rounded to the nearest
// integer (the listing truncates toward zero). pi is pi (the listing used 3.1415).

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "robot/pick_command.h"

namespace hnnstereo::robot {

/// The arm's geometry, pulse scales and joint limits. Defaults: THESIS.md section 5 and the
/// listing; the joint limits are assumptions (waist from the listing's +-5999 pulse comment,
/// the others generous) - adapt them to the arm's manual.
struct ThesisArmGeometry {
  double tool_length_mm = 214.6;        ///< wrist centre to the gripper's grip point (21.46 cm)
  double shoulder_height_mm = 250.0;    ///< shoulder axis above the robot base plane z = 0
  double upper_arm_mm = 220.0;          ///< shoulder to elbow
  double forearm_mm = 160.0;            ///< elbow to wrist
  double joint_pulses_per_deg = 40.0;   ///< waist, shoulder, elbow
  double wrist_pulses_per_deg = 40.0 / 3.0;  ///< each differential wrist motor
  double shoulder_zero_deg = 35.0;      ///< upper-arm elevation at shoulder pulse 0
  int elbow_zero_pulses = 1800;         ///< elbow pulses at eps = 0 (arm straight)
  int wrist_zero_pulses = 1200;         ///< both wrist motors at pitch = roll = 0
  double wrist_pitch_trim_deg = 1.9;    ///< the listing's constant added to the pitch
  double waist_limit_deg = 150.0;       ///< |theta1| (the listing: |a0| <= 5999)
  double shoulder_min_deg = -30.0;      ///< sigma range
  double shoulder_max_deg = 120.0;
  double elbow_min_deg = 0.0;           ///< eps range (0 = straight; elbow-up solution only)
  double elbow_max_deg = 150.0;
  double wrist_pitch_limit_deg = 100.0; ///< |theta4|
  double wrist_roll_limit_deg = 180.0;  ///< |theta5|
  /// Empty when every length and scale is positive and finite and the ranges are ordered.
  std::string Check() const;
};

/// A tool pose in the thesis's terms, robot base frame.
struct ThesisToolPose {
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();  ///< grip point
  double pitch_deg = 180.0;  ///< A: tool angle from the upward vertical (180 = pointing down)
  double roll_deg = 0.0;     ///< S: gripper angle about the tool axis, from the robot x axis
};

/// Joint angles (degrees) in the listing's variables.
struct ThesisJointAngles {
  double waist_deg = 0.0;        ///< theta1
  double shoulder_deg = 0.0;     ///< sigma, upper-arm elevation above horizontal
  double elbow_deg = 0.0;        ///< eps, forearm bend relative to the upper arm (down)
  double wrist_pitch_deg = 0.0;  ///< theta4 (includes the trim)
  double wrist_roll_deg = 0.0;   ///< theta5
};

using ThesisPulses = std::array<int, 6>;  ///< a0..a5 of `PS 1,a0,a1,a2,a3,a4,a5`

/// Inverse kinematics (elbow up). nullopt, with the reason in *why when given, for a pose out of
/// reach or outside a joint limit. A roll that differs by 180 deg grips the same way (parallel
/// jaws), so theta5 is folded into (-90, 90] before the limit check.
std::optional<ThesisJointAngles> ThesisInverseKinematics(const ThesisArmGeometry& geometry,
                                                         const ThesisToolPose& pose,
                                                         std::string* why = nullptr);

/// Forward kinematics: the tool pose the joint angles put the grip point at.
ThesisToolPose ThesisForwardKinematics(const ThesisArmGeometry& geometry,
                                       const ThesisJointAngles& angles);

/// Angles to pulses (rounded to nearest) and back.
ThesisPulses ThesisPulsesFromAngles(const ThesisArmGeometry& geometry,
                                    const ThesisJointAngles& angles);
ThesisJointAngles ThesisAnglesFromPulses(const ThesisArmGeometry& geometry,
                                         const ThesisPulses& pulses);

/// `PS 1,a0,a1,a2,a3,a4,a5` (no terminator).
std::string ThesisPositionLine(const ThesisPulses& pulses);

/// `SP n`: speed_fraction in (0, 1] to the arm's 0..9 speed steps, round(9 * fraction).
int ThesisSpeedStep(double speed_fraction);

/// The thesis pick sequence (grab1 in the listing), all heights relative to the pick command's
/// top-face position, robot base frame. Defaults are the listing's (cm there).
struct ThesisPickOptions {
  double above_mm = 10.0;          ///< approach: top face + 1 cm
  double grip_below_top_mm = 20.0; ///< grip: top face - 2 cm
  double lift_mm = 30.0;           ///< lift: top face + 3 cm
  /// First drop point (x, y); the listing's world (40, 60) cm, i.e. robot (20, -20) cm.
  Eigen::Vector2d drop_first_mm = Eigen::Vector2d(200.0, -200.0);
  /// Added per pick of a cycle (the listing's yy += 5 in world y = -5 cm in robot y).
  Eigen::Vector2d drop_step_mm = Eigen::Vector2d(0.0, -50.0);
  double drop_lift_z_mm = 100.0;   ///< height after the release (10 cm)
  /// Where the arm parks after a cycle: the listing's home2, world (49.95, 5.1, 8) cm.
  Eigen::Vector3d aside_mm = Eigen::Vector3d(100.5, 349.0, 80.0);
  double aside_roll_deg = 0.0;     ///< gripper roll at the aside point
  std::string Check() const;
};

/// The CR-less command lines of one pick (drop_index = 0 for the first pick of a cycle):
///   SP n
///   PS 1,<above> / MO 1 / GO            approach, open
///   PS 1,<grip>  / MO 1 / GC / GF 1     down, close, grip flag
///   PS 1,<lift>  / MO 1                 lift
///   PS 1,<drop>  / MO 1 / GF 0 / GO     to the drop point (at the grip height), release
///   PS 1,<drop lift> / MO 1             lift
/// Every pose is solved before any line is returned; throws std::runtime_error naming the pose
/// and the reason when one is out of reach or the command does not point the tool down.
std::vector<std::string> ThesisPickLines(const ThesisArmGeometry& geometry,
                                         const ThesisPickOptions& options,
                                         const PickCommand& pick, int drop_index);

/// `PS 1,<aside>` / `MO 1`: move aside after a cycle. Throws std::runtime_error if unreachable.
std::vector<std::string> ThesisAsideLines(const ThesisArmGeometry& geometry,
                                          const ThesisPickOptions& options);

}  // namespace hnnstereo::robot
