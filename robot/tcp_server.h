#pragma once
// The TCP server core of the listening transports (modbus-server, vision-server): a listening
// socket, non-blocking accepts and reads, and the per-connection limits of ServerLimits
// (robot/link.h; docs/robot.md, "Hostile clients"). The protocol - how bytes become requests,
// what a request answers, which connection must never give way - is the owner's, through
// TcpServerProtocol. Not thread-safe: one thread drives a TcpServer and its callbacks run there.

#include <chrono>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "robot/link.h"

namespace hnnstereo::robot {

/// One client connection, with its own buffers and timers: nothing one client sends, or fails
/// to send, holds up another (issue 15).
struct TcpConnection {
  using Clock = std::chrono::steady_clock;
  int fd = -1;
  int id = 0;          ///< 1, 2, ... in the order accepted
  std::string peer;    ///< peer address (per-peer limit, log)
  std::string input;   ///< received bytes not yet taken as requests
  std::string output;  ///< reply bytes the client has not taken yet
  Clock::time_point accepted;
  Clock::time_point request_started;            ///< when the incomplete request in `input` began
  Clock::time_point output_since;               ///< when `output` last became non-empty or shrank
  std::optional<Clock::time_point> last_valid;  ///< the last valid request (protocol's verdict)
  double tokens = 0.0;                          ///< request budget (token bucket, ServerLimits)
  Clock::time_point tokens_at;                  ///< when `tokens` was last refilled
  std::string close_reason;                     ///< non-empty: closed at the next CloseMarked
  bool log_close = true;                        ///< false: an ordinary hang-up, not logged

  /// Marks the connection for closing (the first reason counts).
  void MarkForClose(std::string reason, bool log = true);
  bool closing() const { return !close_reason.empty(); }
};

/// What the core asks of the protocol on top of it. Called on the thread driving the server.
class TcpServerProtocol {
 public:
  virtual ~TcpServerProtocol() = default;
  /// True when `input` starts with a whole request (then it waits only for a token).
  virtual bool HasWholeRequest(const TcpConnection& connection) const = 0;
  /// Takes `count` received bytes. Default: appended, request_started set at the first byte.
  virtual void OnReceived(TcpConnection& connection, const char* bytes, std::size_t count);
  /// A started request not complete within io_timeout (the partial bytes are the protocol's).
  virtual void OnRequestIncomplete(TcpConnection& connection) = 0;
  /// True: the connection never gives way to a new one (vision-server's robot).
  virtual bool IsProtected(const TcpConnection&) const { return false; }
  /// Whether losing this connection (`error` an errno, 0 for a hang-up) is worth a log line.
  virtual bool LogsLoss(const TcpConnection& connection, int error) const = 0;
  /// The connection's name in log lines, e.g. "connection 3 from 127.0.0.2".
  virtual std::string DescribeConnection(const TcpConnection& connection) const;
  virtual void OnAccepted(TcpConnection&) {}
  /// Called just before the socket is closed and the connection forgotten.
  virtual void OnClosed(const TcpConnection&) {}
  /// Where the core's log lines go (already rate-limited: TcpServer::LogLimited).
  virtual void WriteLog(const std::string& line) = 0;
};

struct TcpServerSettings {
  std::string name;                  ///< "modbus-server": error messages, log prefix
  std::string log_prefix;            ///< prepended to the core's log lines
  std::size_t read_ahead_bytes = 0;  ///< per connection: input, and output before reading stops
  std::chrono::milliseconds io_timeout{2000};  ///< LinkOptions::io_timeout
  ServerLimits limits;
};

class TcpServer {
 public:
  using Clock = std::chrono::steady_clock;

  /// Listens on host:port (port 0: any free port; an IPv6 literal may be bracketed). Throws
  /// std::runtime_error when the address does not resolve or cannot be bound.
  TcpServer(const std::string& host, int port, TcpServerSettings settings,
            TcpServerProtocol& protocol);
  ~TcpServer();
  TcpServer(const TcpServer&) = delete;
  TcpServer& operator=(const TcpServer&) = delete;

  int port() const { return port_; }
  std::vector<TcpConnection>& connections() { return connections_; }
  const std::vector<TcpConnection>& connections() const { return connections_; }
  TcpConnection* Find(int id);

  /// One round, first half: waits until `deadline` (sooner when a connection's own deadline
  /// comes, at most 1 s) for sockets, sends pending replies and reads what arrived. True when
  /// `wake_fd` (if not -1) is readable.
  bool Wait(Clock::time_point deadline, int wake_fd = -1);
  /// One round, second half: applies the timeouts, closes the marked connections, accepts.
  void EndRound();

  /// Queues a reply and sends what the socket takes now; never blocks.
  void Queue(TcpConnection& connection, const std::string& bytes);
  /// Sends what the socket takes of the pending replies; never blocks.
  void Flush(TcpConnection& connection);
  /// One request token (token bucket: max_requests_per_second, up to request_burst saved).
  /// False: the request waits in `input`, and the client is not read from meanwhile.
  bool TakeToken(TcpConnection& connection);
  void CloseMarked();
  /// Lines about clients: at most kMaxLogLinesPerSecond a second, the rest counted in one
  /// "N more log lines suppressed" line, so a flood of connections cannot flood the log.
  void LogLimited(const std::string& line);

  /// New connections taken per round: a connection storm cannot starve the connected clients
  /// of reads, and a backlog of a few hundred drains within a few rounds.
  static constexpr int kAcceptsPerRound = 64;
  /// A connection at a limit gives way to a new one only after this long without a valid
  /// request (ServerLimits::max_connections).
  static constexpr std::chrono::milliseconds kEvictAfterQuiet{1000};
  /// A new connection is safe from its own peer's newer connections for this long, so a burst
  /// accepted in one round cannot push out one whose first request is on its way.
  static constexpr std::chrono::milliseconds kEvictionGrace{200};
  /// After accept fails for want of descriptors (EMFILE, ENFILE), the listening socket is not
  /// watched for this long: the pending connection stays readable, and poll() would spin.
  static constexpr std::chrono::milliseconds kAcceptBackoff{100};
  static constexpr int kMaxLogLinesPerSecond = 20;

 private:
  void Listen(const std::string& host, int port);
  Clock::time_point NextDeadline(const TcpConnection& connection) const;
  Clock::time_point TokenAvailable(const TcpConnection& connection) const;
  void Receive(TcpConnection& connection);
  void ExpireTimeouts(Clock::time_point now);
  bool MakeRoom(const std::string& peer);
  void AcceptPending();

  TcpServerSettings settings_;
  TcpServerProtocol& protocol_;
  int listen_fd_ = -1;
  int port_ = 0;
  std::vector<TcpConnection> connections_;
  int last_connection_id_ = 0;
  bool listen_ready_ = false;  ///< the last Wait saw a connection waiting to be accepted
  Clock::time_point accept_paused_until_{};
  Clock::time_point log_window_start_{};
  int log_window_lines_ = 0;
  std::size_t suppressed_logs_ = 0;
};

}  // namespace hnnstereo::robot
