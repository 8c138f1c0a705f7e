// The transport-independent robot link: URI parsing, pick planning, FRAME.yml, the gate in
// RobotLink::Publish, and the cell loop against a recording fake transport.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "robot/cell_loop.h"
#include "robot/frame_io.h"
#include "robot/link.h"
#include "robot/pick_planning.h"

namespace hnnstereo::robot {
namespace {

namespace fs = std::filesystem;

TEST(ParseLinkUri, AcceptsEveryTransportForm) {
  const LinkUri dry = ParseLinkUri("dryrun:out/picks.jsonl");
  EXPECT_EQ(dry.scheme, "dryrun");
  EXPECT_EQ(dry.path, "out/picks.jsonl");
  const LinkUri server = ParseLinkUri("modbus-server://0.0.0.0:1502");
  EXPECT_EQ(server.host, "0.0.0.0");
  EXPECT_EQ(server.port, 1502);
  EXPECT_EQ(ParseLinkUri("vision-server://127.0.0.1:0").port, 0) << "servers may bind port 0";
  const LinkUri serial = ParseLinkUri("serial:/dev/ttyUSB0?baud=2400&flow=none");
  EXPECT_EQ(serial.path, "/dev/ttyUSB0");
  EXPECT_EQ(serial.query.at("baud"), "2400");
  EXPECT_EQ(serial.query.at("flow"), "none");
}

TEST(ParseLinkUri, RefusesMalformedUris) {
  for (const char* bad : {"", "picks.jsonl", "tcp://1.2.3.4:5", "modbus-server:1502",
                          "modbus-server://host", "modbus-server://host:70000",
                          "modbus-client://host:0", "vision-server://:x", "dryrun:",
                          "serial:/dev/ttyS0?baud", "serial:/dev/ttyS0?=3"}) {
    EXPECT_THROW(ParseLinkUri(bad), std::invalid_argument) << bad;
  }
}

TEST(PlanPick, MapsTheTopCentreAndTurnsTheYawWithTheFrame) {
  const RobotFrame frame = ThesisRobotFrame();  // half turn about z, then (600, 400, 0)
  const SensedObject object{7, {100.0, 50.0, 40.0}, 40.0, 30.0};
  const PickCommand pick = PlanPick(object, frame.robot_from_world, {}, 11, 2.5);
  EXPECT_NEAR((pick.position_mm - Eigen::Vector3d(500.0, 350.0, 40.0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR(pick.yaw_deg, 30.0, 1e-9) << "30 + 180 wraps back to 30 for a parallel gripper";
  EXPECT_EQ(pick.sequence, 11u);
  EXPECT_EQ(pick.object_id, 7);
  // The tool's z axis points down; its x axis lies along the yaw in the base plane.
  const Eigen::Matrix3d r = pick.orientation.toRotationMatrix();
  EXPECT_NEAR((r.col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 0.0, 1e-12);
  const double yaw = std::atan2(r(1, 0), r(0, 0)) * 180.0 / std::numbers::pi;
  EXPECT_NEAR(yaw, 30.0, 1e-9);
  EXPECT_EQ(pick.Check(), "");
}

TEST(PlanPick, WrapsYawIntoTheHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(WrapYawDeg(90.0), 90.0);
  EXPECT_DOUBLE_EQ(WrapYawDeg(-90.0), 90.0);
  EXPECT_DOUBLE_EQ(WrapYawDeg(135.0), -45.0);
  EXPECT_DOUBLE_EQ(WrapYawDeg(-200.0), -20.0);
  EXPECT_DOUBLE_EQ(WrapYawDeg(270.0), 90.0);
}

TEST(SensedObjectsFromJson, ReadsPickOutputAndRefusesBadFiles) {
  const auto objects = SensedObjectsFromJson(
      R"({"units":"mm","objects":[{"id":2,"centroid":[1,2,30],"height":30,"yaw_deg":-5}]})");
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0].id, 2);
  EXPECT_DOUBLE_EQ(objects[0].top_centre_world.z(), 30.0);
  EXPECT_THROW(SensedObjectsFromJson("{"), std::invalid_argument);
  EXPECT_THROW(SensedObjectsFromJson(R"({"objects":{}})"), std::invalid_argument);
  EXPECT_THROW(SensedObjectsFromJson(R"({"objects":[{"id":1,"centroid":[1,2],"height":3,
                                       "yaw_deg":0}]})"),
               std::invalid_argument);
}

// A round part's yaw is free: 0 is sent whatever the file's yaw_deg.
TEST(SensedObjectsFromJson, RoundPartsCarryYawZero) {
  const auto objects = SensedObjectsFromJson(
      R"({"objects":[{"id":1,"centroid":[1,2,30],"height":30,"yaw_deg":37,"round":true},)"
      R"({"id":2,"centroid":[5,2,30],"height":30,"yaw_deg":37,"round":false}]})");
  ASSERT_EQ(objects.size(), 2u);
  EXPECT_DOUBLE_EQ(objects[0].yaw_deg, 0.0);
  EXPECT_DOUBLE_EQ(objects[1].yaw_deg, 37.0);
}

class FrameFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("hnnstereo_frame_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(FrameFile, RoundTripsAndRefusesBrokenFrames) {
  RobotFrame frame;
  frame.robot_from_world.rotate(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 0.1, 1).normalized()));
  frame.robot_from_world.pretranslate(Eigen::Vector3d(10, -20, 30));
  frame.workspace_min = {-100, -200, 5};
  frame.workspace_max = {300, 200, 400};
  frame.rms_mm = 0.42;
  SaveRobotFrame(Path("frame.yml"), frame);
  const RobotFrame loaded = LoadRobotFrame(Path("frame.yml"));
  EXPECT_LT((loaded.robot_from_world.matrix() - frame.robot_from_world.matrix()).norm(), 1e-12);
  EXPECT_EQ(loaded.workspace_min, frame.workspace_min);
  EXPECT_EQ(loaded.workspace_max, frame.workspace_max);
  EXPECT_DOUBLE_EQ(loaded.rms_mm, 0.42);

  EXPECT_THROW(LoadRobotFrame(Path("missing.yml")), std::invalid_argument);
  std::ofstream(Path("garbage.yml")) << "not: [valid\n";
  EXPECT_THROW(LoadRobotFrame(Path("garbage.yml")), std::invalid_argument);
  // A small file whose matrix header claims 100000 x 100000 doubles (80 GB, allocated by OpenCV
  // before reading the data): refused from the header.
  std::ofstream(Path("huge.yml")) << "%YAML:1.0\nrobot_from_world: !!opencv-matrix\n   rows: 100000\n"
                                     "   cols: 100000\n   dt: d\n   data: [ 1., 0. ]\n";
  try {
    LoadRobotFrame(Path("huge.yml"));
    FAIL() << "a 100000 x 100000 matrix header was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("robot_from_world"), std::string::npos) << e.what();
  }
  // A file that ends inside an XML header: OpenCV's XML parser dereferenced a null pointer
  // (fuzz/fuzz_frame_yml.cc); frames are read as YAML only, and this one is refused.
  std::ofstream(Path("truncated_xml.yml")) << "<?xml version=";
  EXPECT_THROW(LoadRobotFrame(Path("truncated_xml.yml")), std::invalid_argument);
  // OpenCV's YAML parser looped forever on a top level that ends before the text does and a '-'
  // three characters on (fuzz_frame_yml): refused before OpenCV sees it.
  std::ofstream(Path("hang.yml")) << "%YAML:1.0\n -o\nK---\no\n";
  EXPECT_THROW(LoadRobotFrame(Path("hang.yml")), std::invalid_argument);
  std::ofstream(Path("hang2.yml")) << "%YAML:1.0\nrms_mm: 0\n...-\nz\n";
  EXPECT_THROW(LoadRobotFrame(Path("hang2.yml")), std::invalid_argument);
  // Whatever the extension, a frame is written as YAML and reads back.
  SaveRobotFrame(Path("frame.xml"), frame);
  EXPECT_DOUBLE_EQ(LoadRobotFrame(Path("frame.xml")).rms_mm, 0.42);
  // A scaled "rotation" is not rigid.
  RobotFrame scaled = frame;
  scaled.robot_from_world.linear() *= 2.0;
  EXPECT_NE(scaled.Check(), "");
  EXPECT_THROW(SaveRobotFrame(Path("scaled.yml"), scaled), std::invalid_argument);
  EXPECT_FALSE(fs::exists(Path("scaled.yml")));
  RobotFrame inverted_box = frame;
  inverted_box.workspace_min.z() = 500;
  EXPECT_NE(inverted_box.Check(), "");
  // The optional reach: absent stays absent, present reads back, non-positive is refused.
  EXPECT_FALSE(LoadRobotFrame(Path("frame.yml")).max_reach_mm.has_value());
  RobotFrame reaching = frame;
  reaching.max_reach_mm = 750.0;
  SaveRobotFrame(Path("reach.yml"), reaching);
  EXPECT_EQ(LoadRobotFrame(Path("reach.yml")).max_reach_mm, 750.0);
  reaching.max_reach_mm = -1.0;
  EXPECT_NE(reaching.Check(), "");
}

// The thesis frame covers the rendered default cell's table (vision/synth/scene_render.h: parts
// within (100, 385) +- (130, 100) mm, footprints up to 49 mm from their centre, 150 mm tall)
// with the default 50 mm approach and retreat: every such pose is inside its box and reach.
TEST(ThesisRobotFrame, CoversTheRenderedTable) {
  const RobotFrame frame = ThesisRobotFrame();
  ASSERT_TRUE(frame.max_reach_mm.has_value());
  for (const double x : {100.0 - 130.0 - 49.0, 100.0 + 130.0 + 49.0}) {
    for (const double y : {385.0 - 100.0 - 49.0, 385.0 + 100.0 + 49.0}) {
      for (const double z : {10.0, 150.0 + 50.0}) {
        const Eigen::Vector3d robot = frame.robot_from_world * Eigen::Vector3d(x, y, z);
        EXPECT_TRUE((robot.array() >= frame.workspace_min.array()).all() &&
                    (robot.array() <= frame.workspace_max.array()).all())
            << robot.transpose();
        EXPECT_LE(robot.norm(), *frame.max_reach_mm) << robot.transpose();
      }
    }
  }
}

// A transport that records what reaches it and plays back scripted triggers and acknowledges.
class FakeLink final : public RobotLink {
 public:
  FakeLink(SafetyGate gate, LinkOptions options) : RobotLink(std::move(gate), std::move(options)) {}
  std::string Describe() const override { return "fake"; }
  Trigger WaitForTrigger(std::chrono::milliseconds) override {
    if (triggers.empty()) return {TriggerKind::kStop, 0};
    const Trigger next = triggers.front();
    triggers.pop_front();
    return next;
  }
  AckKind WaitForAcknowledge(std::chrono::milliseconds) override { return AckKind::kAcknowledged; }
  void SendCellCommand(CellCommand) override {}
  LinkStats Stats() const override { return {}; }
  std::deque<Trigger> triggers;
  std::vector<CycleResult> sent;

 protected:
  void Send(const CycleResult& admitted) override { sent.push_back(admitted); }
};

LinkOptions QuietOptions() {
  LinkOptions options;
  options.log = [](const std::string&) {};
  return options;
}

TEST(CellLoop, PublishesTallestFirstWithIncreasingSequencesAndSurvivesSensingErrors) {
  FakeLink link(SafetyGate(SafetyLimits{}, true), QuietOptions());
  for (std::uint32_t r : {5u, 6u, 7u}) link.triggers.push_back({TriggerKind::kTrigger, r});
  int call = 0;
  const SenseFunction sense = [&] {
    if (++call == 2) throw std::runtime_error("left image unreadable");
    return SensedCycle{{{1, {0, 0, 20}, 20, 0}, {2, {50, 0, 60}, 60, 0}, {3, {0, 50, 40}, 40, 0}},
                       1.0};
  };
  const CellLoopReport report = RunCellLoop(link, RobotFrame{}, sense, {});
  EXPECT_EQ(report.cycles, 3);
  EXPECT_TRUE(report.stopped) << "the fake's empty trigger queue is a stop";
  EXPECT_EQ(report.sense_errors, 1);
  ASSERT_EQ(link.sent.size(), 3u);
  EXPECT_EQ(link.sent[0].request_sequence, 5u);
  ASSERT_EQ(link.sent[0].picks.size(), 3u);
  EXPECT_EQ(link.sent[0].picks[0].object_id, 2);
  EXPECT_EQ(link.sent[0].picks[1].object_id, 3);
  EXPECT_EQ(link.sent[0].picks[2].object_id, 1);
  EXPECT_EQ(link.sent[1].status, kErrorSensingFailed);
  EXPECT_NE(link.sent[1].error.find("unreadable"), std::string::npos);
  EXPECT_TRUE(link.sent[1].picks.empty());
  ASSERT_EQ(link.sent[2].picks.size(), 3u);
  EXPECT_EQ(link.sent[2].picks[0].sequence, 4u) << "sequences run on over the cycles";
}

TEST(CellLoop, TheGateInPublishDropsUnsafePicksAndFlagsACycleWithNoneLeft) {
  LinkOptions options = QuietOptions();
  options.max_poses = 2;
  FakeLink link(SafetyGate(SafetyLimits{}, true), options);
  link.triggers = {{TriggerKind::kTrigger, 1}, {TriggerKind::kTrigger, 2}};
  int call = 0;
  const SenseFunction sense = [&] {
    if (++call == 1) {  // one outside the box (y = 900), three inside: two fit max_poses
      return SensedCycle{{{1, {0, 900, 50}, 50, 0}, {2, {0, 0, 40}, 40, 0},
                          {3, {10, 0, 30}, 30, 0}, {4, {20, 0, 20}, 20, 0}},
                         0.0};
    }
    return SensedCycle{{{5, {0, 0, -50}, 10, 0}}, 0.0};  // below the table: refused
  };
  const CellLoopReport report = RunCellLoop(link, RobotFrame{}, sense, {});
  ASSERT_EQ(link.sent.size(), 2u);
  ASSERT_EQ(link.sent[0].picks.size(), 2u);
  EXPECT_EQ(link.sent[0].picks[0].object_id, 2);
  EXPECT_EQ(link.sent[0].picks[1].object_id, 3);
  EXPECT_EQ(link.sent[0].status, 0);
  EXPECT_TRUE(link.sent[1].picks.empty());
  EXPECT_EQ(link.sent[1].status, kErrorAllRefused);
  EXPECT_EQ(report.poses_published, 2);
  EXPECT_EQ(report.refused, 3);
  for (const CycleResult& cycle : link.sent) {
    for (const PickCommand& pick : cycle.picks) {
      EXPECT_TRUE((pick.position_mm.array() >= SafetyLimits{}.workspace_min.array()).all());
      EXPECT_TRUE((pick.position_mm.array() <= SafetyLimits{}.workspace_max.array()).all());
    }
  }
}

// What a status display (the cell's web page) reads of each cycle: every candidate pick sent or
// refused with the gate's reason, the times of the cycle's phases, and a call while idle.
TEST(CellLoop, LogsEachPicksOutcomeThePhaseTimesAndCallsOnIdle) {
  LinkOptions link_options = QuietOptions();
  link_options.max_poses = 1;
  FakeLink link(SafetyGate(SafetyLimits{}, true), link_options);
  link.triggers = {{TriggerKind::kIdle, 0}, {TriggerKind::kIdle, 0}, {TriggerKind::kTrigger, 3}};
  const SenseFunction sense = [] {
    return SensedCycle{{{1, {0, 900, 50}, 50, 0}, {2, {0, 0, 40}, 40, 0}, {3, {10, 0, 30}, 30, 0}},
                       0.0};
  };
  CellLoopOptions options;
  int idle_calls = 0;
  std::vector<CycleLog> logs;
  options.on_idle = [&] { ++idle_calls; };
  options.on_cycle = [&](const CycleLog& log) { logs.push_back(log); };
  RunCellLoop(link, RobotFrame{}, sense, options);
  EXPECT_EQ(idle_calls, 2);
  ASSERT_EQ(logs.size(), 1u);
  const CycleLog& log = logs[0];
  ASSERT_EQ(log.picks.size(), 3u) << "one outcome per candidate, tallest first";
  EXPECT_EQ(log.picks[0].object_id, 1);
  EXPECT_FALSE(log.picks[0].admitted);
  EXPECT_NE(log.picks[0].reason.find("workspace"), std::string::npos) << log.picks[0].reason;
  EXPECT_EQ(log.picks[1].object_id, 2);
  EXPECT_TRUE(log.picks[1].admitted);
  EXPECT_EQ(log.picks[1].reason, "");
  EXPECT_EQ(log.picks[2].object_id, 3);
  EXPECT_FALSE(log.picks[2].admitted);
  EXPECT_NE(log.picks[2].reason.find("max_poses"), std::string::npos) << log.picks[2].reason;
  EXPECT_GE(log.publish_ms, 0.0);
  EXPECT_GE(log.ack_ms, 0.0);
  EXPECT_LE(log.sense_ms + log.publish_ms + log.ack_ms, log.cycle_ms + 1e-6);
}

TEST(CellLoop, HonoursTheStopFlagAndTheCycleCount) {
  FakeLink link(SafetyGate(SafetyLimits{}, true), QuietOptions());
  for (std::uint32_t r = 1; r <= 10; ++r) link.triggers.push_back({TriggerKind::kTrigger, r});
  const SenseFunction sense = [] { return SensedCycle{}; };
  CellLoopOptions options;
  options.cycles = 4;
  EXPECT_EQ(RunCellLoop(link, RobotFrame{}, sense, options).cycles, 4);
  std::atomic<bool> stop{true};
  options.stop_requested = &stop;
  const CellLoopReport stopped = RunCellLoop(link, RobotFrame{}, sense, options);
  EXPECT_EQ(stopped.cycles, 0);
  EXPECT_TRUE(stopped.stopped);
}

}  // namespace
}  // namespace hnnstereo::robot
