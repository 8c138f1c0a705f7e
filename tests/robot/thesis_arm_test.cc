// The thesis arm profile: inverse and forward kinematics, joint pulses, the pick's command lines.
#include "robot/thesis_arm.h"
#include "robot/pick_planning.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace hnnstereo::robot {
namespace {

constexpr double kPi = std::numbers::pi;

// robot::moveto from the thesis listing, transcribed literally (cm, degrees, pi = 3.1415,
// truncating casts, asin for alpha) - an independent reference for the pulses. Takes robot-frame
// coordinates (the listing first applies x_r = 60 - X, y_r = 40 - Y).
ThesisPulses ListingMoveTo(double X, double Y, double Z, double A, double S) {
  const double pi = 3.1415;
  const double d5 = 21.46;
  int a[6] = {0, 0, 0, 0, 0, 0};
  const double magnitude = std::sqrt(X * X + Y * Y);
  const double A_an = A;
  A = A * pi / 180;
  double px = X - d5 * (X / magnitude) * std::sin(A);
  double py = Y - d5 * (Y / magnitude) * std::sin(A);
  double pz = Z - d5 * std::cos(A);
  pz -= 25.0;
  const double pmag = std::sqrt(px * px + py * py + pz * pz);
  double b = std::fabs(std::atan2(Y, X));
  if (Y < 0) b = -b;
  a[0] = static_cast<int>(-40 * b * 180 / pi);
  const double theta1 = b * 180 / pi;
  const double lambda = std::atan(pz / std::sqrt(px * px + py * py));
  double temp1 = px * px + py * py + pz * pz + 22.0 * 22.0 - 16.0 * 16.0;
  temp1 /= 2 * 22.0 * pmag;
  const double beta = std::acos(temp1);
  b = (beta + lambda) * 180.0 / pi - 35.0;
  a[1] = static_cast<int>(b * 40.0);
  const double alpha = std::asin((22.0 / 16.0) * std::sin(beta));
  b = (alpha + beta) * -40.0 * 180.0 / pi + 1800.0;
  a[2] = static_cast<int>(b);
  double theta4 = A_an - 90.0 + (lambda - alpha) * 180.0 / pi;
  theta4 += 1.9;
  const double theta5 = S - theta1;
  a[3] = static_cast<int>(1200 - (40.0 / 3.0) * (theta4 + theta5));
  a[4] = static_cast<int>(1200 + (40.0 / 3.0) * (theta4 - theta5));
  return {a[0], a[1], a[2], a[3], a[4], 0};
}

ThesisToolPose Down(double x, double y, double z, double roll_deg) {
  ThesisToolPose pose;
  pose.position_mm = Eigen::Vector3d(x, y, z);
  pose.roll_deg = roll_deg;
  return pose;
}

// A tool-down pick at (x, y, z) of the robot frame, as the cell loop plans it.
PickCommand ToolDownPick(double x, double y, double z, double yaw_deg, double speed) {
  PickPlanningOptions planning;
  planning.speed_fraction = speed;
  return PlanPick({0, {x, y, z}, z, yaw_deg}, Eigen::Isometry3d::Identity(), planning, 0, 0.0);
}

double RollDifferenceDeg(double a, double b) {  // modulo 180 (parallel jaws)
  double d = std::fmod(a - b, 180.0);
  if (d > 90.0) d -= 180.0;
  if (d < -90.0) d += 180.0;
  return std::abs(d);
}

TEST(ThesisArmGeometry, DefaultsAreValidAndBadValuesAreNamed) {
  EXPECT_EQ(ThesisArmGeometry{}.Check(), "");
  ThesisArmGeometry bad;
  bad.forearm_mm = -1.0;
  EXPECT_NE(bad.Check(), "");
  bad = {};
  bad.elbow_max_deg = bad.elbow_min_deg;
  EXPECT_NE(bad.Check(), "");
}

TEST(ThesisInverseKinematics, ForwardKinematicsReturnsThePoseOverASeededWorkspace) {
  const ThesisArmGeometry geometry;
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> radius(180.0, 380.0), angle(-120.0, 120.0),
      height(0.0, 150.0), roll(-89.0, 89.0);
  int solved = 0;
  for (int i = 0; i < 2000; ++i) {
    const double r = radius(rng);
    const double a = angle(rng) * kPi / 180.0;
    const ThesisToolPose target = Down(r * std::cos(a), r * std::sin(a), height(rng), roll(rng));
    const auto angles = ThesisInverseKinematics(geometry, target);
    if (!angles) continue;
    ++solved;
    const ThesisToolPose exact = ThesisForwardKinematics(geometry, *angles);
    ASSERT_LT((exact.position_mm - target.position_mm).norm(), 1e-6) << "sample " << i;
    ASSERT_NEAR(exact.pitch_deg, 180.0, 1e-9);
    ASSERT_LT(RollDifferenceDeg(exact.roll_deg, target.roll_deg), 1e-9);
    // Through the integer pulses: within what half a pulse per joint can move the grip point
    // (0.0125 deg at up to 600 mm lever is 0.13 mm; five joints).
    const ThesisPulses pulses = ThesisPulsesFromAngles(geometry, *angles);
    const ThesisToolPose quantised =
        ThesisForwardKinematics(geometry, ThesisAnglesFromPulses(geometry, pulses));
    ASSERT_LT((quantised.position_mm - target.position_mm).norm(), 0.5) << "sample " << i;
    ASSERT_NEAR(quantised.pitch_deg, 180.0, 0.1);
    ASSERT_LT(RollDifferenceDeg(quantised.roll_deg, target.roll_deg), 0.1);
  }
  EXPECT_GT(solved, 1000);  // most of that annulus is reachable
}

TEST(ThesisInverseKinematics, PulsesOfAHandComputedPose) {
  // Chosen joints: waist 30 deg, upper arm 35 deg up (shoulder pulse 0), elbow bent 80 deg
  // (forearm 45 deg down), tool down, roll 30 deg (wrist roll 0 relative to the waist).
  const double s35 = std::sin(35 * kPi / 180), c35 = std::cos(35 * kPi / 180);
  const double s45 = std::sin(45 * kPi / 180), c45 = std::cos(45 * kPi / 180);
  const double rho = 220 * c35 + 160 * c45;          // 293.35 mm, wrist and grip point
  const double z = 250 + 220 * s35 - 160 * s45 - 214.6;  // 48.45 mm
  const ThesisToolPose pose =
      Down(rho * std::cos(30 * kPi / 180), rho * std::sin(30 * kPi / 180), z, 30.0);
  const auto angles = ThesisInverseKinematics(ThesisArmGeometry{}, pose);
  ASSERT_TRUE(angles.has_value());
  EXPECT_NEAR(angles->waist_deg, 30.0, 1e-9);
  EXPECT_NEAR(angles->shoulder_deg, 35.0, 1e-9);
  EXPECT_NEAR(angles->elbow_deg, 80.0, 1e-9);
  EXPECT_NEAR(angles->wrist_pitch_deg, 90.0 - 45.0 + 1.9, 1e-9);
  EXPECT_NEAR(angles->wrist_roll_deg, 0.0, 1e-9);
  // a0 = -40 * 30; a1 = 40 * (35 - 35); a2 = 1800 - 40 * 80;
  // a3 = 1200 - 40/3 * 46.9 = 574.67; a4 = 1200 + 40/3 * 46.9 = 1825.33.
  const ThesisPulses expected = {-1200, 0, -1400, 575, 1825, 0};
  EXPECT_EQ(ThesisPulsesFromAngles(ThesisArmGeometry{}, *angles), expected);
  EXPECT_EQ(ThesisPositionLine(expected), "PS 1,-1200,0,-1400,575,1825,0");
}

TEST(ThesisInverseKinematics, AgreesWithTheListingTranscription) {
  // The listing's calibration poses and a spread of pick poses, in cm for the listing. It
  // truncates and uses pi = 3.1415: agreement within 2 pulses. Its roll S is absolute; keep
  // theta5 inside (-90, 90] so the fold does not apply.
  const ThesisArmGeometry geometry;
  const double poses[][4] = {{35, 0, 5, 88},    {35, 0, 9, 88},   {35, 0, 13, 88},
                             {35, 0, -0.7, 88}, {30, 10, 4, 30},  {25, -12, 2, -20},
                             {20, 20, 8, 60},   {32, -5, 0, -10}, {28, 15, 12, 45}};
  for (const auto& p : poses) {
    const auto angles = ThesisInverseKinematics(
        geometry, Down(p[0] * 10, p[1] * 10, p[2] * 10, p[3]));
    ASSERT_TRUE(angles.has_value()) << p[0] << "," << p[1] << "," << p[2];
    const ThesisPulses ours = ThesisPulsesFromAngles(geometry, *angles);
    const ThesisPulses listing = ListingMoveTo(p[0], p[1], p[2], 180.0, p[3]);
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(ours[j], listing[j], 2) << "joint " << j << " at " << p[0] << "," << p[1]
                                          << "," << p[2] << " cm";
    }
  }
}

TEST(ThesisInverseKinematics, RefusesWhatTheArmCannotReach) {
  const ThesisArmGeometry geometry;
  std::string why;
  EXPECT_FALSE(ThesisInverseKinematics(geometry, Down(600, 0, 0, 0), &why).has_value());
  EXPECT_NE(why.find("out of reach"), std::string::npos) << why;
  EXPECT_FALSE(ThesisInverseKinematics(geometry, Down(0, 0, 100, 0), &why).has_value());
  EXPECT_FALSE(ThesisInverseKinematics(geometry, Down(-300, 10, 50, 0), &why).has_value());
  EXPECT_NE(why.find("waist"), std::string::npos) << why;
  EXPECT_FALSE(ThesisInverseKinematics(geometry, Down(300, 0, NAN, 0), &why).has_value());
}

TEST(ThesisSpeedStep, MapsTheFractionOntoTheArmsTenSteps) {
  EXPECT_EQ(ThesisSpeedStep(0.01), 0);
  EXPECT_EQ(ThesisSpeedStep(0.2), 2);
  EXPECT_EQ(ThesisSpeedStep(0.5), 5);
  EXPECT_EQ(ThesisSpeedStep(1.0), 9);
}

TEST(ThesisPickLines, TheExactCommandLinesOfAPick) {
  const ThesisArmGeometry geometry;
  const ThesisPickOptions options;
  const PickCommand pick = ToolDownPick(300.0, 50.0, 40.0, 20.0, 0.2);
  const std::vector<std::string> lines = ThesisPickLines(geometry, options, pick, 0);
  const std::vector<std::string> expected = {
      "SP 2",
      "PS 1,-378,-73,-1183,386,1733,0", "MO 1", "GO",                // above, z 50
      "PS 1,-378,-299,-1183,461,1658,0", "MO 1", "GC", "GF 1",       // grip, z 20
      "PS 1,-378,64,-1150,329,1790,0", "MO 1",                       // lift, z 70
      "PS 1,1800,-155,-1597,92,1108,0", "MO 1", "GF 0", "GO",        // drop (200, -200, 20)
      "PS 1,1800,438,-1468,-149,1349,0", "MO 1"};                      // drop lift, z 100
  EXPECT_EQ(lines, expected);
  // Each PS line matches the listing's own arithmetic within its truncation.
  const ThesisPulses listing = ListingMoveTo(30.0, 5.0, 5.0, 180.0, 20.0);
  const ThesisPulses ours = ThesisPulsesFromAngles(
      geometry, *ThesisInverseKinematics(geometry, Down(300, 50, 50, 20)));
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(ours[j], listing[j], 2) << "joint " << j;

  // The second pick of a cycle drops 50 mm further along robot -y.
  const auto second = ThesisPickLines(geometry, options, pick, 1);
  EXPECT_NE(second[10], lines[10]);
  EXPECT_EQ(ThesisAsideLines(geometry, options).size(), 2u);
}

TEST(ThesisPickLines, AnUnreachablePickYieldsNoLineAtAll) {
  const ThesisArmGeometry geometry;
  const ThesisPickOptions options;
  EXPECT_THROW(ThesisPickLines(geometry, options, ToolDownPick(550, 0, 40, 0, 0.2), 0),
               std::runtime_error);
  // Reachable top face, but the approach above it is not: still nothing.
  EXPECT_THROW(ThesisPickLines(geometry, options, ToolDownPick(380, 0, 45, 0, 0.2), 0),
               std::runtime_error);
  // Not tool-down.
  PickCommand tilted = ToolDownPick(300, 0, 40, 0, 0.2);
  tilted.orientation = Eigen::Quaterniond::Identity();
  EXPECT_THROW(ThesisPickLines(geometry, options, tilted, 0), std::runtime_error);
  // The drop point out of reach refuses the whole pick.
  ThesisPickOptions far_drop;
  far_drop.drop_first_mm = Eigen::Vector2d(900, 0);
  EXPECT_THROW(ThesisPickLines(geometry, far_drop, ToolDownPick(300, 0, 40, 0, 0.2), 0),
               std::runtime_error);
}

}  // namespace
}  // namespace hnnstereo::robot
