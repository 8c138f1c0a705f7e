// The TCP server core of the listening transports (robot/tcp_server.h).
#include "robot/tcp_server.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <stdexcept>
#include <thread>

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// "[::1]" -> "::1" (IPv6 literals in a URI are bracketed).
std::string BareHost(const std::string& host) {
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    return host.substr(1, host.size() - 2);
  }
  return host;
}

std::string PeerAddress(const sockaddr_storage& address) {
  char text[INET6_ADDRSTRLEN] = "?";
  if (address.ss_family == AF_INET) {
    inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in&>(address).sin_addr, text, sizeof text);
  } else if (address.ss_family == AF_INET6) {
    inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6&>(address).sin6_addr, text,
              sizeof text);
  }
  return text;
}

/// Milliseconds for poll() to reach `wake`: 0 when due, rounded up otherwise, at most 1 s.
int PollTimeoutMs(Clock::time_point wake) {
  const auto now = Clock::now();
  if (wake <= now) return 0;
  const auto left = std::chrono::duration_cast<milliseconds>(wake - now).count();
  return static_cast<int>(std::min<long long>(left + 1, 1000));
}

}  // namespace

void TcpConnection::MarkForClose(std::string reason, bool log) {
  if (closing()) return;
  close_reason = std::move(reason);
  log_close = log;
}

void TcpServerProtocol::OnReceived(TcpConnection& connection, const char* bytes,
                                   std::size_t count) {
  if (connection.input.empty()) connection.request_started = Clock::now();
  connection.input.append(bytes, count);
}

std::string TcpServerProtocol::DescribeConnection(const TcpConnection& connection) const {
  return "connection " + std::to_string(connection.id) + " from " + connection.peer;
}

TcpServer::TcpServer(const std::string& host, int port, TcpServerSettings settings,
                     TcpServerProtocol& protocol)
    : settings_(std::move(settings)), protocol_(protocol) {
  Listen(host, port);
}

TcpServer::~TcpServer() {
  for (const TcpConnection& connection : connections_) close(connection.fd);
  if (listen_fd_ >= 0) close(listen_fd_);
}

void TcpServer::Listen(const std::string& host_text, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string port_text = std::to_string(port);
  const std::string host = BareHost(host_text);
  if (const int rc = getaddrinfo(host.c_str(), port_text.c_str(), &hints, &found); rc != 0) {
    throw std::runtime_error(settings_.name + ": cannot resolve '" + host +
                             "': " + gai_strerror(rc));
  }
  std::string last_error = "no address";
  for (addrinfo* address = found; address != nullptr && listen_fd_ < 0;
       address = address->ai_next) {
    const int fd = socket(address->ai_family, address->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK,
                          address->ai_protocol);
    if (fd < 0) {
      last_error = std::strerror(errno);
      continue;
    }
    const int yes = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    // A deep backlog: when clients connect and hang up by the thousand, a full accept queue
    // drops the PLC's or robot's SYN and its connect waits for the retransmission (1 s, 3 s).
    if (bind(fd, address->ai_addr, address->ai_addrlen) == 0 && listen(fd, SOMAXCONN) == 0) {
      listen_fd_ = fd;
    } else {
      last_error = std::strerror(errno);
      close(fd);
    }
  }
  freeaddrinfo(found);
  if (listen_fd_ < 0) {
    throw std::runtime_error(settings_.name + ": cannot listen on " + host_text + ":" + port_text +
                             ": " + last_error);
  }
  sockaddr_storage bound{};
  socklen_t length = sizeof bound;
  getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &length);
  port_ = bound.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port)
                                      : ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
}

TcpConnection* TcpServer::Find(int id) {
  for (TcpConnection& connection : connections_) {
    if (connection.id == id) return &connection;
  }
  return nullptr;
}

bool TcpServer::Wait(Clock::time_point deadline, int wake_fd) {
  std::vector<pollfd> fds;
  const bool accepting = Clock::now() >= accept_paused_until_;
  fds.push_back({listen_fd_, static_cast<short>(accepting ? POLLIN : 0), 0});
  fds.push_back({wake_fd, POLLIN, 0});  // poll() ignores a negative descriptor
  auto wake = accepting ? deadline : std::min(deadline, accept_paused_until_);
  for (const TcpConnection& connection : connections_) {
    short events = 0;
    // Back-pressure: a client with requests buffered or replies piling up is not read from
    // until they are gone; TCP flow control then slows it down, nobody else.
    if (connection.input.size() < settings_.read_ahead_bytes &&
        connection.output.size() < settings_.read_ahead_bytes) {
      events |= POLLIN;
    }
    if (!connection.output.empty()) events |= POLLOUT;
    fds.push_back({connection.fd, events, 0});
    wake = std::min(wake, NextDeadline(connection));
  }
  listen_ready_ = false;
  const int ready = poll(fds.data(), fds.size(), PollTimeoutMs(wake));
  if (ready < 0) {
    if (errno != EINTR) {
      LogLimited(settings_.log_prefix + "poll failed: " + std::strerror(errno));
      std::this_thread::sleep_for(milliseconds(10));  // a persistent failure must not spin
    }
    return false;
  }
  if (ready == 0) return false;
  for (std::size_t i = 0; i < connections_.size(); ++i) {
    const short revents = fds[i + 2].revents;
    if (revents & POLLOUT) Flush(connections_[i]);
    if (revents & (POLLIN | POLLHUP | POLLERR)) Receive(connections_[i]);
  }
  listen_ready_ = (fds[0].revents & POLLIN) != 0;
  return (fds[1].revents & POLLIN) != 0;
}

void TcpServer::EndRound() {
  ExpireTimeouts(Clock::now());
  CloseMarked();
  // After the reads, so a peer's old connection closing and its new one arriving in the same
  // round are seen in that order (Modbus's reconnect rule needs the old one gone).
  if (listen_ready_) AcceptPending();
  listen_ready_ = false;
  if (suppressed_logs_ > 0 && Clock::now() - log_window_start_ >= std::chrono::seconds(1)) {
    LogLimited({});
  }
}

/// When the server must look at this connection again even if it sends nothing.
TcpServer::Clock::time_point TcpServer::NextDeadline(const TcpConnection& connection) const {
  auto deadline = Clock::time_point::max();
  if (protocol_.HasWholeRequest(connection)) {
    deadline = TokenAvailable(connection);
  } else if (!connection.input.empty()) {
    deadline = connection.request_started + settings_.io_timeout;
  }
  if (!connection.last_valid) {
    deadline = std::min(deadline, connection.accepted + settings_.limits.first_request_timeout);
  }
  if (!connection.output.empty()) {
    deadline = std::min(deadline, connection.output_since + settings_.io_timeout);
  }
  return deadline;
}

void TcpServer::Receive(TcpConnection& connection) {
  while (!connection.closing() && connection.input.size() < settings_.read_ahead_bytes) {
    char buffer[4096];
    const std::size_t room =
        std::min(sizeof buffer, settings_.read_ahead_bytes - connection.input.size());
    const ssize_t n = recv(connection.fd, buffer, room, MSG_DONTWAIT);
    if (n > 0) {
      protocol_.OnReceived(connection, buffer, static_cast<std::size_t>(n));
      continue;
    }
    if (n == 0) {
      connection.MarkForClose("closed by the client", protocol_.LogsLoss(connection, 0));
      return;
    }
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      const int error = errno;
      connection.MarkForClose(std::string("connection lost: ") + std::strerror(error),
                              protocol_.LogsLoss(connection, error));
    }
    return;
  }
}

void TcpServer::Queue(TcpConnection& connection, const std::string& bytes) {
  if (connection.output.empty()) connection.output_since = Clock::now();
  connection.output += bytes;
  Flush(connection);
}

void TcpServer::Flush(TcpConnection& connection) {
  while (!connection.output.empty() && !connection.closing()) {
    // MSG_NOSIGNAL: a client that vanished must not raise SIGPIPE and kill the server.
    const ssize_t n = send(connection.fd, connection.output.data(), connection.output.size(),
                           MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      connection.output.erase(0, static_cast<std::size_t>(n));
      connection.output_since = Clock::now();  // progress: the client reads
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
    const int error = n < 0 ? errno : EPIPE;
    connection.MarkForClose(std::string("reply write failed: ") + std::strerror(error),
                            protocol_.LogsLoss(connection, error));
    return;
  }
}

bool TcpServer::TakeToken(TcpConnection& connection) {
  const ServerLimits& limits = settings_.limits;
  const auto now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - connection.tokens_at).count();
  connection.tokens_at = now;
  connection.tokens = std::min<double>(
      limits.request_burst, connection.tokens + elapsed * limits.max_requests_per_second);
  if (connection.tokens < 1.0) return false;
  connection.tokens -= 1.0;
  return true;
}

/// When the connection will have a request token again.
TcpServer::Clock::time_point TcpServer::TokenAvailable(const TcpConnection& connection) const {
  if (connection.tokens >= 1.0) return Clock::now();
  const double wait_s = (1.0 - connection.tokens) / settings_.limits.max_requests_per_second;
  return connection.tokens_at +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_s));
}

void TcpServer::ExpireTimeouts(Clock::time_point now) {
  const std::string io_ms = std::to_string(settings_.io_timeout.count());
  for (TcpConnection& connection : connections_) {
    if (connection.closing()) continue;
    if (!connection.output.empty() && now - connection.output_since > settings_.io_timeout) {
      connection.MarkForClose("replies not read for " + io_ms + " ms");
    } else if (!connection.last_valid &&
               now - connection.accepted > settings_.limits.first_request_timeout) {
      connection.MarkForClose("no valid request within " +
                              std::to_string(settings_.limits.first_request_timeout.count()) +
                              " ms of connecting");
    } else if (!connection.input.empty() && !protocol_.HasWholeRequest(connection) &&
               now - connection.request_started > settings_.io_timeout) {
      // A whole request waiting for its token (request rate) is not an incomplete one.
      protocol_.OnRequestIncomplete(connection);
    }
  }
}

void TcpServer::CloseMarked() {
  for (std::size_t i = 0; i < connections_.size();) {
    if (!connections_[i].closing()) {
      ++i;
      continue;
    }
    const TcpConnection connection = std::move(connections_[i]);
    connections_.erase(connections_.begin() + static_cast<std::ptrdiff_t>(i));
    close(connection.fd);
    if (connection.log_close) {
      LogLimited(settings_.log_prefix + protocol_.DescribeConnection(connection) +
                 " closed: " + connection.close_reason);
    }
    protocol_.OnClosed(connection);
  }
}

void TcpServer::LogLimited(const std::string& line) {
  const auto now = Clock::now();
  if (now - log_window_start_ >= std::chrono::seconds(1)) {
    if (suppressed_logs_ > 0) {
      protocol_.WriteLog(settings_.log_prefix + std::to_string(suppressed_logs_) +
                         " more log lines suppressed");
    }
    log_window_start_ = now;
    log_window_lines_ = 0;
    suppressed_logs_ = 0;
  }
  if (line.empty()) return;
  if (log_window_lines_ < kMaxLogLinesPerSecond) {
    ++log_window_lines_;
    protocol_.WriteLog(line);
  } else {
    ++suppressed_logs_;
  }
}

/// Frees a slot for a new connection from `peer` when a limit is reached. False: no room, the
/// new connection is refused. The rules (ServerLimits, docs/robot.md): at the per-peer limit the
/// peer's own quietest evictable connection gives way; at the overall limit, the quietest
/// evictable connection of a peer holding at least two more connections than `peer` (so floods
/// from a few addresses cannot lock out another host), else the peer's own. Quietest first:
/// never valid (oldest accepted first), then the oldest last valid request. A protected
/// connection (vision-server's robot), or one with a valid request within kEvictAfterQuiet
/// (an active PLC), never gives way.
bool TcpServer::MakeRoom(const std::string& peer) {
  const auto now = Clock::now();
  std::map<std::string, int> per_peer;
  for (const TcpConnection& c : connections_) ++per_peer[c.peer];
  const int own = per_peer[peer];
  auto quiet_since = [](const TcpConnection& c) {
    return c.last_valid ? *c.last_valid : c.accepted - std::chrono::hours(24 * 365);
  };
  auto evictable = [&](const TcpConnection& c, bool same_peer) {
    if (c.closing() || protocol_.IsProtected(c)) return false;
    if (c.last_valid) return now - *c.last_valid >= kEvictAfterQuiet;
    return !same_peer || now - c.accepted >= kEvictionGrace;
  };
  auto evict_quietest = [&](auto&& eligible, const std::string& why) {
    TcpConnection* victim = nullptr;
    for (TcpConnection& c : connections_) {
      if (eligible(c) && (victim == nullptr || quiet_since(c) < quiet_since(*victim))) {
        victim = &c;
      }
    }
    if (victim == nullptr) return false;
    victim->MarkForClose("closed to make room for a new connection (" + why + ")");
    CloseMarked();
    return true;
  };
  auto own_quietest = [&](const TcpConnection& c) { return c.peer == peer && evictable(c, true); };
  const ServerLimits& limits = settings_.limits;
  if (own >= limits.max_connections_per_peer) {
    return evict_quietest(
        own_quietest,
        "per-peer limit " + std::to_string(limits.max_connections_per_peer) + " from " + peer);
  }
  if (static_cast<int>(connections_.size()) >= limits.max_connections) {
    const std::string why = "limit " + std::to_string(limits.max_connections);
    auto heavier = [&](const TcpConnection& c) {
      return per_peer[c.peer] >= own + 2 && evictable(c, false);
    };
    return evict_quietest(heavier, why) || evict_quietest(own_quietest, why);
  }
  return true;
}

void TcpServer::AcceptPending() {
  for (int n = 0; n < kAcceptsPerRound; ++n) {
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    const int fd = accept4(listen_fd_, reinterpret_cast<sockaddr*>(&address), &length,
                           SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) {
      if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
        accept_paused_until_ = Clock::now() + kAcceptBackoff;
        LogLimited(settings_.log_prefix + "cannot accept a connection: " + std::strerror(errno));
      }
      return;  // none left (the listening socket is non-blocking), or no descriptors
    }
    TcpConnection connection;
    connection.fd = fd;
    connection.peer = PeerAddress(address);
    if (!MakeRoom(connection.peer)) {
      close(fd);
      LogLimited(settings_.log_prefix + "connection from " + connection.peer +
                 " refused: every slot is held by an active client");
      continue;
    }
    const int yes = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
    connection.id = ++last_connection_id_;
    connection.accepted = Clock::now();
    connection.tokens = settings_.limits.request_burst;
    connection.tokens_at = connection.accepted;
    connections_.push_back(std::move(connection));
    protocol_.OnAccepted(connections_.back());
  }
}

}  // namespace hnnstereo::robot
