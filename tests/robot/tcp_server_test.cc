// The TCP server core under modbus-server and vision-server (robot/tcp_server.h): its
// per-connection limits (ServerLimits, docs/robot.md "Hostile clients") tested once, under a
// trivial line protocol. The test thread is both the clients and the server's driver, so
// every step is ordered; timers are aged by moving a connection's time stamps back, not by
// sleeping. 127.0.0.1 and other loopback addresses, every wait bounded.
#include "robot/tcp_server.h"

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "hostile_clients.h"

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;
using testing::ConnectTcp;
using testing::SendBytes;

/// One line a request: "OK" is valid (answered "ok"), "BIG" is valid and answered 16 MiB,
/// "PROTECT" makes its connection protected, anything else is answered "bad".
class LineProtocol : public TcpServerProtocol {
 public:
  bool HasWholeRequest(const TcpConnection& connection) const override {
    return connection.input.find('\n') != std::string::npos;
  }
  void OnRequestIncomplete(TcpConnection& connection) override {
    connection.MarkForClose("incomplete");
  }
  bool IsProtected(const TcpConnection& connection) const override {
    return protected_ids.count(connection.id) > 0;
  }
  bool LogsLoss(const TcpConnection&, int) const override { return false; }
  void OnAccepted(TcpConnection&) override { ++accepted; }
  void OnClosed(const TcpConnection& connection) override {
    closed.push_back(connection.close_reason);
  }
  void WriteLog(const std::string& line) override { log.push_back(line); }

  /// Answers every whole line the token bucket allows.
  void Process(TcpServer& server) {
    for (TcpConnection& connection : server.connections()) {
      std::size_t end = 0;
      while (!connection.closing() && (end = connection.input.find('\n')) != std::string::npos &&
             server.TakeToken(connection)) {
        const std::string line = connection.input.substr(0, end);
        connection.input.erase(0, end + 1);
        ++requests;
        if (line == "OK" || line == "BIG") connection.last_valid = Clock::now();
        if (line == "PROTECT") protected_ids.insert(connection.id);
        server.Queue(connection, line == "OK"    ? "ok\n"
                                 : line == "BIG" ? std::string(16 << 20, 'x')
                                                 : "bad\n");
      }
    }
  }

  std::set<int> protected_ids;
  int accepted = 0;
  int requests = 0;
  std::vector<std::string> closed;  ///< close reasons, in order
  std::vector<std::string> log;
};

struct Server {
  explicit Server(ServerLimits limits, milliseconds io_timeout = milliseconds(2000))
      : server("127.0.0.1", 0, TcpServerSettings{"test-server", "", 1024, io_timeout, limits},
               protocol) {}

  /// Server rounds until `done` holds (true) or 5 s pass (false).
  bool PumpUntil(const std::function<bool()>& done) {
    const auto deadline = Clock::now() + std::chrono::seconds(5);
    while (Clock::now() < deadline) {
      server.Wait(Clock::now() + milliseconds(5));
      protocol.Process(server);
      server.EndRound();
      if (done()) return true;
    }
    return false;
  }
  /// Runs rounds for `duration`: for what must not happen meanwhile.
  void PumpFor(milliseconds duration) {
    const auto end = Clock::now() + duration;
    PumpUntil([&] { return Clock::now() >= end; });
  }
  /// Connections the server took or refused so far.
  int Taken() const {
    int refused = 0;
    for (const std::string& line : protocol.log)
      refused += line.find(" refused: ") != std::string::npos;
    return protocol.accepted + refused;
  }
  /// Connects from `source` and runs rounds until the server has taken or refused it.
  int Connect(const char* source) {
    const int before = Taken();
    const int fd = ConnectTcp(server.port(), 2000, source);
    EXPECT_GE(fd, 0);
    EXPECT_TRUE(PumpUntil([&] { return Taken() > before; }));
    return fd;
  }
  /// Sends "OK" on `fd` and waits for "ok" (after earlier replies): the connection is served.
  bool Served(int fd) {
    if (!SendBytes(fd, "OK\n")) return false;
    std::string reply;
    auto answered = [&] {
      return reply.size() >= 3 && reply.compare(reply.size() - 3, 3, "ok\n") == 0;
    };
    PumpUntil([&] {
      char buffer[256];
      const ssize_t n = recv(fd, buffer, sizeof buffer, MSG_DONTWAIT);
      if (n > 0) reply.append(buffer, static_cast<std::size_t>(n));
      return n == 0 || answered();
    });
    return answered();
  }
  /// Ages every open connection by `age`: accepted and last valid request that much earlier.
  void Age(milliseconds age) {
    for (TcpConnection& connection : server.connections()) {
      connection.accepted -= age;
      if (connection.last_valid) *connection.last_valid -= age;
    }
  }

  LineProtocol protocol;
  TcpServer server;
};

/// True when the server closed `fd` (EOF or reset), read without waiting.
bool ClosedByServer(int fd) {
  char buffer[4096];
  for (;;) {
    const ssize_t n = recv(fd, buffer, sizeof buffer, MSG_DONTWAIT);
    if (n == 0) return true;
    if (n < 0) return errno == ECONNRESET || errno == EPIPE;
  }
}

ServerLimits Limits(int max_connections, int per_peer) {
  ServerLimits limits;
  limits.max_connections = max_connections;
  limits.max_connections_per_peer = per_peer;
  return limits;
}

TEST(TcpServer, BindsPortZeroToAFreePortAndRefusesOneInUse) {
  Server first(ServerLimits{});
  EXPECT_GT(first.server.port(), 0);
  LineProtocol protocol;
  EXPECT_THROW(
      TcpServer("127.0.0.1", first.server.port(),
                TcpServerSettings{"test-server", "", 1024, milliseconds(100), {}}, protocol),
      std::runtime_error);
}

TEST(TcpServer, AtThePerPeerLimitThePeersQuietestConnectionGivesWay) {
  Server s(Limits(32, 2));
  const int silent = s.Connect("127.0.0.2");
  const int active = s.Connect("127.0.0.2");
  ASSERT_TRUE(s.Served(active));
  s.Age(TcpServer::kEvictionGrace + milliseconds(1));  // out of the new connection's grace
  const int newcomer = s.Connect("127.0.0.2");
  EXPECT_TRUE(ClosedByServer(silent)) << "the silent one is the quietest";
  EXPECT_TRUE(s.Served(active));
  EXPECT_TRUE(s.Served(newcomer));
  ASSERT_EQ(s.protocol.closed.size(), 1u);
  EXPECT_NE(s.protocol.closed[0].find("per-peer limit 2"), std::string::npos);
  // Another peer is not limited by this one's slots.
  EXPECT_TRUE(s.Served(s.Connect("127.0.0.3")));
}

TEST(TcpServer, ANewConnectionIsSafeFromItsOwnPeerForTheGrace) {
  Server s(Limits(32, 1));
  const int first = s.Connect("127.0.0.2");
  const int second = s.Connect("127.0.0.2");  // within the grace of the first: refused
  EXPECT_TRUE(ClosedByServer(second));
  EXPECT_TRUE(s.Served(first));
}

TEST(TcpServer, AnActiveConnectionNeverGivesWayAQuietOneDoes) {
  Server s(Limits(32, 1));
  const int plc = s.Connect("127.0.0.2");
  ASSERT_TRUE(s.Served(plc));
  s.Age(TcpServer::kEvictionGrace + milliseconds(1));
  const int refused = s.Connect("127.0.0.2");
  EXPECT_TRUE(ClosedByServer(refused)) << "a valid request within kEvictAfterQuiet: no room";
  EXPECT_TRUE(s.Served(plc));
  s.Age(TcpServer::kEvictAfterQuiet + milliseconds(1));
  const int newcomer = s.Connect("127.0.0.2");
  EXPECT_TRUE(ClosedByServer(plc)) << "quiet for kEvictAfterQuiet: it gives way";
  EXPECT_TRUE(s.Served(newcomer));
  EXPECT_FALSE(s.protocol.log.empty()) << "the refusal is logged";
}

TEST(TcpServer, AProtectedConnectionNeverGivesWay) {
  Server s(Limits(32, 1));
  const int robot = s.Connect("127.0.0.2");
  ASSERT_TRUE(SendBytes(robot, "PROTECT\n"));
  ASSERT_TRUE(s.PumpUntil([&] { return !s.protocol.protected_ids.empty(); }));
  s.Age(TcpServer::kEvictionGrace + milliseconds(1));  // out of its grace, never valid
  const int newcomer = s.Connect("127.0.0.2");
  EXPECT_TRUE(ClosedByServer(newcomer));
  EXPECT_TRUE(s.Served(robot));
}

TEST(TcpServer, AtTheOverallLimitAHeavierPeerGivesWayNotALightOne) {
  Server s(Limits(4, 8));
  std::vector<int> flood;
  for (int i = 0; i < 3; ++i) flood.push_back(s.Connect("127.0.0.2"));
  const int light = s.Connect("127.0.0.3");  // 4 of 4: a peer with 1 against one with 3
  const int newcomer = s.Connect("127.0.0.4");
  EXPECT_TRUE(ClosedByServer(flood[0])) << "the flood's oldest silent connection";
  EXPECT_TRUE(s.Served(light));
  EXPECT_TRUE(s.Served(newcomer));
  // Now the flood holds 2 against the newcomer peer's 1: not two more, so it keeps them, and
  // the newcomer's own connection is within its grace: the second newcomer is refused.
  const int second = s.Connect("127.0.0.4");
  EXPECT_TRUE(ClosedByServer(second));
  for (const int fd : {flood[1], flood[2], light, newcomer}) EXPECT_FALSE(ClosedByServer(fd));
}

TEST(TcpServer, ASilentConnectionIsClosedAfterTheFirstRequestTimeout) {
  ServerLimits limits;
  limits.first_request_timeout = milliseconds(300);
  Server s(limits);
  const int silent = s.Connect("127.0.0.2");
  const int speaker = s.Connect("127.0.0.2");
  ASSERT_TRUE(s.Served(speaker));
  s.Age(milliseconds(301));
  ASSERT_TRUE(s.PumpUntil([&] { return !s.protocol.closed.empty(); }));
  EXPECT_TRUE(ClosedByServer(silent));
  EXPECT_NE(s.protocol.closed[0].find("no valid request within 300 ms"), std::string::npos);
  EXPECT_TRUE(s.Served(speaker));
}

TEST(TcpServer, AStartedRequestMustCompleteWithinTheIoTimeout) {
  Server s(ServerLimits{}, milliseconds(200));
  const int trickle = s.Connect("127.0.0.2");
  ASSERT_TRUE(s.Served(trickle));
  ASSERT_TRUE(SendBytes(trickle, "O"));
  ASSERT_TRUE(s.PumpUntil([&] { return !s.server.connections()[0].input.empty(); }));
  s.server.connections()[0].request_started -= milliseconds(201);
  ASSERT_TRUE(s.PumpUntil([&] { return !s.protocol.closed.empty(); }));
  EXPECT_EQ(s.protocol.closed[0], "incomplete") << "the protocol's OnRequestIncomplete decides";
}

TEST(TcpServer, TheTokenBucketRefillsAtTheRateUpToTheBurst) {
  ServerLimits limits;
  limits.max_requests_per_second = 1;
  limits.request_burst = 3;
  Server s(limits);
  TcpConnection connection;
  connection.tokens = 0.0;
  connection.tokens_at = Clock::now() - milliseconds(2500);  // 2.5 tokens earned
  EXPECT_TRUE(s.server.TakeToken(connection));
  EXPECT_TRUE(s.server.TakeToken(connection));
  EXPECT_FALSE(s.server.TakeToken(connection)) << "half a token is no request";
  connection.tokens_at -= std::chrono::hours(1);  // far more earned than the burst
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(s.server.TakeToken(connection));
  EXPECT_FALSE(s.server.TakeToken(connection)) << "at most request_burst saved";
}

TEST(TcpServer, RequestsOverTheRateWaitAndAreServedNotRefused) {
  ServerLimits limits;
  limits.max_requests_per_second = 200;
  limits.request_burst = 5;
  Server s(limits);
  const int flood = s.Connect("127.0.0.2");
  std::string lines;
  for (int i = 0; i < 25; ++i) lines += "OK\n";
  const auto start = Clock::now();
  ASSERT_TRUE(SendBytes(flood, lines));
  ASSERT_TRUE(s.PumpUntil([&] { return s.protocol.requests == 25; }));
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  // The bucket holds 5 and refills 200 a second: 25 requests span at least 19 refill intervals.
  EXPECT_GE(seconds, 19 / 200.0);
  EXPECT_TRUE(s.protocol.closed.empty());
  EXPECT_TRUE(s.Served(flood));
}

TEST(TcpServer, AClientThatDoesNotReadIsNotReadFromAndIsClosedAfterTheIoTimeout) {
  Server s(ServerLimits{}, milliseconds(300));
  const int reader = s.Connect("127.0.0.2");
  int small = 0;
  setsockopt(reader, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  ASSERT_TRUE(SendBytes(reader, "BIG\n"));
  // The reply piles up past the read-ahead (the client takes nothing) ...
  ASSERT_TRUE(s.PumpUntil([&] { return s.server.connections()[0].output.size() > 1024; }));
  // ... so its next request is not read meanwhile.
  ASSERT_TRUE(SendBytes(reader, "OK\n"));
  s.PumpFor(milliseconds(200));
  EXPECT_EQ(s.protocol.requests, 1);
  EXPECT_TRUE(s.server.connections()[0].input.empty());
  s.server.connections()[0].output_since -= milliseconds(301);
  ASSERT_TRUE(s.PumpUntil([&] { return !s.protocol.closed.empty(); }));
  EXPECT_NE(s.protocol.closed[0].find("replies not read for 300 ms"), std::string::npos);
}

TEST(TcpServer, AtMostKAcceptsPerRoundTakesEveryoneInTurn) {
  Server s(Limits(200, 200));
  std::vector<int> clients;
  for (int i = 0; i < TcpServer::kAcceptsPerRound + 10; ++i) {
    clients.push_back(ConnectTcp(s.server.port(), 2000, "127.0.0.2"));
    ASSERT_GE(clients.back(), 0);
  }
  // One round: the listening socket is readable at once (the kernel completed the handshakes).
  s.server.Wait(Clock::now() + std::chrono::seconds(2));
  s.server.EndRound();
  EXPECT_EQ(s.protocol.accepted, TcpServer::kAcceptsPerRound);
  ASSERT_TRUE(s.PumpUntil([&] { return s.protocol.accepted == static_cast<int>(clients.size()); }));
  for (const int fd : clients) close(fd);
}

}  // namespace
}  // namespace hnnstereo::robot
