// vision-server://HOST:PORT - the ASCII vision server a URScript program (or any robot that can
// open a TCP socket and read parenthesised floats) talks to. The vision side listens; the robot
// connects, sends `TRIG\n` and reads one line `(st,x,y,z,rx,ry,rz)\n` - the form URScript's
// socket_read_ascii_float(7) parses. Protocol, units and codes: docs/robot_ascii.md.
//
// Plain POSIX sockets and poll(): one listening socket, one robot and whatever else connects
// (monitors, scanners, hostile clients), a few bytes per cycle. No Debian library does such a
// small line server better, and this keeps every wait bounded by a timeout we choose. Every
// connection has its own buffers and timers and none is ever waited on except the robot's
// reply in Send; limits (connections, line length, request rate, timeouts): LinkOptions::server
// (robot/link.h). Single-threaded: all socket work happens inside the calls the cell loop makes
// (WaitForTrigger, Send, WaitForAcknowledge), so there is nothing to lock but the stop request,
// which SendCellCommand may make from another thread.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "robot/link.h"
#include "robot/vision_server_protocol.h"

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;

std::string Errno(const std::string& what) { return what + ": " + std::strerror(errno); }

int RemainingMs(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  return left.count() <= 0 ? 0 : static_cast<int>(left.count());
}

void SetNonBlocking(int fd) {
  const int flags = fcntl(fd, F_GETFL, 0);
  if (flags < 0 || fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0) {
    throw std::runtime_error(Errno("vision-server: fcntl"));
  }
}

using vision_server::ReplyLine;

class VisionServerLink final : public RobotLink {
 public:
  VisionServerLink(const LinkUri& uri, SafetyGate gate, LinkOptions options)
      : RobotLink(std::move(gate), std::move(options)), host_(uri.host) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    addrinfo* found = nullptr;
    const std::string port = std::to_string(uri.port);
    if (const int error = getaddrinfo(host_.c_str(), port.c_str(), &hints, &found); error != 0) {
      throw std::runtime_error("vision-server: cannot resolve '" + host_ + "': " +
                               gai_strerror(error));
    }
    std::string last_error = "no address";
    for (addrinfo* a = found; a != nullptr && listen_fd_ < 0; a = a->ai_next) {
      const int fd = socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
      if (fd < 0) continue;
      const int one = 1;
      setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
      // A deep backlog: when clients connect and hang up by the thousand, a full accept queue
      // drops the robot's SYN and its connect waits for the retransmission (1 s, then 3 s).
      if (bind(fd, a->ai_addr, a->ai_addrlen) == 0 && listen(fd, SOMAXCONN) == 0) {
        listen_fd_ = fd;
      } else {
        last_error = std::strerror(errno);
        close(fd);
      }
    }
    freeaddrinfo(found);
    if (listen_fd_ < 0) {
      throw std::runtime_error("vision-server: cannot listen on " + host_ + ":" + port + ": " +
                               last_error);
    }
    SetNonBlocking(listen_fd_);
    sockaddr_storage bound{};
    socklen_t length = sizeof bound;
    getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &length);
    port_ = bound.ss_family == AF_INET6
                ? ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port)
                : ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  }

  ~VisionServerLink() override {
    for (const Connection& connection : connections_) close(connection.fd);
    if (listen_fd_ >= 0) close(listen_fd_);
  }

  std::string Describe() const override {
    return "vision-server://" + host_ + ":" + std::to_string(port_);
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
  /// One client connection, with its own buffers and timers: nothing one client sends, or
  /// fails to send, holds up the robot (issue 15). The robot is the connection that made the
  /// last valid request (TRIG, NEXT or STOP); the others are answered, limited and closed
  /// without ever blocking.
  struct Connection {
    int fd = -1;
    int id = 0;
    std::string peer;             ///< peer address (per-peer limit, log)
    std::string input;            ///< bytes received, not yet a complete request
    std::string output;           ///< reply bytes not yet taken by the client
    Clock::time_point accepted;
    Clock::time_point partial_since;  ///< when the unterminated tail of `input` began
    Clock::time_point output_since;   ///< when `output` last became non-empty or shrank
    bool valid = false;           ///< has made a valid request
    double tokens = 0.0;          ///< request budget (token bucket, ServerLimits)
    Clock::time_point tokens_at;
    std::string close_reason;     ///< non-empty: close before the next poll
    bool log_close = true;
  };

  const ServerLimits& limits() const { return options().server; }

  Connection* Find(int id) {
    for (Connection& connection : connections_) {
      if (connection.id == id) return &connection;
    }
    return nullptr;
  }
  const Connection* Robot() const {
    for (const Connection& connection : connections_) {
      if (connection.id == robot_id_ && connection.close_reason.empty()) return &connection;
    }
    return nullptr;
  }
  Connection* Robot() { return const_cast<Connection*>(std::as_const(*this).Robot()); }

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
    for (std::size_t i = 0; i < connections_.size(); ++i) {
      const int id = connections_[i].id;
      for (;;) {
        Connection* connection = Find(id);
        if (connection == nullptr || !connection->close_reason.empty()) break;
        if (!vision_server::HasCompleteLine(connection->input)) break;
        // Over its request rate: the line waits (PollOnce wakes when a token is due) and, its
        // buffer full, the client is not read from - TCP flow control slows it, nobody else.
        if (!TakeToken(*connection)) break;
        const std::string line = NextLine(*connection);
        const vision_server::Request request = vision_server::ParseRequest(line);
        if (request != vision_server::Request::kMalformed) {
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
        } else {
          Malformed(*connection, "unknown request '" + vision_server::Printable(line) + "'");
        }
      }
    }
    CloseMarked();
    return std::nullopt;
  }

  /// A valid request from another connection than the robot's: that client is the robot now
  /// (a restarted robot program); the old connection is closed and its poses dropped.
  void BecomeRobot(Connection& connection) {
    connection.valid = true;
    if (connection.id == robot_id_) return;
    if (robot_id_ >= 0) {
      ++stats_.reconnects;
      if (Connection* old = Find(robot_id_)) {
        Mark(*old, "a new robot connection replaces it");
      }
    }
    if (!pending_.empty()) {
      stats_.dropped_on_reconnect += static_cast<int>(pending_.size());
      Log("new robot connection: " + std::to_string(pending_.size()) + " pending pose(s) dropped");
      ClearPending();
    }
    robot_id_ = connection.id;
    CloseMarked();
  }

  /// When PollOnce must look at a connection again even if nothing arrives.
  Clock::time_point NextDeadline(const Connection& connection) const {
    auto deadline = Clock::time_point::max();
    if (connection.input.find('\n') != std::string::npos) {
      deadline = std::min(deadline, TokenAvailable(connection));
    } else if (!connection.input.empty()) {
      deadline = std::min(deadline, connection.partial_since + options().io_timeout);
    }
    if (!connection.valid) {
      deadline = std::min(deadline, connection.accepted + limits().first_request_timeout);
    }
    if (!connection.output.empty()) {
      deadline = std::min(deadline, connection.output_since + options().io_timeout);
    }
    return deadline;
  }

  // Waits until the deadline (or a connection's own deadline) for connections or bytes, and
  // takes them; never blocks on one client.
  void PollOnce(Clock::time_point deadline) {
    CloseMarked();
    std::vector<pollfd> fds;
    const bool accepting = Clock::now() >= accept_paused_until_;
    fds.push_back({listen_fd_, static_cast<short>(accepting ? POLLIN : 0), 0});
    auto wake = accepting ? deadline : std::min(deadline, accept_paused_until_);
    for (const Connection& connection : connections_) {
      short events = 0;
      if (connection.input.size() < ReadAheadBytes()) events |= POLLIN;
      if (!connection.output.empty()) events |= POLLOUT;
      fds.push_back({connection.fd, events, 0});
      wake = std::min(wake, NextDeadline(connection));
    }
    const int ready = poll(fds.data(), fds.size(), RemainingMs(wake) + (wake > Clock::now()));
    if (ready < 0) {
      if (errno != EINTR) Log(Errno("poll"));
      return;
    }
    for (std::size_t i = 0; ready > 0 && i < connections_.size(); ++i) {
      const short revents = fds[i + 1].revents;
      if (revents & POLLOUT) Flush(connections_[i]);
      if (revents & (POLLIN | POLLHUP | POLLERR)) ReadAvailable(connections_[i]);
    }
    ExpireTimeouts(Clock::now());
    CloseMarked();
    if (ready > 0 && (fds[0].revents & POLLIN)) AcceptPending();
  }

  std::size_t ReadAheadBytes() const { return 4 * limits().max_line_bytes; }

  void ExpireTimeouts(Clock::time_point now) {
    for (Connection& connection : connections_) {
      if (!connection.close_reason.empty()) continue;
      if (!connection.output.empty() && now - connection.output_since > options().io_timeout) {
        Mark(connection, "replies not taken within " +
                             std::to_string(options().io_timeout.count()) + " ms");
      } else if (!connection.valid &&
                 now - connection.accepted > limits().first_request_timeout) {
        Mark(connection, "no valid request within " +
                             std::to_string(limits().first_request_timeout.count()) +
                             " ms of connecting");
      } else if (!connection.input.empty() && connection.input.find('\n') == std::string::npos &&
                 now - connection.partial_since > options().io_timeout) {
        connection.input.clear();
        Malformed(connection, "request incomplete after " +
                                  std::to_string(options().io_timeout.count()) +
                                  " ms (no newline)");
      }
    }
  }

  static void Mark(Connection& connection, std::string reason, bool log = true) {
    if (!connection.close_reason.empty()) return;
    connection.close_reason = std::move(reason);
    connection.log_close = log;
  }

  void CloseMarked() {
    for (std::size_t i = 0; i < connections_.size();) {
      Connection& connection = connections_[i];
      if (connection.close_reason.empty()) {
        ++i;
        continue;
      }
      if (connection.log_close) {
        LogLimited((connection.id == robot_id_ ? "robot connection closed: " : "connection from " +
                    connection.peer + " closed: ") + connection.close_reason);
      }
      close(connection.fd);
      connections_.erase(connections_.begin() + static_cast<std::ptrdiff_t>(i));
    }
  }

  static std::string PeerAddress(const sockaddr_storage& address) {
    char text[INET6_ADDRSTRLEN] = "?";
    if (address.ss_family == AF_INET) {
      inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in&>(address).sin_addr, text,
                sizeof text);
    } else if (address.ss_family == AF_INET6) {
      inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6&>(address).sin6_addr, text,
                sizeof text);
    }
    return text;
  }

  /// Room for a new connection from `peer` (rules: ServerLimits). The robot's connection never
  /// gives way; a silent one gives way to its own peer's newer ones after kEvictionGrace.
  bool MakeRoom(const std::string& peer) {
    const auto now = Clock::now();
    std::map<std::string, int> per_peer;
    for (const Connection& c : connections_) ++per_peer[c.peer];
    const int own = per_peer[peer];
    auto evictable = [&](const Connection& c, bool same_peer) {
      if (c.id == robot_id_ || c.valid) return false;
      return !same_peer || now - c.accepted >= kEvictionGrace;
    };
    auto evict_oldest = [&](auto&& eligible, const std::string& why) {
      std::optional<std::size_t> victim;
      for (std::size_t i = 0; i < connections_.size(); ++i) {
        if (!eligible(connections_[i])) continue;
        if (!victim || connections_[i].accepted < connections_[*victim].accepted) victim = i;
      }
      if (!victim) return false;
      Mark(connections_[*victim], "closed to make room for a new connection (" + why + ")");
      CloseMarked();
      return true;
    };
    auto own_oldest = [&](const Connection& c) { return c.peer == peer && evictable(c, true); };
    if (own >= limits().max_connections_per_peer) {
      return evict_oldest(own_oldest, "per-peer limit " +
                                          std::to_string(limits().max_connections_per_peer) +
                                          " from " + peer);
    }
    if (static_cast<int>(connections_.size()) >= limits().max_connections) {
      const std::string why = "limit " + std::to_string(limits().max_connections);
      auto heavier = [&](const Connection& c) {
        return per_peer[c.peer] >= own + 2 && evictable(c, false);
      };
      return evict_oldest(heavier, why) || evict_oldest(own_oldest, why);
    }
    return true;
  }

  void AcceptPending() {
    for (int n = 0; n < kAcceptsPerPoll; ++n) {
      sockaddr_storage address{};
      socklen_t length = sizeof address;
      const int fd = accept4(listen_fd_, reinterpret_cast<sockaddr*>(&address), &length,
                             SOCK_CLOEXEC | SOCK_NONBLOCK);
      if (fd < 0) {
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
          accept_paused_until_ = Clock::now() + kAcceptBackoff;
          LogLimited(Errno("cannot accept a connection"));
        }
        return;
      }
      Connection connection;
      connection.fd = fd;
      connection.peer = PeerAddress(address);
      if (!MakeRoom(connection.peer)) {
        close(fd);
        LogLimited("connection from " + connection.peer + " refused: no free slot");
        continue;
      }
      const int one = 1;
      setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      connection.id = ++last_connection_id_;
      connection.accepted = Clock::now();
      connection.tokens = limits().request_burst;
      connection.tokens_at = connection.accepted;
      ++stats_.connections;
      connections_.push_back(std::move(connection));
    }
  }

  // Reads what the client has sent without blocking; closes on EOF, error or an overlong line.
  void ReadAvailable(Connection& connection) {
    while (connection.close_reason.empty() && connection.input.size() < ReadAheadBytes()) {
      char buffer[512];
      const ssize_t n = recv(connection.fd, buffer,
                             std::min(sizeof buffer, ReadAheadBytes() - connection.input.size()),
                             MSG_DONTWAIT);
      if (n > 0) {
        if (connection.id == robot_id_) heard_ = Clock::now();
        // Only the unterminated tail counts against the line limit.
        const vision_server::Appended appended = vision_server::AppendReceived(
            &connection.input, buffer, static_cast<std::size_t>(n));
        if (appended.tail_started) connection.partial_since = Clock::now();
        if (appended.tail > limits().max_line_bytes) {
          Malformed(connection, "request longer than " + std::to_string(limits().max_line_bytes) +
                                    " bytes without a newline; connection closed");
          Flush(connection);
          Mark(connection, "line too long");
          return;
        }
        continue;
      }
      if (n == 0) {
        Mark(connection, connection.id == robot_id_ ? "robot disconnected" : "client hung up",
             connection.id == robot_id_);
        return;
      }
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) {
        Mark(connection, Errno("connection lost"), connection.id == robot_id_);
      }
      return;
    }
  }

  // One complete request, trimmed of spaces and the CR a `socket_send_line` may add.
  std::string NextLine(Connection& connection) {
    connection.partial_since = Clock::now();
    return vision_server::TakeLine(&connection.input);
  }

  bool TakeToken(Connection& connection) {
    const auto now = Clock::now();
    const double elapsed = std::chrono::duration<double>(now - connection.tokens_at).count();
    connection.tokens_at = now;
    connection.tokens = std::min<double>(
        limits().request_burst, connection.tokens + elapsed * limits().max_requests_per_second);
    if (connection.tokens < 1.0) return false;
    connection.tokens -= 1.0;
    return true;
  }

  Clock::time_point TokenAvailable(const Connection& connection) const {
    if (connection.tokens >= 1.0) return Clock::now();
    const double wait_s = (1.0 - connection.tokens) / limits().max_requests_per_second;
    return connection.tokens_at + std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(wait_s));
  }

  void ReplyNext() {
    Connection* robot = Robot();
    if (robot == nullptr) return;
    if (pending_.empty()) {
      Queue(*robot, ReplyLine(0, nullptr));
      return;
    }
    Queue(*robot, ReplyLine(1, &pending_.front()));
    ++stats_.poses_sent;
    pending_.pop_front();
  }

  void Malformed(Connection& connection, const std::string& why) {
    ++stats_.malformed;
    // Logged for the robot; a stranger's garbage is only counted (it could flood the log).
    if (connection.id == robot_id_ || connection.valid) Log("malformed request: " + why);
    Queue(connection, ReplyLine(kErrorMalformedRequest, nullptr));
  }

  /// Queues a reply and sends what the socket takes now; never blocks.
  void Queue(Connection& connection, const std::string& line) {
    if (connection.output.empty()) connection.output_since = Clock::now();
    connection.output += line;
    Flush(connection);
  }

  void Flush(Connection& connection) {
    while (!connection.output.empty() && connection.close_reason.empty()) {
      // MSG_NOSIGNAL: a client that vanished must not raise SIGPIPE and kill the server.
      const ssize_t n = send(connection.fd, connection.output.data(), connection.output.size(),
                             MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) {
        connection.output.erase(0, static_cast<std::size_t>(n));
        connection.output_since = Clock::now();
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      Mark(connection, Errno("reply write failed"), connection.id == robot_id_);
      return;
    }
  }

  // Writes one reply to the robot within io_timeout. False (and the connection closed) when it
  // cannot. Only the robot's replies wait (the cycle's acknowledge is that write).
  bool WriteRobotReply(const std::string& line) {
    Connection* robot = Robot();
    if (robot == nullptr) return false;
    const int id = robot->id;
    Queue(*robot, line);
    const auto deadline = Clock::now() + options().io_timeout;
    for (;;) {
      robot = Find(id);
      if (robot == nullptr || !robot->close_reason.empty()) break;
      if (robot->output.empty()) return true;
      pollfd fd{robot->fd, POLLOUT, 0};
      const int wait_ms = RemainingMs(deadline);
      if (wait_ms <= 0 || poll(&fd, 1, wait_ms) < 0) {
        Log("reply not taken by the robot within " + std::to_string(options().io_timeout.count()) +
            " ms; connection closed");
        Mark(*robot, "reply not taken", false);
        break;
      }
      Flush(*robot);
    }
    CloseMarked();
    return false;
  }

  /// Lines about clients other than the robot: at most kMaxLogLinesPerSecond, the rest
  /// counted - a flood of hostile connections must not flood the cell's log.
  void LogLimited(const std::string& line) {
    const auto now = Clock::now();
    if (now - log_window_start_ >= std::chrono::seconds(1)) {
      if (suppressed_logs_ > 0) {
        Log(std::to_string(suppressed_logs_) + " more log lines suppressed");
      }
      log_window_start_ = now;
      log_window_lines_ = 0;
      suppressed_logs_ = 0;
    }
    if (log_window_lines_ < kMaxLogLinesPerSecond) {
      ++log_window_lines_;
      Log(line);
    } else {
      ++suppressed_logs_;
    }
  }

  static constexpr int kAcceptsPerPoll = 64;
  static constexpr int kMaxLogLinesPerSecond = 20;
  /// After accept fails for want of descriptors (EMFILE, ENFILE), the listening socket is not
  /// watched for this long: the pending connection stays readable, and poll() would spin.
  static constexpr std::chrono::milliseconds kAcceptBackoff{100};
  /// A new connection is safe from its own peer's newer connections for this long.
  static constexpr std::chrono::milliseconds kEvictionGrace{200};

  std::string host_;
  int port_ = 0;
  int listen_fd_ = -1;
  std::vector<Connection> connections_;
  int last_connection_id_ = 0;
  int robot_id_ = -1;          ///< connection that made the last valid request
  Clock::time_point accept_paused_until_{};
  Clock::time_point log_window_start_{};
  int log_window_lines_ = 0;
  std::size_t suppressed_logs_ = 0;
  Clock::time_point heard_{};  ///< when the robot last sent anything
  std::deque<PickCommand> pending_;   ///< admitted poses not yet sent (NEXT serves them)
  AckKind last_ack_ = AckKind::kPeerLost;
  std::uint32_t request_sequence_ = 0;
  std::mutex stop_mutex_;
  bool stop_requested_ = false;
  LinkStats stats_;
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
