// Modbus TCP transports of the robot link (issue 5; docs/robot_modbus.md), on libmodbus 3.1.6.
//
// modbus-server://HOST:PORT[?unit=N&connection=persistent|per-request]  the vision side is a Modbus TCP server the PLC polls.
//   A background thread drives the TCP server core (robot/tcp_server.h: one poll() over the
//   listening socket and all clients, non-blocking reads, the limits of LinkOptions::server);
//   MBAP frames are cut and answered here (not by libmodbus's modbus_receive/modbus_reply,
//   which block on one socket until its frame is complete, and sleep before answering an
//   unknown function code - one slow or hostile client then stalled every other, issue 15).
//   The register mapping is guarded by one mutex. Writes to the command register become events
//   in a queue, so a fast PLC that writes "acknowledge" and then "trigger" loses neither.
// modbus-client://HOST:PORT[?unit=N&poll_ms=M]  the vision side writes into the controller's
//   registers (same map, roles swapped), polling the controller's command register.
//
// The register map and the word codec: robot/modbus_registers.h.
#include <modbus/modbus.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "robot/link.h"
#include "robot/modbus_frames.h"
#include "robot/modbus_registers.h"
#include "robot/tcp_server.h"

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;

double SteadyNowSeconds() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}
using std::chrono::milliseconds;
namespace mb = modbus;

/// Per-transport settings from the URI query (link.h's LinkOptions are shared by all links).
struct ModbusUriOptions {
  std::optional<int> unit;  ///< server: answer only this unit id (default: any);
                            ///< client: unit id sent (default 1)
  milliseconds poll{20};    ///< client: period of reading the controller's command register
  /// server: the PLC keeps one connection (default). A cycle then belongs to the connection
  /// that triggered it: its loss ends the wait for the acknowledge (kPeerLost) and the next
  /// connection drops the unacknowledged result. false (?connection=per-request): masters that
  /// open a connection per request (mbpoll, some PLC function blocks) - no connection rule.
  bool persistent_connection = true;
};

int ParseQueryInt(const LinkUri& uri, const std::string& key, int lowest, int highest) {
  const std::string& text = uri.query.at(key);
  int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value < lowest ||
      value > highest) {
    throw std::invalid_argument("robot URI '" + uri.text + "': " + key + "='" + text +
                                "' is not a number in " + std::to_string(lowest) + ".." +
                                std::to_string(highest));
  }
  return value;
}

ModbusUriOptions ParseModbusQuery(const LinkUri& uri, bool client) {
  ModbusUriOptions options;
  for (const auto& [key, value] : uri.query) {
    if (key == "unit") {
      options.unit = ParseQueryInt(uri, key, 0, 255);
    } else if (key == "poll_ms" && client) {
      options.poll = milliseconds(ParseQueryInt(uri, key, 1, 10000));
    } else if (key == "connection" && !client) {
      if (value != "persistent" && value != "per-request") {
        throw std::invalid_argument("robot URI '" + uri.text + "': connection='" + value +
                                    "' is not persistent or per-request");
      }
      options.persistent_connection = value == "persistent";
    } else {
      throw std::invalid_argument("robot URI '" + uri.text + "': unknown query key '" + key +
                                  "' (" + (client ? "unit, poll_ms" : "unit, connection") + ")");
    }
  }
  return options;
}

/// "[::1]" -> "::1" (IPv6 literals in a URI are bracketed).
std::string BareHost(const std::string& host) {
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    return host.substr(1, host.size() - 2);
  }
  return host;
}

std::uint16_t Word(const std::uint8_t* bytes) {
  return static_cast<std::uint16_t>((bytes[0] << 8) | bytes[1]);
}

/// A command written to register 0, in the order the server received it.
struct CommandEvent {
  std::uint16_t command = 0;
  std::uint16_t request_sequence = 0;  ///< register 1 right after the write
  int connection = -1;                 ///< id of the client that wrote it
};

// ------------------------------------------------------------------------------------------
// modbus-server
// ------------------------------------------------------------------------------------------

class ModbusServerLink final : public RobotLink, private TcpServerProtocol {
 public:
  ModbusServerLink(const LinkUri& uri, SafetyGate gate, LinkOptions options)
      : RobotLink(std::move(gate), std::move(options)),
        host_(uri.host),
        query_(ParseModbusQuery(uri, false)),
        register_count_(mb::RegisterCount(this->options().max_poses)) {
    server_ = std::make_unique<TcpServer>(
        uri.host, uri.port,
        TcpServerSettings{"modbus-server", "modbus-server: ", kReadAheadBytes,
                          this->options().io_timeout, this->options().server},
        static_cast<TcpServerProtocol&>(*this));
    if (pipe(wake_pipe_) != 0) {
      server_.reset();
      throw std::runtime_error("modbus-server: pipe: " + std::string(std::strerror(errno)));
    }
    mapping_ = modbus_mapping_new(0, 0, register_count_, 0);
    if (mapping_ == nullptr) {
      CloseAll();
      throw std::runtime_error("modbus-server: cannot allocate the register mapping");
    }
    thread_ = std::thread([this] { Serve(); });
  }

  ~ModbusServerLink() override {
    stopping_ = true;
    const char byte = 0;
    if (write(wake_pipe_[1], &byte, 1) < 0) {
      // Nothing to do: the select() timeout (heartbeat period) ends the thread anyway.
    }
    if (thread_.joinable()) thread_.join();
    CloseAll();
  }

  std::string Describe() const override {
    return "modbus-server://" + host_ + ":" + std::to_string(server_->port());
  }

  Trigger WaitForTrigger(milliseconds timeout) override {
    const auto deadline = Clock::now() + timeout;
    std::unique_lock lock(mutex_);
    while (true) {
      FlushLogsLocked();
      while (!events_.empty()) {
        const CommandEvent event = PopEventLocked();
        switch (event.command) {
          case mb::kCommandTrigger:
            if (IsDuplicateLocked(event.request_sequence)) continue;
            return AcceptTriggerLocked(event);
          case mb::kCommandStop:
            return {TriggerKind::kStop, event.request_sequence};
          case mb::kCommandAcknowledge:
            // A late acknowledge (the loop stopped waiting for it) or a PLC's retry of one.
            if (result_pending_) ClearResultLocked();
            continue;
          default:
            MalformedLocked(event);
            continue;
        }
      }
      if (changed_.wait_until(lock, deadline) == std::cv_status::timeout && events_.empty()) {
        return {TriggerKind::kIdle, 0};
      }
    }
  }

  AckKind WaitForAcknowledge(milliseconds timeout) override {
    const auto deadline = Clock::now() + timeout;
    std::unique_lock lock(mutex_);
    while (true) {
      FlushLogsLocked();
      while (!events_.empty()) {
        const CommandEvent& next = events_.front();
        if (next.command == mb::kCommandTrigger && !IsDuplicateLocked(next.request_sequence)) {
          // A PLC that reconnected (its result dropped) and triggered again before this wait
          // began: the result was lost with the peer, not left unacknowledged. The trigger
          // stays queued for the next WaitForTrigger either way.
          if (result_dropped_) return AckKind::kPeerLost;
          // The PLC moved on to a new request without acknowledging this one: the result was
          // not acknowledged.
          Log("modbus-server: new trigger (request " + std::to_string(next.request_sequence) +
              ") before the acknowledge of request " + std::to_string(served_sequence_));
          return AckKind::kTimeout;
        }
        const CommandEvent event = PopEventLocked();
        switch (event.command) {
          case mb::kCommandTrigger:
            continue;  // a retry of the trigger being served (counted as duplicate above)
          case mb::kCommandAcknowledge:
            ClearResultLocked();
            return AckKind::kAcknowledged;
          case mb::kCommandStop:
            ClearResultLocked();
            return AckKind::kStop;
          default:
            MalformedLocked(event);
            continue;
        }
      }
      if (result_dropped_ || (result_pending_ && owner_lost_)) return AckKind::kPeerLost;
      if (changed_.wait_until(lock, deadline) == std::cv_status::timeout && events_.empty()) {
        if (result_dropped_ || (result_pending_ && owner_lost_)) return AckKind::kPeerLost;
        return AckKind::kTimeout;
      }
    }
  }

  void SendCellCommand(CellCommand command) override {
    if (command != CellCommand::kStop) {
      throw std::runtime_error(std::string("modbus-server: cell command '") +
                               CellCommandName(command) + "' is not supported by modbus");
    }
    std::lock_guard lock(mutex_);
    ClearResultLocked();
  }

  LinkStats Stats() const override {
    std::lock_guard lock(mutex_);
    LinkStats stats = stats_;
    stats.peer_connected = !live_connections_.empty();
    stats.peer_heard_steady_s = peer_heard_steady_s_;
    return stats;
  }

 protected:
  void Send(const CycleResult& admitted) override {
    // Encode first: a value that does not fit is refused before any register changes.
    const bool error = admitted.status < 0;
    std::vector<std::array<std::uint16_t, mb::kWordsPerPose>> poses;
    if (!error) {
      for (const PickCommand& pick : admitted.picks) poses.push_back(mb::EncodePose(pick));
    }
    const std::uint16_t status =
        mb::EncodeStatus(error ? admitted.status : mb::kStatusResultReady);
    std::lock_guard lock(mutex_);
    std::uint16_t* registers = mapping_->tab_registers;
    ZeroPosesLocked();
    registers[mb::kResultSequenceRegister] =
        static_cast<std::uint16_t>(admitted.request_sequence & 0xFFFFu);
    registers[mb::kPoseCountRegister] = static_cast<std::uint16_t>(poses.size());
    for (std::size_t i = 0; i < poses.size(); ++i) {
      std::copy(poses[i].begin(), poses[i].end(),
                registers + mb::kFirstPoseRegister +
                    static_cast<std::size_t>(mb::kWordsPerPose) * i);
    }
    registers[mb::kStatusRegister] = status;
    result_pending_ = true;
    result_dropped_ = false;
    ++stats_.cycles_published;
    stats_.poses_sent += static_cast<int>(poses.size());
  }

 private:
  void CloseAll() {
    server_.reset();
    for (int& fd : wake_pipe_) {
      if (fd >= 0) close(fd);
      fd = -1;
    }
    if (mapping_ != nullptr) modbus_mapping_free(mapping_);
    mapping_ = nullptr;
  }

  // The server thread: accepts clients, reads their bytes without blocking, answers whole
  // frames, enforces the limits (TcpServer), counts the heartbeat. One poll() per round.
  void Serve() {
    const milliseconds period = options().heartbeat_period;
    auto next_heartbeat = Clock::now() + period;
    while (!stopping_) {
      const bool woken = server_->Wait(next_heartbeat, wake_pipe_[0]);
      if (Clock::now() >= next_heartbeat) {
        std::lock_guard lock(mutex_);
        // Wraps 65535 -> 0 by unsigned arithmetic.
        ++mapping_->tab_registers[mb::kHeartbeatRegister];
        next_heartbeat += period;
        if (next_heartbeat < Clock::now()) next_heartbeat = Clock::now() + period;
      }
      if (stopping_) break;
      if (woken) {
        char drain[64];
        if (read(wake_pipe_[0], drain, sizeof drain) < 0) {
          // Nothing to do: the pipe only wakes this loop.
        }
      }
      // A few frames per connection per round: a client that floods requests waits its turn
      // behind everyone else instead of owning the loop.
      for (TcpConnection& connection : server_->connections()) ProcessFrames(connection);
      for (TcpConnection& connection : server_->connections()) {
        if (!connection.output.empty()) server_->Flush(connection);
      }
      server_->EndRound();
    }
  }

  // TcpServerProtocol: a request is one MBAP frame (header + the length it announces).
  bool HasWholeRequest(const TcpConnection& connection) const override {
    if (connection.input.size() < mb::kMbapHeaderBytes) return false;
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(connection.input.data());
    return connection.input.size() >= 6u + Word(bytes + 4);
  }
  void OnRequestIncomplete(TcpConnection& connection) override {
    connection.MarkForClose("request incomplete after " +
                            std::to_string(options().io_timeout.count()) + " ms");
  }
  bool LogsLoss(const TcpConnection&, int error) const override {
    return error != 0 && error != ECONNRESET && error != EPIPE;
  }
  void OnAccepted(TcpConnection& connection) override { Accepted(connection.id); }
  void OnClosed(const TcpConnection& connection) override {
    std::lock_guard lock(mutex_);
    live_connections_.erase(connection.id);
    if (connection.id == trigger_owner_) owner_lost_ = true;
    changed_.notify_all();
  }
  // The log callback is called on the caller's thread only (it need not be thread-safe): lines
  // from the server thread wait here, at most kMaxDeferredLogs, until the next
  // WaitForTrigger/WaitForAcknowledge.
  void WriteLog(const std::string& line) override {
    std::lock_guard lock(log_mutex_);
    if (deferred_logs_.size() < kMaxDeferredLogs) {
      deferred_logs_.push_back(line);
    } else {
      ++suppressed_logs_;
    }
  }

  void ProcessFrames(TcpConnection& connection) {
    for (int n = 0; n < kFramesPerRound && !connection.closing(); ++n) {
      // A malformed header (mb::CutMbapFrame): not a Modbus TCP peer, or a stream that lost its
      // frame boundary and cannot regain it - drop the connection rather than wait for 65535 bytes.
      const auto* bytes = reinterpret_cast<const std::uint8_t*>(connection.input.data());
      const mb::MbapCut cut = mb::CutMbapFrame(bytes, connection.input.size());
      if (cut.kind == mb::MbapCut::Kind::kMalformed) {
        connection.MarkForClose(cut.problem);
        return;
      }
      if (cut.kind == mb::MbapCut::Kind::kIncomplete) return;
      // Over its request rate: the frame waits in the buffer (the server wakes when a token is
      // due) and, the buffer being full, nothing more is read from this client.
      if (!server_->TakeToken(connection)) return;
      Answer(connection, bytes, cut.frame_bytes);
      connection.input.erase(0, cut.frame_bytes);
      if (!connection.input.empty()) connection.request_started = Clock::now();
    }
  }

  void Accepted(int id) {
    std::lock_guard lock(mutex_);
    ++stats_.connections;
    if (stats_.connections > 1) ++stats_.reconnects;
    live_connections_.insert(id);
    // A PLC that lost its connection while a result was pending comes back and triggers again;
    // the stale result must not be picked (docs/robot_modbus.md, "Reconnects").
    if (result_pending_ && owner_lost_) {
      const int poses = mapping_->tab_registers[mb::kPoseCountRegister];
      ClearResultLocked();
      result_dropped_ = true;
      ++stats_.dropped_on_reconnect;
      // The request may be triggered again under the same sequence: nothing was acknowledged.
      served_sequence_valid_ = false;
      DeferLogLocked("modbus-server: client reconnected while the result of request " +
          std::to_string(served_sequence_) + " (" + std::to_string(poses) +
          " poses) was pending; dropped it");
    }
    changed_.notify_all();
  }

  /// Answers one whole frame (MBAP header + PDU) into the connection's output
  /// (mb::HandleModbusFrame, robot/modbus_frames.h).
  void Answer(TcpConnection& connection, const std::uint8_t* frame, std::size_t frame_bytes) {
    mb::ModbusAnswer answer;
    {
      std::lock_guard lock(mutex_);
      answer = mb::HandleModbusFrame(frame, frame_bytes, query_.unit, mapping_->tab_registers,
                                     register_count_);
      if (answer.addressed) {
        peer_heard_steady_s_ = SteadyNowSeconds();
        if (answer.wrote_command) QueueCommandLocked(connection.id);
      }
    }
    if (!answer.exception) connection.last_valid = Clock::now();
    if (connection.output.empty()) connection.output_since = Clock::now();
    connection.output += answer.frame;
  }

  /// A write to register 0 became a command: queue it for the cell loop.
  void QueueCommandLocked(int connection) {
    const std::uint16_t command = mapping_->tab_registers[mb::kCommandRegister];
    if (command == mb::kCommandNone) return;
    if (events_.size() >= kMaxQueuedCommands) {
      ++stats_.malformed;
      DeferLogLocked("modbus-server: more than " + std::to_string(kMaxQueuedCommands) +
          " commands unconsumed; dropping the oldest");
      events_.pop_front();
    }
    events_.push_back(
        {command, mapping_->tab_registers[mb::kRequestSequenceRegister], connection});
    changed_.notify_all();
  }
  /// A line from the server thread about clients: rate-limited (TcpServer::LogLimited), then
  /// deferred (WriteLog). Server thread only.
  void DeferLogLocked(const std::string& line) { server_->LogLimited(line); }
  void FlushLogsLocked() {
    std::vector<std::string> lines;
    std::size_t suppressed = 0;
    {
      std::lock_guard lock(log_mutex_);
      lines.swap(deferred_logs_);
      std::swap(suppressed, suppressed_logs_);
    }
    for (const std::string& line : lines) Log(line);
    if (suppressed > 0) {
      Log("modbus-server: " + std::to_string(suppressed) + " more log lines suppressed");
    }
  }

  CommandEvent PopEventLocked() {
    CommandEvent event = events_.front();
    events_.pop_front();
    // Register 0 reads back 0 once every command written has been consumed.
    if (events_.empty()) mapping_->tab_registers[mb::kCommandRegister] = mb::kCommandNone;
    return event;
  }

  bool IsDuplicateLocked(std::uint16_t request_sequence) {
    if (!served_sequence_valid_ || request_sequence != served_sequence_) return false;
    ++stats_.duplicate_triggers;
    Log("modbus-server: trigger repeats request " + std::to_string(request_sequence) +
        " already served; ignored");
    return true;
  }

  Trigger AcceptTriggerLocked(const CommandEvent& event) {
    served_sequence_ = event.request_sequence;
    served_sequence_valid_ = true;
    ++stats_.triggers;
    trigger_owner_ = query_.persistent_connection ? event.connection : -1;
    owner_lost_ = query_.persistent_connection && live_connections_.count(event.connection) == 0;
    ClearResultLocked();
    mapping_->tab_registers[mb::kStatusRegister] = mb::EncodeStatus(mb::kStatusBusy);
    return {TriggerKind::kTrigger, event.request_sequence};
  }

  void MalformedLocked(const CommandEvent& event) {
    ++stats_.malformed;
    Log("modbus-server: unknown command " + std::to_string(event.command) +
        " in register 0 (1 trigger, 2 acknowledge, 99 stop); ignored");
    // A pending result stays readable; otherwise the PLC sees the error until its next trigger.
    if (!result_pending_) {
      mapping_->tab_registers[mb::kStatusRegister] = mb::EncodeStatus(kErrorMalformedRequest);
    }
  }

  void ZeroPosesLocked() {
    std::fill(mapping_->tab_registers + mb::kFirstPoseRegister,
              mapping_->tab_registers + register_count_, std::uint16_t{0});
  }

  /// Status idle, no poses; the result (if any) is gone.
  void ClearResultLocked() {
    ZeroPosesLocked();
    mapping_->tab_registers[mb::kPoseCountRegister] = 0;
    mapping_->tab_registers[mb::kStatusRegister] = mb::EncodeStatus(mb::kStatusIdle);
    result_pending_ = false;
  }

  static constexpr std::size_t kMaxQueuedCommands = 64;
  /// Bytes read ahead per connection: two of the largest frames (260 bytes each).
  static constexpr std::size_t kReadAheadBytes = 2 * MODBUS_TCP_MAX_ADU_LENGTH;
  static constexpr int kFramesPerRound = 4;  ///< per connection, per poll round
  static constexpr std::size_t kMaxDeferredLogs = 200;

  std::string host_;
  ModbusUriOptions query_;
  int register_count_ = 0;
  std::unique_ptr<TcpServer> server_;  // server thread only, once started
  int wake_pipe_[2] = {-1, -1};
  std::atomic<bool> stopping_{false};
  std::thread thread_;

  std::mutex log_mutex_;  // guards the two below; taken after mutex_ where both are held
  std::vector<std::string> deferred_logs_;
  std::size_t suppressed_logs_ = 0;

  mutable std::mutex mutex_;  // guards everything below and the mapping's registers
  std::condition_variable changed_;
  modbus_mapping_t* mapping_ = nullptr;
  std::deque<CommandEvent> events_;
  std::set<int> live_connections_;
  int trigger_owner_ = -1;    ///< connection that sent the trigger being served
  bool owner_lost_ = false;   ///< ... and has disconnected since
  double peer_heard_steady_s_ = 0.0;  ///< the last request answered (steady clock, s)
  bool result_pending_ = false;  ///< a result is in the registers, not yet acknowledged
  bool result_dropped_ = false;  ///< the last result was dropped on a reconnect
  std::uint16_t served_sequence_ = 0;
  bool served_sequence_valid_ = false;
  LinkStats stats_;
};

// ------------------------------------------------------------------------------------------
// modbus-client
// ------------------------------------------------------------------------------------------

class ModbusClientLink final : public RobotLink {
 public:
  ModbusClientLink(const LinkUri& uri, SafetyGate gate, LinkOptions options)
      : RobotLink(std::move(gate), std::move(options)),
        uri_(uri),
        query_(ParseModbusQuery(uri, true)),
        register_count_(mb::RegisterCount(this->options().max_poses)),
        backoff_(this->options().reconnect_backoff_min) {
    const std::string host = BareHost(uri.host);
    const std::string port = std::to_string(uri.port);
    context_ = modbus_new_tcp_pi(host.c_str(), port.c_str());
    if (context_ == nullptr) {
      throw std::runtime_error("modbus-client: cannot create a context for " + uri.text);
    }
    const auto io = this->options().io_timeout.count();
    modbus_set_response_timeout(context_, static_cast<std::uint32_t>(io / 1000),
                                static_cast<std::uint32_t>((io % 1000) * 1000));
    modbus_set_slave(context_, query_.unit.value_or(1));
    // Fail fast when the controller is not there at start (a typo in the URI); later losses
    // are retried with backoff.
    if (modbus_connect(context_) != 0) {
      const std::string reason = modbus_strerror(errno);
      modbus_free(context_);
      throw std::runtime_error("modbus-client: cannot connect to " + uri.host + ":" + port +
                               ": " + reason);
    }
    connected_ = true;
    stats_.connections = 1;
    heartbeat_thread_ = std::thread([this] { Heartbeat(); });
  }

  ~ModbusClientLink() override {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    stop_changed_.notify_all();
    if (heartbeat_thread_.joinable()) heartbeat_thread_.join();
    modbus_close(context_);
    modbus_free(context_);
  }

  std::string Describe() const override {
    return "modbus-client://" + uri_.host + ":" + std::to_string(uri_.port);
  }

  Trigger WaitForTrigger(milliseconds timeout) override {
    const auto deadline = Clock::now() + timeout;
    while (true) {
      {
        std::lock_guard lock(mutex_);
        FlushLogsLocked();
        std::uint16_t words[2];
        if (ReadLocked(mb::kCommandRegister, 2, words)) {
          const std::uint16_t command = words[0];
          const std::uint16_t sequence = words[1];
          if (command == mb::kCommandTrigger) {
            if (IsDuplicateLocked(sequence)) {
              WriteLocked(mb::kCommandRegister, mb::kCommandNone);
            } else if (ClearResultLocked(mb::kStatusBusy) &&
                       WriteLocked(mb::kCommandRegister, mb::kCommandNone)) {
              served_sequence_ = sequence;
              served_sequence_valid_ = true;
              ++stats_.triggers;
              return {TriggerKind::kTrigger, sequence};
            }
          } else if (command == mb::kCommandStop) {
            WriteLocked(mb::kCommandRegister, mb::kCommandNone);
            return {TriggerKind::kStop, sequence};
          } else if (command == mb::kCommandAcknowledge) {
            // A late acknowledge (the loop stopped waiting) or a retried one.
            if (result_pending_) ClearResultLocked(mb::kStatusIdle);
            WriteLocked(mb::kCommandRegister, mb::kCommandNone);
          } else if (command != mb::kCommandNone) {
            MalformedLocked(command);
          }
        }
      }
      if (Clock::now() >= deadline) return {TriggerKind::kIdle, 0};
      SleepUntilNextPoll(deadline);
    }
  }

  AckKind WaitForAcknowledge(milliseconds timeout) override {
    const auto deadline = Clock::now() + timeout;
    while (true) {
      {
        std::lock_guard lock(mutex_);
        FlushLogsLocked();
        if (lost_pending_) {
          lost_pending_ = false;
          return AckKind::kPeerLost;
        }
        std::uint16_t words[2];
        if (ReadLocked(mb::kCommandRegister, 2, words)) {
          const std::uint16_t command = words[0];
          if (command == mb::kCommandAcknowledge) {
            if (ClearResultLocked(mb::kStatusIdle) &&
                WriteLocked(mb::kCommandRegister, mb::kCommandNone)) {
              return AckKind::kAcknowledged;
            }
          } else if (command == mb::kCommandStop) {
            ClearResultLocked(mb::kStatusIdle);
            WriteLocked(mb::kCommandRegister, mb::kCommandNone);
            return AckKind::kStop;
          } else if (command == mb::kCommandTrigger) {
            if (IsDuplicateLocked(words[1])) {
              WriteLocked(mb::kCommandRegister, mb::kCommandNone);
            } else {
              Log("modbus-client: new trigger (request " + std::to_string(words[1]) +
                  ") before the acknowledge of request " + std::to_string(served_sequence_));
              return AckKind::kTimeout;  // the trigger stays for the next WaitForTrigger
            }
          } else if (command != mb::kCommandNone) {
            MalformedLocked(command);
          }
        }
        if (lost_pending_) {
          lost_pending_ = false;
          return AckKind::kPeerLost;
        }
      }
      if (Clock::now() >= deadline) return AckKind::kTimeout;
      SleepUntilNextPoll(deadline);
    }
  }

  void SendCellCommand(CellCommand command) override {
    if (command != CellCommand::kStop) {
      throw std::runtime_error(std::string("modbus-client: cell command '") +
                               CellCommandName(command) + "' is not supported by modbus");
    }
    std::lock_guard lock(mutex_);
    result_pending_ = false;
    std::vector<std::uint16_t> zeros(static_cast<std::size_t>(mb::kWordsPerPose) *
                                     static_cast<std::size_t>(options().max_poses));
    // Best effort: when the controller is unreachable there is nothing to clear there, and
    // the next connection starts without a result anyway.
    if (ClearResultLocked(mb::kStatusIdle)) WritePosesLocked(zeros);
  }

  LinkStats Stats() const override {
    std::lock_guard lock(mutex_);
    LinkStats stats = stats_;
    stats.peer_connected = connected_;
    stats.peer_heard_steady_s = peer_heard_steady_s_;
    return stats;
  }

 protected:
  void Send(const CycleResult& admitted) override {
    const bool error = admitted.status < 0;
    std::vector<std::uint16_t> pose_words;
    if (!error) {
      for (const PickCommand& pick : admitted.picks) {
        const auto words = mb::EncodePose(pick);
        pose_words.insert(pose_words.end(), words.begin(), words.end());
      }
    }
    const std::uint16_t status =
        mb::EncodeStatus(error ? admitted.status : mb::kStatusResultReady);
    const int poses = static_cast<int>(pose_words.size()) / mb::kWordsPerPose;
    std::lock_guard lock(mutex_);
    FlushLogsLocked();
    result_pending_ = true;  // from here a lost connection drops (and counts) this result
    lost_pending_ = false;
    const std::uint16_t header[2] = {
        static_cast<std::uint16_t>(admitted.request_sequence & 0xFFFFu),
        static_cast<std::uint16_t>(poses)};
    // Sequence, count and poses first; status last, so the controller never sees "result
    // ready" over a half-written result.
    const bool written = WriteBlockLocked(mb::kResultSequenceRegister, header, 2) &&
                         WritePosesLocked(pose_words) &&
                         WriteLocked(mb::kStatusRegister, status);
    if (!written) {
      if (result_pending_) DropPendingLocked();  // not connected at all: nothing was written
      Log("modbus-client: result of request " + std::to_string(admitted.request_sequence) +
          " not written (controller unreachable); dropped");
      return;
    }
    ++stats_.cycles_published;
    stats_.poses_sent += poses;
  }

 private:
  void SleepUntilNextPoll(Clock::time_point deadline) {
    std::this_thread::sleep_until(std::min(Clock::now() + query_.poll, deadline));
  }

  void Heartbeat() {
    std::unique_lock lock(mutex_);
    auto next = Clock::now() + options().heartbeat_period;
    while (!stopping_) {
      if (stop_changed_.wait_until(lock, next, [this] { return stopping_; })) break;
      next += options().heartbeat_period;
      if (next < Clock::now()) next = Clock::now() + options().heartbeat_period;
      const auto word = static_cast<std::uint16_t>(heartbeat_ + 1);  // wraps 65535 -> 0
      on_heartbeat_thread_ = true;
      if (WriteLocked(mb::kHeartbeatRegister, word)) heartbeat_ = word;
      on_heartbeat_thread_ = false;
    }
  }

  // The log callback is called on the caller's thread only (it need not be thread-safe): lines
  // from the heartbeat thread wait for the next WaitForTrigger/WaitForAcknowledge/Send.
  void LogLocked(std::string line) {
    if (on_heartbeat_thread_) {
      deferred_logs_.push_back(std::move(line));
    } else {
      Log(line);
    }
  }
  void FlushLogsLocked() {
    for (const std::string& line : deferred_logs_) Log(line);
    deferred_logs_.clear();
  }

  /// Connects when not connected and the backoff allows. False: no connection now.
  bool EnsureConnectedLocked() {
    if (connected_) return true;
    if (Clock::now() < next_attempt_) return false;
    if (modbus_connect(context_) != 0) {
      const std::string reason = modbus_strerror(errno);
      modbus_close(context_);
      next_attempt_ = Clock::now() + backoff_;
      LogLocked("modbus-client: reconnect to " + uri_.host + ":" + std::to_string(uri_.port) +
          " failed (" + reason + "); next try in " + std::to_string(backoff_.count()) + " ms");
      backoff_ = std::min(backoff_ * 2, options().reconnect_backoff_max);
      return false;
    }
    connected_ = true;
    backoff_ = options().reconnect_backoff_min;
    ++stats_.connections;
    ++stats_.reconnects;
    LogLocked("modbus-client: reconnected to " + uri_.host + ":" + std::to_string(uri_.port));
    if (clear_on_reconnect_) {
      // The result pending at the loss was dropped: tell the controller there is none, so it
      // triggers again (status idle, no poses).
      const std::uint16_t zero = 0;
      if (WriteBlockLocked(mb::kPoseCountRegister, &zero, 1) &&
          WriteBlockLocked(mb::kStatusRegister, &zero, 1)) {
        clear_on_reconnect_ = false;
      }
    }
    return connected_;
  }

  void LostLocked(const std::string& what) {
    LogLocked("modbus-client: " + what + " failed: " + modbus_strerror(errno) + "; reconnecting");
    modbus_close(context_);
    connected_ = false;
    next_attempt_ = Clock::now() + backoff_;
    backoff_ = std::min(backoff_ * 2, options().reconnect_backoff_max);
    if (result_pending_) DropPendingLocked();
  }

  void DropPendingLocked() {
    result_pending_ = false;
    lost_pending_ = true;
    clear_on_reconnect_ = true;
    // A reconnected controller triggers again; the same request sequence is served anew,
    // since nothing of this result was acknowledged.
    served_sequence_valid_ = false;
    ++stats_.dropped_on_reconnect;
  }

  bool ReadLocked(int address, int count, std::uint16_t* words) {
    if (!EnsureConnectedLocked()) return false;
    if (modbus_read_registers(context_, address, count, words) == count) {
      peer_heard_steady_s_ = SteadyNowSeconds();
      return true;
    }
    LostLocked("reading registers " + std::to_string(address) + ".." +
               std::to_string(address + count - 1));
    return false;
  }

  bool WriteBlockLocked(int address, const std::uint16_t* words, int count) {
    if (!EnsureConnectedLocked()) return false;
    if (modbus_write_registers(context_, address, count, words) == count) {
      peer_heard_steady_s_ = SteadyNowSeconds();
      return true;
    }
    LostLocked("writing registers " + std::to_string(address) + ".." +
               std::to_string(address + count - 1));
    return false;
  }

  bool WriteLocked(int address, std::uint16_t word) { return WriteBlockLocked(address, &word, 1); }

  bool WritePosesLocked(const std::vector<std::uint16_t>& words) {
    // At most 123 registers per request (Modbus application protocol v1.1b3, 6.12): whole poses.
    constexpr std::size_t kChunk = (MODBUS_MAX_WRITE_REGISTERS / mb::kWordsPerPose) * mb::kWordsPerPose;
    for (std::size_t start = 0; start < words.size(); start += kChunk) {
      const std::size_t count = std::min(kChunk, words.size() - start);
      if (!WriteBlockLocked(mb::kFirstPoseRegister + static_cast<int>(start), words.data() + start,
                            static_cast<int>(count))) {
        return false;
      }
    }
    return true;
  }

  /// Pose count 0, then `status`. False when the controller could not be written.
  bool ClearResultLocked(int status) {
    result_pending_ = false;
    return WriteLocked(mb::kPoseCountRegister, 0) &&
           WriteLocked(mb::kStatusRegister, mb::EncodeStatus(status));
  }

  bool IsDuplicateLocked(std::uint16_t request_sequence) {
    if (!served_sequence_valid_ || request_sequence != served_sequence_) return false;
    ++stats_.duplicate_triggers;
    Log("modbus-client: trigger repeats request " + std::to_string(request_sequence) +
        " already served; ignored");
    return true;
  }

  void MalformedLocked(std::uint16_t command) {
    ++stats_.malformed;
    Log("modbus-client: unknown command " + std::to_string(command) +
        " in register 0 (1 trigger, 2 acknowledge, 99 stop); ignored");
    if (!result_pending_) WriteLocked(mb::kStatusRegister, mb::EncodeStatus(kErrorMalformedRequest));
    WriteLocked(mb::kCommandRegister, mb::kCommandNone);
  }

  LinkUri uri_;
  ModbusUriOptions query_;
  int register_count_ = 0;

  mutable std::mutex mutex_;  // guards the context (libmodbus is not thread-safe) and below
  std::condition_variable stop_changed_;
  modbus_t* context_ = nullptr;
  bool connected_ = false;
  double peer_heard_steady_s_ = 0.0;  ///< the last read or write that succeeded
  bool stopping_ = false;
  milliseconds backoff_;
  Clock::time_point next_attempt_{};
  bool result_pending_ = false;      ///< a result is in the controller, not yet acknowledged
  bool lost_pending_ = false;        ///< the connection was lost with a result pending
  bool clear_on_reconnect_ = false;  ///< tell the controller its result is gone
  std::uint16_t heartbeat_ = 0;
  bool on_heartbeat_thread_ = false;  ///< set while the heartbeat thread holds the lock
  std::vector<std::string> deferred_logs_;
  std::uint16_t served_sequence_ = 0;
  bool served_sequence_valid_ = false;
  LinkStats stats_;
  std::thread heartbeat_thread_;
};

}  // namespace

std::unique_ptr<RobotLink> MakeModbusServerLink(const LinkUri& uri, SafetyGate gate,
                                                LinkOptions options) {
  return std::make_unique<ModbusServerLink>(uri, std::move(gate), std::move(options));
}

std::unique_ptr<RobotLink> MakeModbusClientLink(const LinkUri& uri, SafetyGate gate,
                                                LinkOptions options) {
  return std::make_unique<ModbusClientLink>(uri, std::move(gate), std::move(options));
}

}  // namespace hnnstereo::robot
