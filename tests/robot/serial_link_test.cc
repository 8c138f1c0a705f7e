// serial:DEVICE - the thesis RS-232 link against a pseudo-terminal (openpty): the bytes on the
// wire, CR terminators, the 8N2 line settings read back with tcgetattr.
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <numbers>
#include <string>

#include "robot/link.h"
#include "robot/pick_planning.h"
#include "robot/thesis_arm.h"

namespace hnnstereo::robot {
namespace {

using std::chrono::milliseconds;

// A tool-down pick at (x, y, z) of the robot frame, as the cell loop plans it.
PickCommand ToolDownPick(std::uint32_t sequence, double x, double y, double z, double yaw_deg) {
  return PlanPick({static_cast<int>(sequence), {x, y, z}, z, yaw_deg},
                  Eigen::Isometry3d::Identity(), {}, sequence, 0.0);
}

SafetyGate ThesisGate() {
  SafetyLimits limits;  // ThesisRobotFrame()'s workspace
  limits.workspace_min = Eigen::Vector3d(100, -300, 0);
  limits.workspace_max = Eigen::Vector3d(600, 300, 450);
  return SafetyGate(limits, true);
}

std::string Joined(const std::vector<std::string>& lines) {
  std::string bytes;
  for (const auto& line : lines) bytes += line + "\r";
  return bytes;
}

class SerialLinkTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[128] = {};
    ASSERT_EQ(openpty(&master_, &slave_, name, nullptr, nullptr), 0);
    device_ = name;
    LinkOptions options;
    options.io_timeout = milliseconds(500);
    options.log = [this](const std::string& line) { log_.push_back(line); };
    options_ = options;
  }
  void TearDown() override {
    link_.reset();
    close(master_);
    close(slave_);
  }

  void Open(const std::string& query) {
    link_ = OpenLink("serial:" + device_ + query, ThesisGate(), options_);
  }

  /// What the far end receives within `timeout` (stops once `expected` bytes have arrived).
  std::string Received(std::size_t expected, milliseconds timeout = milliseconds(2000)) {
    std::string bytes;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (bytes.size() < expected && std::chrono::steady_clock::now() < deadline) {
      pollfd fd{master_, POLLIN, 0};
      if (poll(&fd, 1, 50) <= 0) continue;
      char buffer[256];
      const ssize_t n = read(master_, buffer, sizeof buffer);
      if (n > 0) bytes.append(buffer, static_cast<std::size_t>(n));
    }
    return bytes;
  }

  int master_ = -1;
  int slave_ = -1;
  std::string device_;
  LinkOptions options_;
  std::unique_ptr<RobotLink> link_;
  std::vector<std::string> log_;
};

TEST_F(SerialLinkTest, ConfiguresRaw8N2AtTheRequestedRate) {
  Open("?baud=2400&flow=none");
  termios tio{};
  ASSERT_EQ(tcgetattr(slave_, &tio), 0);
  EXPECT_EQ(cfgetospeed(&tio), static_cast<speed_t>(B2400));
  EXPECT_EQ(tio.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_NE(tio.c_cflag & CSTOPB, 0u);
  EXPECT_EQ(tio.c_cflag & PARENB, 0u);
  EXPECT_EQ(tio.c_cflag & CRTSCTS, 0u);
  EXPECT_EQ(tio.c_oflag & OPOST, 0u);  // no CR/LF translation on the way out
  EXPECT_EQ(link_->Describe(), "serial:" + device_ + "?baud=2400&flow=none");

  link_.reset();
  Open("?baud=9600");  // defaults: hardware flow control as in the thesis
  ASSERT_EQ(tcgetattr(slave_, &tio), 0);
  EXPECT_EQ(cfgetospeed(&tio), static_cast<speed_t>(B9600));
  EXPECT_NE(tio.c_cflag & CRTSCTS, 0u);
  EXPECT_NE(link_->Describe().find("flow=rtscts"), std::string::npos);
}

TEST_F(SerialLinkTest, RefusesBadSettingsAndDevices) {
  EXPECT_THROW(Open("?baud=2500"), std::invalid_argument);
  EXPECT_THROW(Open("?baud=fast"), std::invalid_argument);
  EXPECT_THROW(Open("?flow=xonxoff"), std::invalid_argument);
  EXPECT_THROW(Open("?parity=even"), std::invalid_argument);
  EXPECT_THROW(OpenLink("serial:/nonexistent/tty", ThesisGate(), options_), std::runtime_error);
  char path[] = "/tmp/hnnstereo-serial-XXXXXX";
  const int file = mkstemp(path);
  ASSERT_GE(file, 0);
  EXPECT_THROW(OpenLink(std::string("serial:") + path, ThesisGate(), options_),
               std::runtime_error);  // not a terminal
  close(file);
  unlink(path);
}

TEST_F(SerialLinkTest, APickGoesOutAsTheThesisSequenceWithCarriageReturns) {
  Open("?baud=2400&flow=none");
  const Trigger trigger = link_->WaitForTrigger(milliseconds(0));
  ASSERT_EQ(trigger.kind, TriggerKind::kTrigger);
  CycleResult cycle;
  cycle.request_sequence = trigger.request_sequence;
  cycle.picks = {ToolDownPick(1, 300, 50, 40, 20), ToolDownPick(2, 250, -60, 30, -10)};
  const PublishReport report = link_->Publish(cycle);
  EXPECT_EQ(report.admitted, 2);
  EXPECT_EQ(link_->WaitForAcknowledge(milliseconds(1000)), AckKind::kAcknowledged);

  const ThesisArmGeometry geometry;
  const ThesisPickOptions options;
  const std::string expected = Joined(ThesisPickLines(geometry, options, cycle.picks[0], 0)) +
                               Joined(ThesisPickLines(geometry, options, cycle.picks[1], 1)) +
                               Joined(ThesisAsideLines(geometry, options));
  const std::string wire = Received(expected.size());
  EXPECT_EQ(wire, expected);
  EXPECT_EQ(wire.rfind("SP 2\rPS 1,-378,-73,-1183,386,1733,0\rMO 1\rGO\r", 0), 0u);
  EXPECT_EQ(wire.find('\n'), std::string::npos);  // CR only
  EXPECT_EQ(Received(1, milliseconds(100)), "");   // and nothing more
  EXPECT_EQ(link_->Stats().poses_sent, 2);
}

TEST_F(SerialLinkTest, AnUnreachablePickIsRefusedWholeAndTheRestStillGoes) {
  Open("?flow=none");
  link_->WaitForTrigger(milliseconds(0));
  CycleResult cycle;
  // Inside the gate's workspace (x <= 600) but beyond the arm (about 380 mm at that height).
  cycle.picks = {ToolDownPick(1, 550, 0, 40, 0), ToolDownPick(2, 300, 50, 40, 20)};
  link_->Publish(cycle);
  EXPECT_EQ(link_->WaitForAcknowledge(milliseconds(1000)), AckKind::kAcknowledged);
  const ThesisArmGeometry geometry;
  const ThesisPickOptions options;
  // The reachable pick is the first to go, so it drops at the first drop point.
  const std::string expected = Joined(ThesisPickLines(geometry, options, cycle.picks[1], 0)) +
                               Joined(ThesisAsideLines(geometry, options));
  EXPECT_EQ(Received(expected.size()), expected);
  EXPECT_EQ(Received(1, milliseconds(100)), "");
  EXPECT_EQ(link_->Stats().poses_sent, 1);
  ASSERT_FALSE(log_.empty());
  EXPECT_NE(log_.front().find("cannot reach"), std::string::npos) << log_.front();
}

TEST_F(SerialLinkTest, NothingOutsideTheWorkspaceAndNothingOnAnErrorCycle) {
  Open("?flow=none");
  CycleResult outside;
  outside.picks = {ToolDownPick(1, 50, 0, 40, 0)};  // x 50 < workspace x min 100
  link_->Publish(outside);
  CycleResult failed;
  failed.status = kErrorSensingFailed;
  failed.error = "images unreadable";
  link_->Publish(failed);
  EXPECT_EQ(link_->WaitForAcknowledge(milliseconds(500)), AckKind::kAcknowledged);
  EXPECT_EQ(Received(1, milliseconds(200)), "");
  EXPECT_EQ(link_->Stats().cycles_published, 2);
}

TEST_F(SerialLinkTest, CellCommandsMapToTheThesisCommands) {
  Open("?flow=none");
  link_->SendCellCommand(CellCommand::kHome);
  link_->SendCellCommand(CellCommand::kOpen);
  link_->SendCellCommand(CellCommand::kClose);
  EXPECT_EQ(Received(19), "OG\rGO\rGF 0\rGC\rGF 1\r");
  link_->SendCellCommand(CellCommand::kStop);
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(0)).kind, TriggerKind::kStop);
  EXPECT_EQ(Received(1, milliseconds(100)), "");
}

}  // namespace
}  // namespace hnnstereo::robot
