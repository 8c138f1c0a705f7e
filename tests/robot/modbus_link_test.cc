// The Modbus TCP transports (robot/modbus_link.cc) against libmodbus peers in this process,
// on 127.0.0.1 with ports chosen by the kernel: a PLC (libmodbus client) for modbus-server,
// a controller (libmodbus server) for modbus-client. Every wait is bounded.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "robot/link.h"
#include "robot/modbus_registers.h"

namespace hnnstereo::robot {
namespace {

namespace mb = modbus;
using std::chrono::milliseconds;

LinkOptions QuietOptions() {
  LinkOptions options;
  options.io_timeout = milliseconds(500);
  options.heartbeat_period = milliseconds(1000);
  options.reconnect_backoff_min = milliseconds(10);
  options.reconnect_backoff_max = milliseconds(80);
  options.max_poses = 4;
  options.log = [](const std::string&) {};
  return options;
}

std::unique_ptr<RobotLink> OpenServer(LinkOptions options = QuietOptions(),
                                      const std::string& query = "") {
  return OpenLink("modbus-server://127.0.0.1:0" + query, SafetyGate(SafetyLimits{}, true),
                  std::move(options));
}

int PortOf(const RobotLink& link) {
  const std::string text = link.Describe();
  return std::stoi(text.substr(text.rfind(':') + 1));
}

PickCommand Pick(std::uint32_t sequence, double x, double y, double z, double yaw) {
  PickCommand pick;
  pick.sequence = sequence;
  pick.object_id = static_cast<int>(sequence);
  pick.position_mm = Eigen::Vector3d(x, y, z);
  pick.yaw_deg = yaw;
  return pick;
}

CycleResult Cycle(std::uint32_t request_sequence, std::vector<PickCommand> picks) {
  CycleResult cycle;
  cycle.request_sequence = request_sequence;
  cycle.picks = std::move(picks);
  return cycle;
}

/// True once `condition` holds, polling for at most `timeout`.
bool Eventually(const std::function<bool()>& condition, milliseconds timeout = milliseconds(3000)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(milliseconds(5));
  }
  return condition();
}

/// A PLC: a libmodbus TCP client of the vision server.
class Plc {
 public:
  explicit Plc(int port, int unit = 1) : context_(modbus_new_tcp("127.0.0.1", port)) {
    modbus_set_response_timeout(context_, 2, 0);
    modbus_set_slave(context_, unit);
    connected_ = modbus_connect(context_) == 0;
  }
  ~Plc() {
    modbus_close(context_);
    modbus_free(context_);
  }
  bool connected() const { return connected_; }
  void Write(int address, std::uint16_t value) {
    ASSERT_EQ(modbus_write_register(context_, address, value), 1) << modbus_strerror(errno);
  }
  std::vector<std::uint16_t> Read(int address, int count) {
    std::vector<std::uint16_t> words(static_cast<std::size_t>(count));
    EXPECT_EQ(modbus_read_registers(context_, address, count, words.data()), count)
        << modbus_strerror(errno);
    return words;
  }
  std::uint16_t Read(int address) { return Read(address, 1)[0]; }
  /// The handshake of docs/robot_modbus.md: request sequence first, then the command.
  void Trigger(std::uint16_t request_sequence) {
    Write(mb::kRequestSequenceRegister, request_sequence);
    Write(mb::kCommandRegister, mb::kCommandTrigger);
  }
  modbus_t* context() { return context_; }

 private:
  modbus_t* context_;
  bool connected_ = false;
};

TEST(ModbusServerLink, DescribeNamesTheBoundPort) {
  auto link = OpenServer();
  const std::string text = link->Describe();
  EXPECT_EQ(text.rfind("modbus-server://127.0.0.1:", 0), 0u) << text;
  EXPECT_GT(PortOf(*link), 0);
}

TEST(ModbusServerLink, TriggerPublishReadAcknowledge) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  ASSERT_TRUE(plc.connected());
  plc.Trigger(7);
  const Trigger trigger = link->WaitForTrigger(milliseconds(2000));
  ASSERT_EQ(trigger.kind, TriggerKind::kTrigger);
  EXPECT_EQ(trigger.request_sequence, 7u);
  EXPECT_EQ(plc.Read(mb::kCommandRegister), 0) << "the consumed command is cleared";
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusBusy);

  const PublishReport report =
      link->Publish(Cycle(7, {Pick(1, 120.5, -80.25, 42.0, 33.5), Pick(2, -10, 5, 20, -89.0)}));
  EXPECT_EQ(report.admitted, 2);
  const auto header = plc.Read(mb::kStatusRegister, 3);
  EXPECT_EQ(header[0], mb::kStatusResultReady);
  EXPECT_EQ(header[1], 7);
  EXPECT_EQ(header[2], 2);
  const auto words = plc.Read(mb::kFirstPoseRegister, 2 * mb::kWordsPerPose);
  const mb::PoseWords first = mb::DecodePose(words.data());
  const mb::PoseWords second = mb::DecodePose(words.data() + mb::kWordsPerPose);
  EXPECT_DOUBLE_EQ(first.x_mm, 120.5);
  EXPECT_DOUBLE_EQ(first.y_mm, -80.25);
  EXPECT_DOUBLE_EQ(first.z_mm, 42.0);
  EXPECT_DOUBLE_EQ(first.yaw_deg, 33.5);
  EXPECT_DOUBLE_EQ(second.x_mm, -10.0);
  EXPECT_DOUBLE_EQ(second.yaw_deg, -89.0);

  plc.Write(mb::kCommandRegister, mb::kCommandAcknowledge);
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kAcknowledged);
  const auto after = plc.Read(0, mb::RegisterCount(4));
  EXPECT_EQ(after[mb::kCommandRegister], 0);
  EXPECT_EQ(after[mb::kStatusRegister], mb::kStatusIdle);
  EXPECT_EQ(after[mb::kPoseCountRegister], 0);
  EXPECT_EQ(after[mb::kFirstPoseRegister], 0);

  const LinkStats stats = link->Stats();
  EXPECT_EQ(stats.connections, 1);
  EXPECT_EQ(stats.triggers, 1);
  EXPECT_EQ(stats.cycles_published, 1);
  EXPECT_EQ(stats.poses_sent, 2);
  EXPECT_EQ(stats.malformed, 0);
}

TEST(ModbusServerLink, TimeoutsAreBounded) {
  auto link = OpenServer();
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(link->WaitForTrigger(milliseconds(100)).kind, TriggerKind::kIdle);
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(100)), AckKind::kTimeout);
  EXPECT_LT(std::chrono::steady_clock::now() - start, milliseconds(1500));
}

TEST(ModbusServerLink, StopWhileIdleAndWhileWaitingForTheAcknowledge) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  plc.Write(mb::kCommandRegister, mb::kCommandStop);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kStop);
  EXPECT_EQ(plc.Read(mb::kCommandRegister), 0);

  plc.Trigger(1);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(1, {Pick(1, 0, 0, 10, 0)}));
  plc.Write(mb::kCommandRegister, mb::kCommandStop);
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kStop);
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusIdle);
  EXPECT_EQ(plc.Read(mb::kPoseCountRegister), 0);
}

TEST(ModbusServerLink, DuplicateTriggerIsIgnored) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  plc.Trigger(5);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(5, {Pick(1, 1, 2, 3, 4)}));
  // A retry of the trigger while the result waits: ignored, the result stays readable.
  plc.Trigger(5);
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(200)), AckKind::kTimeout);
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusResultReady);
  EXPECT_EQ(plc.Read(mb::kPoseCountRegister), 1);
  plc.Write(mb::kCommandRegister, mb::kCommandAcknowledge);
  // (Acknowledged late: the next WaitForTrigger takes it.)
  // A retry after the acknowledge: ignored as well, never a second result.
  plc.Trigger(5);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(200)).kind, TriggerKind::kIdle);
  EXPECT_EQ(plc.Read(mb::kCommandRegister), 0);
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusIdle);
  EXPECT_EQ(link->Stats().duplicate_triggers, 2);
  EXPECT_EQ(link->Stats().triggers, 1);
  plc.Trigger(6);
  const Trigger next = link->WaitForTrigger(milliseconds(2000));
  EXPECT_EQ(next.kind, TriggerKind::kTrigger);
  EXPECT_EQ(next.request_sequence, 6u);
}

TEST(ModbusServerLink, MalformedCommandIsCountedAndTheLinkKeepsServing) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  plc.Write(mb::kCommandRegister, 7);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(200)).kind, TriggerKind::kIdle);
  EXPECT_EQ(plc.Read(mb::kCommandRegister), 0);
  EXPECT_EQ(mb::DecodeStatus(plc.Read(mb::kStatusRegister)), kErrorMalformedRequest);
  EXPECT_EQ(link->Stats().malformed, 1);
  plc.Trigger(1);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusBusy);
}

TEST(ModbusServerLink, AccessBeyondTheMapIsAModbusExceptionAndTheServerSurvives) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  const int size = mb::RegisterCount(4);
  std::uint16_t words[4];
  EXPECT_EQ(modbus_read_registers(plc.context(), size - 1, 2, words), -1);
  EXPECT_EQ(errno, EMBXILADD);
  const std::uint16_t values[2] = {1, 1};
  EXPECT_EQ(modbus_write_registers(plc.context(), size, 2, values), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(modbus_read_registers(plc.context(), 0, 4, words), 4);
  plc.Trigger(3);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
}

TEST(ModbusServerLink, ReconnectDropsThePendingResult) {
  auto link = OpenServer();
  const int port = PortOf(*link);
  {
    Plc plc(port);
    plc.Trigger(11);
    ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
    link->Publish(Cycle(11, {Pick(1, 10, 20, 30, 40)}));
    EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusResultReady);
  }  // the PLC goes away before acknowledging
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kPeerLost);
  Plc again(port);
  const auto header = again.Read(mb::kStatusRegister, 3);
  EXPECT_EQ(header[0], mb::kStatusIdle);
  EXPECT_EQ(header[2], 0);
  EXPECT_EQ(again.Read(mb::kFirstPoseRegister), 0);
  LinkStats stats = link->Stats();
  EXPECT_EQ(stats.dropped_on_reconnect, 1);
  EXPECT_EQ(stats.connections, 2);
  EXPECT_EQ(stats.reconnects, 1);
  // Nothing was acknowledged, so the same request is served again.
  again.Trigger(11);
  const Trigger retry = link->WaitForTrigger(milliseconds(2000));
  EXPECT_EQ(retry.kind, TriggerKind::kTrigger);
  EXPECT_EQ(retry.request_sequence, 11u);
}

// The race a loaded CI machine hit: the PLC dies, reconnects and triggers again before the
// cell loop even waits for the acknowledge. The dropped result is a lost peer, not an
// acknowledge timeout, and the new trigger stays queued for the next cycle.
TEST(ModbusServerLink, ReconnectAndTriggerBeforeTheWaitIsAPeerLost) {
  auto link = OpenServer();
  const int port = PortOf(*link);
  {
    Plc plc(port);
    plc.Trigger(21);
    ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
    link->Publish(Cycle(21, {Pick(1, 10, 20, 30, 40)}));
    EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusResultReady);
  }
  ASSERT_TRUE(Eventually([&] { return link->Stats().peer_connected == false; }));
  Plc again(port);
  ASSERT_TRUE(again.connected());
  ASSERT_TRUE(Eventually([&] { return link->Stats().dropped_on_reconnect == 1; }));
  again.Trigger(21);  // answered after the server queued it: queued before the wait below
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kPeerLost);
  const Trigger retry = link->WaitForTrigger(milliseconds(2000));
  EXPECT_EQ(retry.kind, TriggerKind::kTrigger);
  EXPECT_EQ(retry.request_sequence, 21u);
}

TEST(ModbusServerLink, AMonitorConnectingDoesNotDropTheResult) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  plc.Trigger(1);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(1, {Pick(1, 10, 20, 30, 40)}));
  {
    Plc monitor(PortOf(*link));
    EXPECT_EQ(monitor.Read(mb::kPoseCountRegister), 1);
  }
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusResultReady);
  plc.Write(mb::kCommandRegister, mb::kCommandAcknowledge);
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kAcknowledged);
  EXPECT_EQ(link->Stats().dropped_on_reconnect, 0);
}

TEST(ModbusServerLink, PerRequestConnectionsKeepTheCycle) {
  auto link = OpenServer(QuietOptions(), "?connection=per-request");
  const int port = PortOf(*link);
  Plc(port).Trigger(8);  // connect, write, disconnect - as mbpoll does
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(8, {Pick(1, 10, 20, 30, 40)}));
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(100)), AckKind::kTimeout) << "not kPeerLost";
  EXPECT_EQ(Plc(port).Read(mb::kPoseCountRegister), 1) << "not dropped by a new connection";
  Plc(port).Write(mb::kCommandRegister, mb::kCommandAcknowledge);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(100)).kind, TriggerKind::kIdle);
  EXPECT_EQ(Plc(port).Read(mb::kStatusRegister), mb::kStatusIdle) << "late acknowledge taken";
  EXPECT_EQ(link->Stats().dropped_on_reconnect, 0);
  EXPECT_THROW(OpenServer(QuietOptions(), "?connection=sometimes"), std::invalid_argument);
}

TEST(ModbusServerLink, HeartbeatIncreases) {
  LinkOptions options = QuietOptions();
  options.heartbeat_period = milliseconds(20);
  auto link = OpenServer(options);
  Plc plc(PortOf(*link));
  // Waits for five beats (generous deadline: a loaded machine delays the heartbeat thread), and
  // checks they came no faster than the period: at most one a 20 ms, plus the one at the start.
  const auto start = std::chrono::steady_clock::now();
  const int first = plc.Read(mb::kHeartbeatRegister);
  int second = first;
  while (second - first < 5 && std::chrono::steady_clock::now() - start < std::chrono::seconds(30)) {
    std::this_thread::sleep_for(milliseconds(20));
    second = plc.Read(mb::kHeartbeatRegister);
  }
  const auto elapsed = std::chrono::steady_clock::now() - start;
  EXPECT_GE(second - first, 5);
  EXPECT_LE(second - first, elapsed / milliseconds(20) + 1);
}

TEST(ModbusServerLink, PickOutsideTheWorkspaceNeverReachesTheRegisters) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  plc.Trigger(1);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  const PublishReport report =
      link->Publish(Cycle(1, {Pick(1, 1000, 0, 50, 0), Pick(2, 100, 50, 60, 10)}));
  EXPECT_EQ(report.refused, 1);
  EXPECT_EQ(plc.Read(mb::kPoseCountRegister), 1);
  const auto words = plc.Read(mb::kFirstPoseRegister, mb::kWordsPerPose);
  EXPECT_DOUBLE_EQ(mb::DecodePose(words.data()).x_mm, 100.0);
  EXPECT_EQ(plc.Read(mb::kFirstPoseRegister + mb::kWordsPerPose), 0);
  plc.Write(mb::kCommandRegister, mb::kCommandAcknowledge);
  ASSERT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kAcknowledged);

  plc.Trigger(2);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(2, {Pick(3, 0, 0, 900, 0), Pick(4, -1000, 0, 10, 0)}));
  const auto header = plc.Read(mb::kStatusRegister, 3);
  EXPECT_EQ(mb::DecodeStatus(header[0]), kErrorAllRefused);
  EXPECT_EQ(header[1], 2);
  EXPECT_EQ(header[2], 0);
  const auto poses = plc.Read(mb::kFirstPoseRegister, 2 * mb::kWordsPerPose);
  for (const std::uint16_t word : poses) EXPECT_EQ(word, 0);
  EXPECT_EQ(link->Stats().poses_sent, 1);
}

TEST(ModbusServerLink, UnitFilterAndBadQuery) {
  auto link = OpenServer(QuietOptions(), "?unit=3");
  Plc wrong(PortOf(*link), 4);
  std::uint16_t word = 0;
  EXPECT_EQ(modbus_read_registers(wrong.context(), 10, 1, &word), -1);
  EXPECT_EQ(errno, EMBXGTAR);
  Plc right(PortOf(*link), 3);
  EXPECT_EQ(modbus_read_registers(right.context(), 10, 1, &word), 1);
  EXPECT_THROW(OpenServer(QuietOptions(), "?colour=red"), std::invalid_argument);
  EXPECT_THROW(OpenServer(QuietOptions(), "?unit=300"), std::invalid_argument);
}

TEST(ModbusServerLink, PortInUseIsARuntimeError) {
  auto link = OpenServer();
  EXPECT_THROW(OpenLink("modbus-server://127.0.0.1:" + std::to_string(PortOf(*link)),
                        SafetyGate(SafetyLimits{}, true), QuietOptions()),
               std::runtime_error);
}

TEST(ModbusServerLink, CellCommands) {
  auto link = OpenServer();
  Plc plc(PortOf(*link));
  EXPECT_THROW(link->SendCellCommand(CellCommand::kHome), std::runtime_error);
  plc.Trigger(1);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(1, {Pick(1, 10, 20, 30, 40)}));
  link->SendCellCommand(CellCommand::kStop);
  EXPECT_EQ(plc.Read(mb::kStatusRegister), mb::kStatusIdle);
  EXPECT_EQ(plc.Read(mb::kPoseCountRegister), 0);
  EXPECT_EQ(plc.Read(mb::kFirstPoseRegister + 1), 0);
}

/// A controller for modbus-client: a libmodbus TCP server in a thread, many clients.
class Controller {
 public:
  explicit Controller(int size = mb::RegisterCount(4))
      : context_(modbus_new_tcp("127.0.0.1", 0)), mapping_(modbus_mapping_new(0, 0, size, 0)) {
    listen_fd_ = modbus_tcp_listen(context_, 4);
    sockaddr_in bound{};
    socklen_t length = sizeof(bound);
    getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &length);
    port_ = ntohs(bound.sin_port);
    thread_ = std::thread([this] { Serve(); });
  }
  ~Controller() {
    stopping_ = true;
    thread_.join();
    for (const int fd : clients_) close(fd);
    close(listen_fd_);
    modbus_set_socket(context_, -1);
    modbus_free(context_);
    modbus_mapping_free(mapping_);
  }
  int port() const { return port_; }
  std::uint16_t Get(int address) {
    std::lock_guard lock(mutex_);
    return mapping_->tab_registers[address];
  }
  void Set(int address, std::uint16_t value) {
    std::lock_guard lock(mutex_);
    mapping_->tab_registers[address] = value;
  }
  /// Closes every client connection (a controller restart, a cable pulled).
  void DropClients() { drop_ = true; }
  int accepted() const { return accepted_; }

 private:
  void Serve() {
    std::uint8_t request[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stopping_) {
      if (drop_.exchange(false)) {
        for (const int fd : clients_) close(fd);
        clients_.clear();
      }
      fd_set readable;
      FD_ZERO(&readable);
      FD_SET(listen_fd_, &readable);
      int highest = listen_fd_;
      for (const int fd : clients_) {
        FD_SET(fd, &readable);
        highest = std::max(highest, fd);
      }
      timeval timeout{0, 10000};
      if (select(highest + 1, &readable, nullptr, nullptr, &timeout) <= 0) continue;
      for (std::size_t i = 0; i < clients_.size();) {
        if (!FD_ISSET(clients_[i], &readable)) {
          ++i;
          continue;
        }
        modbus_set_socket(context_, clients_[i]);
        const int length = modbus_receive(context_, request);
        if (length > 0) {
          std::lock_guard lock(mutex_);
          modbus_reply(context_, request, length, mapping_);
        }
        if (length < 0) {
          close(clients_[i]);
          clients_.erase(clients_.begin() + static_cast<std::ptrdiff_t>(i));
        } else {
          ++i;
        }
      }
      if (FD_ISSET(listen_fd_, &readable)) {
        const int fd = accept(listen_fd_, nullptr, nullptr);
        if (fd >= 0) {
          clients_.push_back(fd);
          ++accepted_;
        }
      }
    }
  }

  modbus_t* context_;
  modbus_mapping_t* mapping_;
  std::mutex mutex_;
  int listen_fd_ = -1;
  int port_ = 0;
  std::vector<int> clients_;
  std::atomic<bool> stopping_{false};
  std::atomic<bool> drop_{false};
  std::atomic<int> accepted_{0};
  std::thread thread_;
};

std::unique_ptr<RobotLink> OpenClient(const Controller& controller,
                                      LinkOptions options = QuietOptions()) {
  return OpenLink("modbus-client://127.0.0.1:" + std::to_string(controller.port()) +
                      "?poll_ms=5",
                  SafetyGate(SafetyLimits{}, true), std::move(options));
}

TEST(ModbusClientLink, TriggerPublishAcknowledge) {
  Controller controller;
  auto link = OpenClient(controller);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(50)).kind, TriggerKind::kIdle);
  controller.Set(mb::kRequestSequenceRegister, 9);
  controller.Set(mb::kCommandRegister, mb::kCommandTrigger);
  const Trigger trigger = link->WaitForTrigger(milliseconds(2000));
  ASSERT_EQ(trigger.kind, TriggerKind::kTrigger);
  EXPECT_EQ(trigger.request_sequence, 9u);
  EXPECT_EQ(controller.Get(mb::kCommandRegister), 0);
  EXPECT_EQ(controller.Get(mb::kStatusRegister), mb::kStatusBusy);

  link->Publish(Cycle(9, {Pick(1, -120.5, 80.25, 42.0, -33.5), Pick(2, 1000, 0, 0, 0)}));
  EXPECT_EQ(controller.Get(mb::kStatusRegister), mb::kStatusResultReady);
  EXPECT_EQ(controller.Get(mb::kResultSequenceRegister), 9);
  EXPECT_EQ(controller.Get(mb::kPoseCountRegister), 1);
  std::uint16_t words[mb::kWordsPerPose];
  for (int i = 0; i < mb::kWordsPerPose; ++i) words[i] = controller.Get(mb::kFirstPoseRegister + i);
  const mb::PoseWords pose = mb::DecodePose(words);
  EXPECT_DOUBLE_EQ(pose.x_mm, -120.5);
  EXPECT_DOUBLE_EQ(pose.y_mm, 80.25);
  EXPECT_DOUBLE_EQ(pose.z_mm, 42.0);
  EXPECT_DOUBLE_EQ(pose.yaw_deg, -33.5);
  EXPECT_EQ(controller.Get(mb::kFirstPoseRegister + mb::kWordsPerPose), 0) << "refused pick";

  controller.Set(mb::kCommandRegister, mb::kCommandAcknowledge);
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(2000)), AckKind::kAcknowledged);
  EXPECT_EQ(controller.Get(mb::kCommandRegister), 0);
  EXPECT_EQ(controller.Get(mb::kStatusRegister), mb::kStatusIdle);
  EXPECT_EQ(controller.Get(mb::kPoseCountRegister), 0);

  // A retried trigger of the served request: ignored.
  controller.Set(mb::kCommandRegister, mb::kCommandTrigger);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(100)).kind, TriggerKind::kIdle);
  EXPECT_EQ(controller.Get(mb::kCommandRegister), 0);
  const LinkStats stats = link->Stats();
  EXPECT_EQ(stats.connections, 1);
  EXPECT_EQ(stats.triggers, 1);
  EXPECT_EQ(stats.duplicate_triggers, 1);
  EXPECT_EQ(stats.poses_sent, 1);
}

TEST(ModbusClientLink, StopMalformedAndCellCommands) {
  Controller controller;
  auto link = OpenClient(controller);
  controller.Set(mb::kCommandRegister, 42);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(100)).kind, TriggerKind::kIdle);
  EXPECT_EQ(mb::DecodeStatus(controller.Get(mb::kStatusRegister)), kErrorMalformedRequest);
  EXPECT_EQ(controller.Get(mb::kCommandRegister), 0);
  EXPECT_EQ(link->Stats().malformed, 1);
  controller.Set(mb::kCommandRegister, mb::kCommandStop);
  EXPECT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kStop);
  EXPECT_EQ(controller.Get(mb::kCommandRegister), 0);
  EXPECT_THROW(link->SendCellCommand(CellCommand::kOpen), std::runtime_error);
  controller.Set(mb::kRequestSequenceRegister, 1);
  controller.Set(mb::kCommandRegister, mb::kCommandTrigger);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(1, {Pick(1, 10, 20, 30, 40)}));
  link->SendCellCommand(CellCommand::kStop);
  EXPECT_EQ(controller.Get(mb::kStatusRegister), mb::kStatusIdle);
  EXPECT_EQ(controller.Get(mb::kPoseCountRegister), 0);
  EXPECT_EQ(controller.Get(mb::kFirstPoseRegister + 1), 0);
}

TEST(ModbusClientLink, HeartbeatIsWritten) {
  Controller controller;
  LinkOptions options = QuietOptions();
  options.heartbeat_period = milliseconds(20);
  auto link = OpenClient(controller, options);
  EXPECT_TRUE(Eventually([&] { return controller.Get(mb::kHeartbeatRegister) >= 5; }));
}

TEST(ModbusClientLink, LostConnectionDropsThePendingResultAndReconnects) {
  Controller controller;
  auto link = OpenClient(controller);
  controller.Set(mb::kRequestSequenceRegister, 4);
  controller.Set(mb::kCommandRegister, mb::kCommandTrigger);
  ASSERT_EQ(link->WaitForTrigger(milliseconds(2000)).kind, TriggerKind::kTrigger);
  link->Publish(Cycle(4, {Pick(1, 10, 20, 30, 40)}));
  ASSERT_EQ(controller.Get(mb::kStatusRegister), mb::kStatusResultReady);
  controller.DropClients();
  EXPECT_EQ(link->WaitForAcknowledge(milliseconds(3000)), AckKind::kPeerLost);
  // Reconnected (backoff 10..80 ms): the dropped result is cleared, not rewritten.
  EXPECT_TRUE(Eventually([&] {
    link->WaitForTrigger(milliseconds(10));
    return link->Stats().reconnects >= 1 && controller.Get(mb::kStatusRegister) == 0;
  }));
  EXPECT_EQ(controller.Get(mb::kPoseCountRegister), 0);
  const LinkStats stats = link->Stats();
  EXPECT_EQ(stats.dropped_on_reconnect, 1);
  EXPECT_GE(controller.accepted(), 2);
  // The same request is served again (nothing was acknowledged).
  controller.Set(mb::kCommandRegister, mb::kCommandTrigger);
  const Trigger retry = link->WaitForTrigger(milliseconds(2000));
  EXPECT_EQ(retry.kind, TriggerKind::kTrigger);
  EXPECT_EQ(retry.request_sequence, 4u);
}

TEST(ModbusClientLink, NoControllerIsARuntimeError) {
  int port = 0;
  {
    Controller gone;
    port = gone.port();
  }
  EXPECT_THROW(OpenLink("modbus-client://127.0.0.1:" + std::to_string(port),
                        SafetyGate(SafetyLimits{}, true), QuietOptions()),
               std::runtime_error);
}

}  // namespace
}  // namespace hnnstereo::robot
