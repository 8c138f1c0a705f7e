#pragma once
// The robot link: one interface over every transport (dry run, Modbus TCP server and client,
// ASCII vision server, thesis serial). The safety gate is part of the base class, so no
// transport can send a command that did not pass it (ARCHITECTURE.md, robot/; docs/robot.md).
//
// A cycle, as the cell loop drives it (robot/cell_loop.h):
//   WaitForTrigger -> (sense) -> Publish -> WaitForAcknowledge
// Self-triggered transports (dryrun, serial) report a trigger at once and an acknowledge as
// soon as the data is written; polled ones (Modbus, vision server) wait for their peer.

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "robot/pick_command.h"
#include "robot/safety_gate.h"

namespace hnnstereo::robot {

/// Parsed robot URI: `scheme:path` or `scheme://host:port?key=value&...`.
/// dryrun:FILE.jsonl, modbus-server://HOST:PORT, modbus-client://HOST:PORT,
/// vision-server://HOST:PORT, serial:DEVICE?baud=2400.
struct LinkUri {
  std::string scheme;                         ///< "dryrun", "modbus-server", ...
  std::string path;                           ///< dryrun file or serial device
  std::string host;                           ///< for //HOST:PORT forms
  int port = 0;                               ///< servers: 0 = any free port
  std::map<std::string, std::string> query;   ///< after '?', split on '&' and '='
  std::string text;                           ///< the URI as given (for messages)
};

/// Throws std::invalid_argument with a one-line reason (unknown scheme, missing host or port,
/// port out of range, empty path, malformed query).
LinkUri ParseLinkUri(const std::string& uri);

/// Negative status codes published to the cell (Modbus register 11, vision-server `st`).
enum LinkErrorCode : int {
  kErrorSensingFailed = -1,    ///< images unreadable, matching or sensing threw
  kErrorNoFrame = -2,          ///< no frame calibration: nothing can be sent
  kErrorAllRefused = -3,       ///< parts were found but the safety gate refused every pose
  kErrorMalformedRequest = -4, ///< the peer sent something the protocol does not know
};

/// The status code the cell sees for a cycle with status `cycle_status` (CycleResult::status,
/// 0 = a result): 2, result ready (modbus::kStatusResultReady), or its negative LinkErrorCode.
/// The dry-run file, the cycle lines and the web page all show this code (docs/robot.md).
int PublishedStatusCode(int cycle_status);

/// Limits of the listening transports (modbus-server, vision-server): whatever one client
/// sends, or does not send, no other client and no cycle waits for it. Each connection has its
/// own buffers and timers; the server never blocks on one socket (TcpServer, tcp_server.h). The
/// defaults fit one PLC or robot plus a few HMIs and monitors (docs/robot.md, "Hostile clients").
struct ServerLimits {
  /// Client connections open at once. At the limit a new connection takes the place of the
  /// quietest connection of a peer holding more connections than its own (never made a valid
  /// request, or none for a second); if there is none, the new connection is closed at once.
  /// So a flood from a few addresses cannot lock a PLC out, and an active PLC is never pushed
  /// out. A client that does not read its replies is not read from either (TCP flow control
  /// slows it) and is closed when a reply waits longer than io_timeout.
  int max_connections = 32;
  /// The same, counted per peer address: at the limit the peer's own quietest connection
  /// (silent for 200 ms at least) gives way, or the new one is closed.
  int max_connections_per_peer = 8;
  /// A connection must make its first valid request within this, or it is closed: a client
  /// that connects and never speaks (or only speaks garbage) holds a slot for no longer.
  std::chrono::milliseconds first_request_timeout{10000};
  /// Requests per second one connection is served, sustained (token bucket). Requests beyond
  /// wait: the server reads nothing more from that connection until the rate allows, so TCP
  /// flow control slows the sender and no one else (a PLC is slowed, never refused).
  int max_requests_per_second = 2000;
  /// Requests one connection may make at once above the sustained rate.
  int request_burst = 500;
  /// vision-server: longest request line (bytes without the newline); longer closes the
  /// connection after a status -4 reply.
  std::size_t max_line_bytes = 256;
  std::string Check() const;
};

/// Options shared by every transport. Times are wall-clock.
struct LinkOptions {
  std::chrono::milliseconds io_timeout{2000};   ///< one request/response on the wire
  std::chrono::milliseconds heartbeat_period{1000};  ///< Modbus register 10 (+1 each period)
  std::chrono::milliseconds reconnect_backoff_min{100};   ///< first retry after a lost peer
  std::chrono::milliseconds reconnect_backoff_max{5000};  ///< doubling stops here
  int max_poses = 16;                           ///< per cycle (Modbus: registers 20 + 8 * 16)
  /// Listening transports only. A request whose first byte has arrived must be complete
  /// within io_timeout, or the partial request is discarded (see each transport).
  ServerLimits server;
  /// Where the link logs refusals, reconnects and malformed requests (one line each). Called
  /// only on the thread that calls the link (transports with threads queue their lines).
  std::function<void(const std::string&)> log;
  std::string Check() const;
};

enum class TriggerKind { kTrigger, kStop, kIdle };
struct Trigger {
  TriggerKind kind = TriggerKind::kIdle;
  std::uint32_t request_sequence = 0;  ///< the peer's request number (Modbus register 1)
};

enum class AckKind { kAcknowledged, kTimeout, kStop, kPeerLost };

enum class CellCommand { kHome, kOpen, kClose, kStop };
const char* CellCommandName(CellCommand command);

/// One cycle's result. Before Publish: every candidate pick, tallest first. What a transport's
/// Send sees: only the picks the safety gate admitted, in the same order, at most max_poses.
struct CycleResult {
  std::uint32_t request_sequence = 0;  ///< echoed to the peer (Modbus register 12)
  int status = 0;                      ///< 0 = poses (possibly none); < 0 = LinkErrorCode
  std::string error;                   ///< why, when status < 0
  std::vector<PickCommand> picks;
};

/// What became of one candidate pick in Publish.
struct PickOutcome {
  int object_id = 0;
  std::uint32_t sequence = 0;
  bool admitted = false;  ///< passed the safety gate and handed to the transport
  std::string reason;     ///< why not, when refused
};

struct PublishReport {
  int admitted = 0;
  int refused = 0;
  std::vector<std::string> refusals;  ///< one line per refused pick
  std::vector<PickOutcome> outcomes;  ///< one per candidate pick, in the cycle's order
};

struct LinkStats {
  int connections = 0;           ///< peers accepted / connections made
  int reconnects = 0;            ///< connections after the first
  int triggers = 0;              ///< triggers consumed
  int duplicate_triggers = 0;    ///< triggers ignored because their request sequence repeated
  int malformed = 0;             ///< requests the protocol does not know
  int cycles_published = 0;
  int poses_sent = 0;
  int dropped_on_reconnect = 0;  ///< published results cleared because the peer reconnected
  /// Picks the gate admitted but the transport could not carry (e.g. beyond the thesis arm's
  /// reach): logged, never partly sent.
  int transport_refused = 0;
  /// Whether a peer is connected now; empty where the transport cannot tell (dry run, serial).
  std::optional<bool> peer_connected;
  /// Steady-clock seconds when the peer was last heard (a request or a reply); 0 = never/unknown.
  double peer_heard_steady_s = 0.0;
};

class RobotLink {
 public:
  explicit RobotLink(SafetyGate gate, LinkOptions options);
  virtual ~RobotLink() = default;
  RobotLink(const RobotLink&) = delete;
  RobotLink& operator=(const RobotLink&) = delete;

  /// Runs every pick through the safety gate (refused ones are logged and dropped, never sent),
  /// keeps at most max_poses, then hands the result to the transport. A cycle whose picks were
  /// all refused is published with status kErrorAllRefused.
  PublishReport Publish(CycleResult cycle);

  virtual std::string Describe() const = 0;
  /// Blocks up to `timeout` for the peer's next request.
  virtual Trigger WaitForTrigger(std::chrono::milliseconds timeout) = 0;
  /// Blocks up to `timeout` for the peer to acknowledge the last published result.
  virtual AckKind WaitForAcknowledge(std::chrono::milliseconds timeout) = 0;
  /// Home, open, close, stop. Transports without a way to send one say so by throwing
  /// std::runtime_error; kStop always stops what the link is doing.
  virtual void SendCellCommand(CellCommand command) = 0;
  virtual LinkStats Stats() const = 0;

 protected:
  /// Transport-specific: write the admitted result. Throws std::runtime_error on I/O failure.
  virtual void Send(const CycleResult& admitted) = 0;
  void Log(const std::string& line) const;
  const LinkOptions& options() const { return options_; }

 private:
  SafetyGate gate_;
  LinkOptions options_;
};

/// Opens the transport named by `uri`. Throws std::invalid_argument for a bad URI and
/// std::runtime_error when the transport cannot start (port in use, no such device).
std::unique_ptr<RobotLink> OpenLink(const std::string& uri, SafetyGate gate, LinkOptions options);

// One factory per transport (robot/<transport>_link.cc).
std::unique_ptr<RobotLink> MakeDryRunLink(const LinkUri& uri, SafetyGate gate, LinkOptions options);
std::unique_ptr<RobotLink> MakeModbusServerLink(const LinkUri& uri, SafetyGate gate,
                                                LinkOptions options);
std::unique_ptr<RobotLink> MakeModbusClientLink(const LinkUri& uri, SafetyGate gate,
                                                LinkOptions options);
std::unique_ptr<RobotLink> MakeVisionServerLink(const LinkUri& uri, SafetyGate gate,
                                                LinkOptions options);
std::unique_ptr<RobotLink> MakeSerialLink(const LinkUri& uri, SafetyGate gate, LinkOptions options);

}  // namespace hnnstereo::robot
