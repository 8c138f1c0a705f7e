// vision-server://HOST:PORT - the ASCII vision server a URScript program (or any robot that can
// open a TCP socket and read parenthesised floats) talks to. The vision side listens; the robot
// connects, sends `TRIG\n` and reads one line `(st,x,y,z,rx,ry,rz)\n` - the form URScript's
// socket_read_ascii_float(7) parses. Protocol, units and codes: docs/robot_ascii.md.
//
// Plain POSIX sockets and poll(): one listening socket and at most one robot, a few bytes per
// cycle. No Debian library does such a small line server better, and this keeps every wait
// bounded by a timeout we choose. Single-threaded: all socket work happens inside the calls
// the cell loop makes (WaitForTrigger, Send, WaitForAcknowledge), so there is nothing to lock
// but the stop request, which SendCellCommand may make from another thread.
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
#include <mutex>
#include <optional>
#include <stdexcept>

#include "robot/link.h"

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxLineBytes = 256;

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

/// One reply line: `(st,x,y,z,rx,ry,rz)\n`, metres and radians (UR pose).
std::string ReplyLine(int status, const PickCommand* pick) {
  double v[6] = {0, 0, 0, 0, 0, 0};
  if (pick != nullptr) {
    const Eigen::AngleAxisd rotation(pick->orientation.normalized());
    const Eigen::Vector3d rotation_vector = rotation.axis() * rotation.angle();
    for (int i = 0; i < 3; ++i) {
      v[i] = pick->position_mm[i] / 1000.0;
      v[3 + i] = rotation_vector[i];
    }
  }
  for (double& value : v) {
    if (std::abs(value) < 5e-7) value = 0.0;  // never print "-0.000000"
  }
  char text[160];
  std::snprintf(text, sizeof text, "(%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f)\n", status, v[0], v[1],
                v[2], v[3], v[4], v[5]);
  return text;
}

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
      if (bind(fd, a->ai_addr, a->ai_addrlen) == 0 && listen(fd, 4) == 0) {
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
    CloseClient();
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
      while (auto line = NextLine()) {
        if (*line == "TRIG") {
          ++stats_.triggers;
          return {TriggerKind::kTrigger, ++request_sequence_};
        }
        if (*line == "STOP") {
          ClearPending();
          return {TriggerKind::kStop, request_sequence_};
        }
        if (*line == "NEXT") {
          ReplyNext();
        } else {
          Malformed("unknown request '" + Printable(*line) + "'");
        }
      }
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
    stats.peer_connected = client_fd_ >= 0;
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
    // Drain what the robot sent meanwhile (keeping its requests) so a peer that has gone away
    // is seen now rather than after a write into a dead socket.
    ReadAvailable();
    if (client_fd_ < 0) return;  // nobody to answer: kPeerLost
    if (admitted.status < 0) {
      if (WriteLine(ReplyLine(admitted.status, nullptr))) last_ack_ = AckKind::kAcknowledged;
      return;
    }
    pending_.assign(admitted.picks.begin(), admitted.picks.end());
    if (pending_.empty()) {
      if (WriteLine(ReplyLine(0, nullptr))) last_ack_ = AckKind::kAcknowledged;
      return;
    }
    if (WriteLine(ReplyLine(1, &pending_.front()))) {
      ++stats_.poses_sent;
      pending_.pop_front();
      last_ack_ = AckKind::kAcknowledged;
    }
  }

 private:
  static std::string Printable(const std::string& text) {
    std::string shown;
    for (char c : text.substr(0, 40)) shown += (c >= 32 && c < 127) ? c : '?';
    return text.size() > 40 ? shown + "..." : shown;
  }

  bool TakeStop() {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    if (!stop_requested_) return false;
    stop_requested_ = false;
    ClearPending();
    return true;
  }

  void ClearPending() { pending_.clear(); }

  void CloseClient() {
    if (client_fd_ >= 0) close(client_fd_);
    client_fd_ = -1;
    input_.clear();
  }

  // Waits until the deadline for a connection or bytes from the robot, and takes them.
  void PollOnce(Clock::time_point deadline) {
    pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {client_fd_, POLLIN, 0}};
    const nfds_t count = client_fd_ >= 0 ? 2 : 1;
    int wait_ms = RemainingMs(deadline);
    // A partial request must complete within io_timeout; wake up to enforce that.
    if (client_fd_ >= 0 && !input_.empty()) {
      wait_ms = std::min(wait_ms, RemainingMs(partial_since_ + options().io_timeout) + 1);
    }
    const int ready = poll(fds, count, wait_ms);
    if (ready < 0) {
      if (errno != EINTR) Log(Errno("poll"));
      return;
    }
    if (fds[0].revents & POLLIN) Accept();
    else if (count == 2 && fds[1].revents != 0) ReadAvailable();
    if (client_fd_ >= 0 && !input_.empty() &&
        Clock::now() - partial_since_ > options().io_timeout) {
      input_.clear();
      Malformed("request incomplete after " + std::to_string(options().io_timeout.count()) +
                " ms (no newline)");
    }
  }

  void Accept() {
    const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) return;
    const int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ++stats_.connections;
    if (stats_.connections > 1) ++stats_.reconnects;
    if (client_fd_ >= 0) Log("a new robot connection replaces the previous one");
    if (!pending_.empty()) {
      stats_.dropped_on_reconnect += static_cast<int>(pending_.size());
      Log("new connection: " + std::to_string(pending_.size()) + " pending pose(s) dropped");
      ClearPending();
    }
    CloseClient();
    client_fd_ = fd;
  }

  // Reads whatever the robot has sent without blocking; closes on EOF, error or an overlong line.
  void ReadAvailable() {
    while (client_fd_ >= 0) {
      char buffer[512];
      const ssize_t n = recv(client_fd_, buffer, sizeof buffer, MSG_DONTWAIT);
      if (n > 0) {
        heard_ = Clock::now();
        if (input_.empty()) partial_since_ = Clock::now();
        input_.append(buffer, static_cast<std::size_t>(n));
        // Only the unterminated tail counts against the line limit.
        const auto newline = input_.rfind('\n');
        const std::size_t tail = newline == std::string::npos ? input_.size()
                                                              : input_.size() - newline - 1;
        if (tail > kMaxLineBytes) {
          Malformed("request longer than " + std::to_string(kMaxLineBytes) +
                    " bytes without a newline; connection closed");
          CloseClient();
          return;
        }
        continue;
      }
      if (n == 0) {
        Log("robot disconnected");
        CloseClient();
        return;
      }
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) {
        Log(Errno("robot connection lost"));
        CloseClient();
      }
      return;
    }
  }

  // One complete request, trimmed of spaces and the CR a `socket_send_line` may add.
  std::optional<std::string> NextLine() {
    const auto newline = input_.find('\n');
    if (newline == std::string::npos) return std::nullopt;
    std::string line = input_.substr(0, newline);
    input_.erase(0, newline + 1);
    partial_since_ = Clock::now();
    const auto first = line.find_first_not_of(" \t\r");
    const auto last = line.find_last_not_of(" \t\r");
    return first == std::string::npos ? std::string() : line.substr(first, last - first + 1);
  }

  void ReplyNext() {
    if (pending_.empty()) {
      WriteLine(ReplyLine(0, nullptr));
      return;
    }
    if (WriteLine(ReplyLine(1, &pending_.front()))) {
      ++stats_.poses_sent;
      pending_.pop_front();
    }
  }

  void Malformed(const std::string& why) {
    ++stats_.malformed;
    Log("malformed request: " + why);
    if (client_fd_ >= 0) WriteLine(ReplyLine(kErrorMalformedRequest, nullptr));
  }

  // Writes one reply within io_timeout. False (and the connection closed) when it cannot.
  bool WriteLine(const std::string& line) {
    const auto deadline = Clock::now() + options().io_timeout;
    std::size_t written = 0;
    while (client_fd_ >= 0 && written < line.size()) {
      // MSG_NOSIGNAL: a robot that vanished must not raise SIGPIPE and kill the server.
      const ssize_t n = send(client_fd_, line.data() + written, line.size() - written,
                             MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) {
        written += static_cast<std::size_t>(n);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        pollfd fd{client_fd_, POLLOUT, 0};
        const int wait_ms = RemainingMs(deadline);
        if (wait_ms > 0 && poll(&fd, 1, wait_ms) >= 0) continue;
        Log("reply not taken by the robot within " + std::to_string(options().io_timeout.count()) +
            " ms; connection closed");
      } else {
        Log(Errno("reply write failed"));
      }
      CloseClient();
      return false;
    }
    return client_fd_ >= 0;
  }

  std::string host_;
  int port_ = 0;
  int listen_fd_ = -1;
  int client_fd_ = -1;
  std::string input_;                 ///< bytes received, not yet a complete request
  Clock::time_point partial_since_{};
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
