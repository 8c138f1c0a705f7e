// Frame fitting (Umeyama / Kabsch) and the safety gate in front of every transport.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "robot/frames.h"
#include "robot/pick_planning.h"
#include "robot/safety_gate.h"

namespace hnnstereo::robot {
namespace {

TEST(FitRobotFromWorld, RecoversASeededRigidTransformWithNoise) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> coordinate(-200.0, 200.0);
  std::normal_distribution<double> noise(0.0, 0.1);
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  truth.rotate(Eigen::AngleAxisd(2.8, Eigen::Vector3d(0.1, 0.2, 1.0).normalized()));
  truth.pretranslate(Eigen::Vector3d(600, 400, -30));
  std::vector<Eigen::Vector3d> world, robot;
  for (int i = 0; i < 8; ++i) {
    world.emplace_back(coordinate(rng), coordinate(rng), 0.25 * coordinate(rng));
    robot.push_back(truth * world.back() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  const FrameFitReport report = FitRobotFromWorld(world, robot);
  EXPECT_LT(report.rms_mm, 0.3);
  EXPECT_GT(report.rms_mm, 0.0);
  EXPECT_LT((report.robot_from_world.translation() - truth.translation()).norm(), 0.5);
  EXPECT_LT(Eigen::AngleAxisd(report.robot_from_world.rotation().transpose() * truth.rotation()).angle(),
            2e-3);
}

TEST(FitRobotFromWorld, RefusesDegenerateOrBadSets) {
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(FitRobotFromWorld(two, two), std::invalid_argument);
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {10, 0, 0}, {20, 0, 0}, {30, 0, 0}};
  EXPECT_THROW(FitRobotFromWorld(line, line), std::invalid_argument);
  const std::vector<Eigen::Vector3d> world = {{0, 0, 0}, {100, 0, 0}, {0, 100, 0}};
  const std::vector<Eigen::Vector3d> swapped = {{0, 0, 0}, {0, 100, 0}, {100, 100, 0}};
  EXPECT_THROW(FitRobotFromWorld(world, swapped), std::invalid_argument) << "RMS over the limit";
  std::vector<Eigen::Vector3d> nan = world;
  nan[1].x() = std::nan("");
  EXPECT_THROW(FitRobotFromWorld(nan, world), std::invalid_argument);
}

PickCommand Command(std::uint32_t sequence, Eigen::Vector3d position) {
  PickCommand command;
  command.sequence = sequence;
  command.position_mm = position;
  return command;
}

TEST(SafetyGate, AdmitsValidCommandsAndClampsSpeed) {
  SafetyGate gate(SafetyLimits{}, true);
  PickCommand command = Command(1, {100, 50, 40});
  command.speed_fraction = 0.9;
  EXPECT_EQ(gate.Admit(&command), std::nullopt);
  EXPECT_DOUBLE_EQ(command.speed_fraction, 0.5);
}

TEST(SafetyGate, RefusesEverythingUnsafe) {
  SafetyGate gate(SafetyLimits{}, true);
  PickCommand ok = Command(5, {100, 50, 40});
  ASSERT_EQ(gate.Admit(&ok), std::nullopt);
  PickCommand duplicate = Command(5, {100, 50, 40});
  EXPECT_NE(gate.Admit(&duplicate), std::nullopt) << "duplicate sequence";
  PickCommand stale = Command(4, {100, 50, 40});
  EXPECT_NE(gate.Admit(&stale), std::nullopt) << "stale sequence";
  PickCommand outside = Command(6, {100, 50, -10});
  EXPECT_NE(gate.Admit(&outside), std::nullopt) << "below the workspace";
  PickCommand high_retreat = Command(7, {100, 50, 480});
  EXPECT_NE(gate.Admit(&high_retreat), std::nullopt) << "retreat above the workspace";
  PickCommand far = Command(8, {390, 390, 300});
  EXPECT_NE(gate.Admit(&far), std::nullopt) << "beyond reach";
  PickCommand nan = Command(9, {std::nan(""), 0, 40});
  EXPECT_NE(gate.Admit(&nan), std::nullopt) << "non-finite";
  PickCommand next = Command(10, {0, 0, 100});
  EXPECT_EQ(gate.Admit(&next), std::nullopt) << "refusals do not consume sequence numbers";
}

// A refusal line names the pose's coordinates and the limit it breaks.
TEST(SafetyGate, RefusalsGiveTheCoordinatesAndTheLimit) {
  SafetyLimits limits;
  limits.workspace_min = {-400, -400, 0};
  limits.workspace_max = {400, 400, 500};
  SafetyGate gate(limits, true);
  PickCommand outside = Command(1, {100, 50, -10});
  const auto below = gate.Admit(&outside);
  ASSERT_NE(below, std::nullopt);
  EXPECT_NE(below->find("(100.0, 50.0, -10.0) mm"), std::string::npos) << *below;
  EXPECT_NE(below->find("z -10.0 < min 0.0"), std::string::npos) << *below;
  PickCommand far = Command(2, {390, 390, 300});
  const auto reach = gate.Admit(&far);
  ASSERT_NE(reach, std::nullopt);
  EXPECT_NE(reach->find("beyond reach: (390.0, 390.0,"), std::string::npos) << *reach;
  EXPECT_NE(reach->find("> max reach " ), std::string::npos) << *reach;
}

TEST(SafetyGate, RefusesMergedPartsFromObjectsJson) {
  // Touching parts sensing could not separate carry "merged": true in OBJECTS.json; their pose
  // may lie between two parts, so it never reaches a transport. The other part still does.
  const std::vector<SensedObject> objects = SensedObjectsFromJson(
      R"({"units":"mm","objects":[{"id":1,"centroid":[100,50,40],"height":40,"yaw_deg":0,
          "points":300,"merged":true},{"id":2,"centroid":[0,50,30],"height":30,"yaw_deg":5,
          "points":200}]})");
  ASSERT_EQ(objects.size(), 2u);
  EXPECT_TRUE(objects[0].merged);
  EXPECT_FALSE(objects[1].merged);
  SafetyGate gate(SafetyLimits{}, true);
  PickCommand merged = PlanPick(objects[0], Eigen::Isometry3d::Identity(), {}, 1, 0.0);
  const auto refusal = gate.Admit(&merged);
  ASSERT_NE(refusal, std::nullopt);
  EXPECT_NE(refusal->find("merged"), std::string::npos) << *refusal;
  PickCommand single = PlanPick(objects[1], Eigen::Isometry3d::Identity(), {}, 2, 0.0);
  EXPECT_EQ(gate.Admit(&single), std::nullopt);
}

TEST(SafetyGate, NoFrameCalibrationSendsNothing) {
  SafetyGate gate(SafetyLimits{}, false);
  PickCommand command = Command(1, {100, 50, 40});
  EXPECT_NE(gate.Admit(&command), std::nullopt);
}

}  // namespace
}  // namespace hnnstereo::robot

namespace hnnstereo::robot {
namespace {

TEST(PickPlanning, ARoundPartHasNoYawAndIsSentYawZero) {
  // OBJECTS.json gives a round part yaw_deg null (vision::ObjectsJson); the link sends 0.
  const std::vector<SensedObject> objects = SensedObjectsFromJson(
      R"({"units":"mm","objects":[{"id":1,"centroid":[10,20,30],"height":30,"yaw_deg":null,
          "round":true,"points":90},{"id":2,"centroid":[0,0,20],"height":20,"yaw_deg":12.5,
          "round":false,"points":80}]})");
  ASSERT_EQ(objects.size(), 2u);
  EXPECT_EQ(objects[0].yaw_deg, 0.0);
  EXPECT_EQ(objects[1].yaw_deg, 12.5);
  // A part that is not round needs its yaw.
  EXPECT_THROW(SensedObjectsFromJson(R"({"objects":[{"id":1,"centroid":[0,0,9],"height":9,
                                         "yaw_deg":null}]})"),
               std::invalid_argument);
}

}  // namespace
}  // namespace hnnstereo::robot
