// vision-server://HOST:PORT - the ASCII vision server a URScript program (or any robot that can
// open a TCP socket and read parenthesised floats) talks to. The vision side listens; the robot
// connects, sends `TRIG\n` and reads one line `(st,x,y,z,rx,ry,rz)\n` - the form URScript's
// socket_read_ascii_float(7) parses. Protocol, units and codes: docs/robot_ascii.md.
//
// The TCP server core (robot/tcp_server.h) holds the listening socket, the robot and whatever
// else connects (monitors, scanners, hostile clients), and their limits (LinkOptions::server);
// this file is the line protocol on top. No connection is ever waited on except the robot's
// reply in Send. Single-threaded: all socket work happens inside the calls the cell loop makes
// (WaitForTrigger, Send, WaitForAcknowledge), so there is nothing to lock but the stop request,
// which SendCellCommand may make from another thread.
#include <poll.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "robot/link.h"
#include "robot/tcp_server.h"
#include "robot/vision_server_protocol.h"

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;

int RemainingMs(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  return left.count() <= 0 ? 0 : static_cast<int>(left.count());
}

using vision_server::ReplyLine;

class VisionServerLink final : public RobotLink, private TcpServerProtocol {
 public:
  VisionServerLink(const LinkUri& uri, SafetyGate gate, LinkOptions options)
      : RobotLink(std::move(gate), std::move(options)),
        host_(uri.host),
        server_(uri.host, uri.port,
                TcpServerSettings{"vision-server", "",
                                  4 * this->options().server.max_line_bytes,
                                  this->options().io_timeout, this->options().server},
                *this) {}

  std::string Describe() const override {
    return "vision-server://" + host_ + ":" + std::to_string(server_.port());
  }

  Trigger WaitForTrigger(std::chrono::milliseconds timeout) override {
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      if (TakeStop()) return {TriggerKind::kStop, request_sequence_};
      // Complete requests already buffered first (a robot may pipeline NEXT and TRIG).
      if (auto trigger = ProcessLines()) return *trigger;
      if (Clock::now() >= deadline) return {TriggerKind::kIdle, request_sequence_};
      PollOnce(deadline);
    }
  }

  AckKind WaitForAcknowledge(std::chrono::milliseconds) override {
    // The reply was written (or not) in Send; writing it is the acknowledge.
    if (TakeStop()) return AckKind::kStop;
    const AckKind ack = last_ack_;
    last_ack_ = AckKind::kPeerLost;
    return ack;
  }

  void SendCellCommand(CellCommand command) override {
    if (command != CellCommand::kStop) {
      throw std::runtime_error(std::string("vision-server: '") + CellCommandName(command) +
                               "' not supported by vision-server");
    }
    std::lock_guard<std::mutex> lock(stop_mutex_);
    stop_requested_ = true;  // the loop's next call drops the pending poses and reports a stop
  }

  LinkStats Stats() const override {
    LinkStats stats = stats_;
    stats.peer_connected = Robot() != nullptr;
    stats.peer_heard_steady_s =
        heard_ == Clock::time_point{} ? 0.0
                                      : std::chrono::duration<double>(heard_.time_since_epoch()).count();
    return stats;
  }

 protected:
  void Send(const CycleResult& admitted) override {
    ++stats_.cycles_published;
    ClearPending();
    last_ack_ = AckKind::kPeerLost;
    if (admitted.status < 0 && !admitted.error.empty()) {
      Log("cycle " + std::to_string(admitted.request_sequence) + " status " +
          std::to_string(admitted.status) + ": " + admitted.error);
    }
    // Take what the clients sent meanwhile (keeping their requests) so a robot that has gone
    // away is seen now rather than after a write into a dead socket.
    PollOnce(Clock::now());
    if (Robot() == nullptr) return;  // nobody to answer: kPeerLost
    if (admitted.status < 0) {
      if (WriteRobotReply(ReplyLine(admitted.status, nullptr))) last_ack_ = AckKind::kAcknowledged;
      return;
    }
    pending_.assign(admitted.picks.begin(), admitted.picks.end());
    if (pending_.empty()) {
      if (WriteRobotReply(ReplyLine(0, nullptr))) last_ack_ = AckKind::kAcknowledged;
      return;
    }
    if (WriteRobotReply(ReplyLine(1, &pending_.front()))) {
      ++stats_.poses_sent;
      pending_.pop_front();
      last_ack_ = AckKind::kAcknowledged;
    }
  }

 private:
  // The robot is the connection that made the last valid request (TRIG, NEXT or STOP); the
  // others are answered, limited and closed by the server core without ever blocking.
  const TcpConnection* Robot() const {
    for (const TcpConnection& connection : server_.connections()) {
      if (connection.id == robot_id_ && !connection.closing()) return &connection;
    }
    return nullptr;
  }
  TcpConnection* Robot() { return const_cast<TcpConnection*>(std::as_const(*this).Robot()); }

  bool TakeStop() {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    if (!stop_requested_) return false;
    stop_requested_ = false;
    ClearPending();
    return true;
  }

  void ClearPending() { pending_.clear(); }

  /// The buffered requests of every connection, in turn, until one is a trigger or a stop.
  std::optional<Trigger> ProcessLines() {
    for (std::size_t i = 0; i < server_.connections().size(); ++i) {
      const int id = server_.connections()[i].id;
      for (;;) {
        TcpConnection* connection = server_.Find(id);
        if (connection == nullptr || connection->closing()) break;
        if (!vision_server::HasCompleteLine(connection->input)) break;
        // Over its request rate: the line waits (the server wakes when a token is due) and, its
        // buffer full, the client is not read from - TCP flow control slows it, nobody else.
        if (!server_.TakeToken(*connection)) break;
        connection->request_started = Clock::now();
        const std::string line = vision_server::TakeLine(&connection->input);
        const vision_server::Request request = vision_server::ParseRequest(line);
        if (request == vision_server::Request::kMalformed) {
          Malformed(*connection, "unknown request '" + vision_server::Printable(line) + "'");
          continue;
        }
        BecomeRobot(*connection);
        if (request == vision_server::Request::kTrigger) {
          ++stats_.triggers;
          return Trigger{TriggerKind::kTrigger, ++request_sequence_};
        }
        if (request == vision_server::Request::kStop) {
          ClearPending();
          return Trigger{TriggerKind::kStop, request_sequence_};
        }
        ReplyNext();
      }
    }
    server_.CloseMarked();
    return std::nullopt;
  }

  /// A valid request from another connection than the robot's: that client is the robot now
  /// (a restarted robot program); the old connection is closed and its poses dropped.
  void BecomeRobot(TcpConnection& connection) {
    connection.last_valid = Clock::now();
    if (connection.id == robot_id_) return;
    if (robot_id_ >= 0) {
      ++stats_.reconnects;
      if (TcpConnection* old = server_.Find(robot_id_)) {
        old->MarkForClose("a new robot connection replaces it");
      }
    }
    if (!pending_.empty()) {
      stats_.dropped_on_reconnect += static_cast<int>(pending_.size());
      Log("new robot connection: " + std::to_string(pending_.size()) + " pending pose(s) dropped");
      ClearPending();
    }
    robot_id_ = connection.id;
    server_.CloseMarked();
  }

  // Waits until the deadline (or a connection's own deadline) for connections or bytes, and
  // takes them; never blocks on one client.
  void PollOnce(Clock::time_point deadline) {
    server_.CloseMarked();
    server_.Wait(deadline);
    server_.EndRound();
  }

  // TcpServerProtocol: a request is one line.
  bool HasWholeRequest(const TcpConnection& connection) const override {
    return vision_server::HasCompleteLine(connection.input);
  }
  // Only the unterminated tail counts against the line limit; longer is answered -4 and closed.
  void OnReceived(TcpConnection& connection, const char* bytes, std::size_t count) override {
    if (connection.id == robot_id_) heard_ = Clock::now();
    const vision_server::Appended appended =
        vision_server::AppendReceived(&connection.input, bytes, count);
    if (appended.tail_started) connection.request_started = Clock::now();
    if (appended.tail > limits().max_line_bytes) {
      Malformed(connection, "request longer than " + std::to_string(limits().max_line_bytes) +
                                " bytes without a newline; connection closed");
      connection.MarkForClose("line too long");
    }
  }
  void OnRequestIncomplete(TcpConnection& connection) override {
    connection.input.clear();
    Malformed(connection, "request incomplete after " +
                              std::to_string(options().io_timeout.count()) + " ms (no newline)");
  }
  bool IsProtected(const TcpConnection& connection) const override {
    return connection.id == robot_id_;
  }
  bool LogsLoss(const TcpConnection& connection, int) const override {
    return connection.id == robot_id_;
  }
  std::string DescribeConnection(const TcpConnection& connection) const override {
    return connection.id == robot_id_ ? "robot connection" : "connection from " + connection.peer;
  }
  void OnAccepted(TcpConnection&) override { ++stats_.connections; }
  void WriteLog(const std::string& line) override { Log(line); }

  const ServerLimits& limits() const { return options().server; }

  void ReplyNext() {
    TcpConnection* robot = Robot();
    if (robot == nullptr) return;
    if (pending_.empty()) {
      server_.Queue(*robot, ReplyLine(0, nullptr));
      return;
    }
    server_.Queue(*robot, ReplyLine(1, &pending_.front()));
    ++stats_.poses_sent;
    pending_.pop_front();
  }

  void Malformed(TcpConnection& connection, const std::string& why) {
    ++stats_.malformed;
    // Logged for the robot; a stranger's garbage is only counted (it could flood the log).
    if (connection.id == robot_id_ || connection.last_valid) Log("malformed request: " + why);
    server_.Queue(connection, ReplyLine(kErrorMalformedRequest, nullptr));
  }

  // Writes one reply to the robot within io_timeout. False (and the connection closed) when it
  // cannot. Only the robot's replies wait (the cycle's acknowledge is that write).
  bool WriteRobotReply(const std::string& line) {
    TcpConnection* robot = Robot();
    if (robot == nullptr) return false;
    const int id = robot->id;
    server_.Queue(*robot, line);
    const auto deadline = Clock::now() + options().io_timeout;
    for (;;) {
      robot = server_.Find(id);
      if (robot == nullptr || robot->closing()) break;
      if (robot->output.empty()) return true;
      pollfd fd{robot->fd, POLLOUT, 0};
      const int wait_ms = RemainingMs(deadline);
      if (wait_ms <= 0 || poll(&fd, 1, wait_ms) < 0) {
        Log("reply not taken by the robot within " + std::to_string(options().io_timeout.count()) +
            " ms; connection closed");
        robot->MarkForClose("reply not taken", false);
        break;
      }
      server_.Flush(*robot);
    }
    server_.CloseMarked();
    return false;
  }

  std::string host_;
  int robot_id_ = -1;          ///< connection that made the last valid request
  Clock::time_point heard_{};  ///< when the robot last sent anything
  std::deque<PickCommand> pending_;   ///< admitted poses not yet sent (NEXT serves them)
  AckKind last_ack_ = AckKind::kPeerLost;
  std::uint32_t request_sequence_ = 0;
  std::mutex stop_mutex_;
  bool stop_requested_ = false;
  LinkStats stats_;
  TcpServer server_;  // last: its connections are closed before the state above goes
};

}  // namespace

std::unique_ptr<RobotLink> MakeVisionServerLink(const LinkUri& uri, SafetyGate gate,
                                                LinkOptions options) {
  if (!uri.query.empty()) {
    throw std::invalid_argument("robot URI '" + uri.text + "': vision-server takes no options");
  }
  return std::make_unique<VisionServerLink>(uri, std::move(gate), std::move(options));
}

}  // namespace hnnstereo::robot
