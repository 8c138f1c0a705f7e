// vision-server://: the ASCII vision server against an in-process TCP client on 127.0.0.1.
// The link does its socket work inside the calls the cell loop makes, so one thread can play
// both sides: the client writes, the test calls the link, the client reads.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "robot/link.h"
#include "robot/pick_planning.h"
#include "robot/vision_server_protocol.h"

namespace hnnstereo::robot {
namespace {

using std::chrono::milliseconds;

struct Reply {
  bool ok = false;  ///< exactly 7 numbers in parentheses, newline-terminated
  std::vector<double> values;
};

// A robot: blocking socket with a receive timeout, like URScript's 2 s socket reads.
class Client {
 public:
  explicit Client(int port) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    timeval timeout{2, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  }
  ~Client() { Close(); }
  bool connected() const { return connected_; }
  void Send(const std::string& text) {
    ASSERT_EQ(send(fd_, text.data(), text.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(text.size()));
  }
  /// One line (without '\n'); empty on timeout or EOF.
  std::string ReadLine() {
    std::string line;
    char c = 0;
    while (recv(fd_, &c, 1, 0) == 1) {
      if (c == '\n') return line;
      line += c;
    }
    return {};
  }
  Reply ReadReply() {
    Reply reply;
    const std::string line = ReadLine();
    if (line.size() < 2 || line.front() != '(' || line.back() != ')') return reply;
    std::stringstream fields(line.substr(1, line.size() - 2));
    std::string field;
    while (std::getline(fields, field, ',')) {
      std::size_t used = 0;
      try {
        reply.values.push_back(std::stod(field, &used));
      } catch (const std::exception&) {
        return reply;
      }
      if (used != field.size()) return reply;
    }
    reply.ok = reply.values.size() == 7;
    return reply;
  }
  /// True when the server closed the connection (EOF within the receive timeout).
  bool SeesEof() {
    char c = 0;
    return recv(fd_, &c, 1, 0) == 0;
  }
  void Close() {
    if (fd_ >= 0) close(fd_);
    fd_ = -1;
  }
  void Reset() {  // vanish with a TCP reset, like a killed robot program
    linger hard{1, 0};
    setsockopt(fd_, SOL_SOCKET, SO_LINGER, &hard, sizeof hard);
    Close();
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

// A tool-down pick at (x, y, z) of the robot frame, as the cell loop plans it.
PickCommand Pick(std::uint32_t sequence, double x, double y, double z, double yaw_deg) {
  return PlanPick({static_cast<int>(sequence), {x, y, z}, z, yaw_deg},
                  Eigen::Isometry3d::Identity(), {}, sequence, 0.0);
}

class VisionServerLinkTest : public ::testing::Test {
 protected:
  void SetUp() override {
    LinkOptions options;
    options.io_timeout = milliseconds(300);
    options.log = [this](const std::string& line) { log_.push_back(line); };
    link_ = OpenLink("vision-server://127.0.0.1:0", SafetyGate(SafetyLimits{}, true), options);
    const std::string described = link_->Describe();
    ASSERT_EQ(described.rfind("vision-server://127.0.0.1:", 0), 0u) << described;
    port_ = std::stoi(described.substr(described.rfind(':') + 1));
    ASSERT_GT(port_, 0);
  }

  /// TRIG from `client`, the link sees it, publishes `picks`, returns the acknowledge.
  AckKind Cycle(Client& client, std::vector<PickCommand> picks) {
    client.Send("TRIG\n");
    const Trigger trigger = link_->WaitForTrigger(milliseconds(1000));
    EXPECT_EQ(trigger.kind, TriggerKind::kTrigger);
    CycleResult cycle;
    cycle.request_sequence = trigger.request_sequence;
    cycle.picks = std::move(picks);
    link_->Publish(cycle);
    return link_->WaitForAcknowledge(milliseconds(1000));
  }

  std::unique_ptr<RobotLink> link_;
  int port_ = 0;
  std::vector<std::string> log_;
};

TEST_F(VisionServerLinkTest, IdleWithoutARobotWithinTheTimeout) {
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(150)).kind, TriggerKind::kIdle);
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_GE(took, milliseconds(140));
  EXPECT_LT(took, milliseconds(1000));
}

TEST_F(VisionServerLinkTest, TrigRepliesTheTallestPoseInMetresAndARotationVectorThenNext) {
  Client robot(port_);
  ASSERT_TRUE(robot.connected());
  EXPECT_EQ(Cycle(robot, {Pick(1, 100, 50, 20, 30), Pick(2, -250, 120.5, 35, -45)}),
            AckKind::kAcknowledged);
  const Reply first = robot.ReadReply();
  ASSERT_TRUE(first.ok);
  EXPECT_EQ(first.values[0], 1.0);
  EXPECT_NEAR(first.values[1], 0.100, 1e-6);
  EXPECT_NEAR(first.values[2], 0.050, 1e-6);
  EXPECT_NEAR(first.values[3], 0.020, 1e-6);
  // The rotation vector rebuilds the command's orientation: tool down, yaw 30 deg.
  const Eigen::Vector3d rotation_vector(first.values[4], first.values[5], first.values[6]);
  EXPECT_LE(rotation_vector.norm(), std::numbers::pi + 1e-6);
  const Eigen::Quaterniond rebuilt(
      Eigen::AngleAxisd(rotation_vector.norm(), rotation_vector.normalized()));
  EXPECT_LT(rebuilt.angularDistance(Pick(1, 0, 0, 0, 30).orientation), 1e-5);

  robot.Send("NEXT\n");
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(200)).kind, TriggerKind::kIdle);
  const Reply second = robot.ReadReply();
  ASSERT_TRUE(second.ok);
  EXPECT_EQ(second.values[0], 1.0);
  EXPECT_NEAR(second.values[1], -0.250, 1e-6);
  EXPECT_NEAR(second.values[2], 0.1205, 1e-6);
  robot.Send("NEXT\r\n");  // socket_send_line may add a CR
  link_->WaitForTrigger(milliseconds(200));
  const Reply exhausted = robot.ReadReply();
  ASSERT_TRUE(exhausted.ok);
  EXPECT_EQ(exhausted.values, std::vector<double>(7, 0.0));

  const LinkStats stats = link_->Stats();
  EXPECT_EQ(stats.connections, 1);
  EXPECT_EQ(stats.triggers, 1);
  EXPECT_EQ(stats.poses_sent, 2);
  EXPECT_EQ(stats.cycles_published, 1);
  EXPECT_EQ(stats.malformed, 0);
}

TEST_F(VisionServerLinkTest, AnEmptyCycleRepliesStatusZero) {
  Client robot(port_);
  EXPECT_EQ(Cycle(robot, {}), AckKind::kAcknowledged);
  const Reply reply = robot.ReadReply();
  ASSERT_TRUE(reply.ok);
  EXPECT_EQ(reply.values, std::vector<double>(7, 0.0));
}

TEST_F(VisionServerLinkTest, StopEndsTheLoop) {
  Client robot(port_);
  robot.Send("STOP\n");
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(1000)).kind, TriggerKind::kStop);
}

TEST_F(VisionServerLinkTest, MalformedRequestsAreAnsweredAndTheConnectionKept) {
  Client robot(port_);
  robot.Send("HELLO\n");
  robot.Send("trig\n");
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(200)).kind, TriggerKind::kIdle);
  for (int i = 0; i < 2; ++i) {
    const Reply reply = robot.ReadReply();
    ASSERT_TRUE(reply.ok);
    EXPECT_EQ(reply.values[0], kErrorMalformedRequest);
  }
  EXPECT_EQ(link_->Stats().malformed, 2);
  EXPECT_EQ(Cycle(robot, {Pick(1, 10, 10, 10, 0)}), AckKind::kAcknowledged);
  EXPECT_EQ(robot.ReadReply().values.at(0), 1.0);
}

TEST_F(VisionServerLinkTest, AnOversizedLineIsMalformedAndClosesTheConnection) {
  Client robot(port_);
  robot.Send(std::string(300, 'A'));
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(200)).kind, TriggerKind::kIdle);
  const Reply reply = robot.ReadReply();
  ASSERT_TRUE(reply.ok);
  EXPECT_EQ(reply.values[0], kErrorMalformedRequest);
  EXPECT_TRUE(robot.SeesEof());
  EXPECT_EQ(link_->Stats().malformed, 1);
  // The server goes on: a new robot is served.
  Client next(port_);
  EXPECT_EQ(Cycle(next, {Pick(1, 10, 10, 10, 0)}), AckKind::kAcknowledged);
  EXPECT_EQ(next.ReadReply().values.at(0), 1.0);
}

TEST_F(VisionServerLinkTest, AnIncompleteRequestTimesOutAsMalformed) {
  Client robot(port_);
  robot.Send("TR");
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(600)).kind, TriggerKind::kIdle);
  const Reply reply = robot.ReadReply();
  ASSERT_TRUE(reply.ok);
  EXPECT_EQ(reply.values[0], kErrorMalformedRequest);
}

TEST_F(VisionServerLinkTest, ARobotVanishingMidCycleIsPeerLostNotACrash) {
  for (bool reset : {false, true}) {
    Client robot(port_);
    robot.Send("TRIG\n");
    const Trigger trigger = link_->WaitForTrigger(milliseconds(1000));
    ASSERT_EQ(trigger.kind, TriggerKind::kTrigger);
    if (reset) {
      robot.Reset();
    } else {
      robot.Close();
    }
    CycleResult cycle;
    cycle.request_sequence = trigger.request_sequence;
    cycle.picks = {Pick(reset ? 2 : 1, 10, 10, 10, 0)};
    link_->Publish(cycle);  // must not raise SIGPIPE
    EXPECT_EQ(link_->WaitForAcknowledge(milliseconds(500)), AckKind::kPeerLost);
  }
  EXPECT_EQ(link_->Stats().poses_sent, 0);
}

TEST_F(VisionServerLinkTest, AReconnectDropsThePendingPoses) {
  Client robot(port_);
  ASSERT_EQ(Cycle(robot, {Pick(1, 10, 10, 10, 0), Pick(2, 20, 10, 10, 0), Pick(3, 30, 10, 10, 0)}),
            AckKind::kAcknowledged);
  EXPECT_EQ(robot.ReadReply().values.at(0), 1.0);
  Client again(port_);  // the robot program restarted
  again.Send("NEXT\n");
  link_->WaitForTrigger(milliseconds(300));
  const Reply reply = again.ReadReply();
  ASSERT_TRUE(reply.ok);
  EXPECT_EQ(reply.values[0], 0.0);  // nothing of the old cycle
  const LinkStats stats = link_->Stats();
  EXPECT_EQ(stats.dropped_on_reconnect, 2);
  EXPECT_EQ(stats.connections, 2);
  EXPECT_EQ(stats.reconnects, 1);
  EXPECT_TRUE(robot.SeesEof());  // the old connection was closed
}

TEST_F(VisionServerLinkTest, APoseOutsideTheWorkspaceIsNeverSent) {
  Client robot(port_);
  // Only pick outside the workspace (x 450 > 400): the gate refuses it, st = -3.
  EXPECT_EQ(Cycle(robot, {Pick(1, 450, 0, 20, 0)}), AckKind::kAcknowledged);
  const Reply refused = robot.ReadReply();
  ASSERT_TRUE(refused.ok);
  EXPECT_EQ(refused.values, (std::vector<double>{kErrorAllRefused, 0, 0, 0, 0, 0, 0}));
  // One outside, one inside: only the inside one ever reaches the wire.
  EXPECT_EQ(Cycle(robot, {Pick(2, 0, -450, 20, 0), Pick(3, 100, 100, 20, 0)}),
            AckKind::kAcknowledged);
  const Reply admitted = robot.ReadReply();
  EXPECT_EQ(admitted.values.at(0), 1.0);
  EXPECT_NEAR(admitted.values.at(1), 0.100, 1e-6);
  robot.Send("NEXT\n");
  link_->WaitForTrigger(milliseconds(200));
  EXPECT_EQ(robot.ReadReply().values.at(0), 0.0);
  EXPECT_EQ(link_->Stats().poses_sent, 1);
}

TEST_F(VisionServerLinkTest, CellCommandsOtherThanStopAreRefusedAndStopDropsPending) {
  EXPECT_THROW(link_->SendCellCommand(CellCommand::kHome), std::runtime_error);
  EXPECT_THROW(link_->SendCellCommand(CellCommand::kOpen), std::runtime_error);
  Client robot(port_);
  ASSERT_EQ(Cycle(robot, {Pick(1, 10, 10, 10, 0), Pick(2, 20, 10, 10, 0)}),
            AckKind::kAcknowledged);
  robot.ReadReply();
  link_->SendCellCommand(CellCommand::kStop);
  EXPECT_EQ(link_->WaitForTrigger(milliseconds(100)).kind, TriggerKind::kStop);
  robot.Send("NEXT\n");
  link_->WaitForTrigger(milliseconds(200));
  EXPECT_EQ(robot.ReadReply().values.at(0), 0.0);
}

TEST(VisionServerLinkUri, RejectsOptionsAndReportsAPortInUse) {
  EXPECT_THROW(OpenLink("vision-server://127.0.0.1:0?x=1", SafetyGate(SafetyLimits{}, true), {}),
               std::invalid_argument);
  auto first = OpenLink("vision-server://127.0.0.1:0", SafetyGate(SafetyLimits{}, true), {});
  const std::string port = first->Describe().substr(first->Describe().rfind(':') + 1);
  EXPECT_THROW(
      OpenLink("vision-server://127.0.0.1:" + port, SafetyGate(SafetyLimits{}, true), {}),
      std::runtime_error);
}


// The protocol without the sockets (robot/vision_server_protocol.h), as the link uses it.
TEST(VisionServerProtocol, LinesAreCutTrimmedAndParsed) {
  std::string input;
  const auto append = [&input](const std::string& bytes) {
    return vision_server::AppendReceived(&input, bytes.data(), bytes.size());
  };
  vision_server::Appended appended = append("  TRIG\r");
  EXPECT_EQ(appended.tail, 7u);
  EXPECT_TRUE(appended.tail_started);
  EXPECT_FALSE(vision_server::HasCompleteLine(input));
  appended = append("\nNEXT\n\tSTOP \nnext\nHEL");
  EXPECT_EQ(appended.tail, 3u);
  EXPECT_FALSE(appended.tail_started);  // the tail "  TRIG\r" had begun before
  using vision_server::Request;
  const std::vector<std::pair<std::string, Request>> expected = {
      {"TRIG", Request::kTrigger}, {"NEXT", Request::kNext}, {"STOP", Request::kStop},
      {"next", Request::kMalformed}};
  for (const auto& [line, request] : expected) {
    ASSERT_TRUE(vision_server::HasCompleteLine(input));
    const std::string taken = vision_server::TakeLine(&input);
    EXPECT_EQ(taken, line);
    EXPECT_EQ(vision_server::ParseRequest(taken), request) << taken;
  }
  EXPECT_EQ(input, "HEL");
  EXPECT_FALSE(vision_server::HasCompleteLine(input));
  appended = append("LO\n");
  EXPECT_EQ(appended.tail, 0u);
  EXPECT_EQ(vision_server::TakeLine(&input), "HELLO");
  EXPECT_TRUE(input.empty());
  append("\r \n");
  EXPECT_EQ(vision_server::TakeLine(&input), "");
}

TEST(VisionServerProtocol, LogTextIsPrintableAndRepliesAreOneLine) {
  EXPECT_EQ(vision_server::Printable(std::string("A\0\x7f\xff", 4)), "A???");
  EXPECT_EQ(vision_server::Printable(std::string(50, 'x')), std::string(40, 'x') + "...");
  EXPECT_EQ(vision_server::ReplyLine(kErrorMalformedRequest, nullptr),
            "(-4,0.000000,0.000000,0.000000,0.000000,0.000000,0.000000)\n");
  PickCommand pick;
  pick.position_mm = Eigen::Vector3d(-150.0, 80.0, 60.0);
  EXPECT_EQ(vision_server::ReplyLine(1, &pick),
            "(1,-0.150000,0.080000,0.060000,0.000000,0.000000,0.000000)\n");
}

}  // namespace
}  // namespace hnnstereo::robot
