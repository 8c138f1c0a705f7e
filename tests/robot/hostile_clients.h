#pragma once
// Misbehaving TCP clients for the listening transports' tests (modbus-server, vision-server):
// each runs in its own thread against 127.0.0.1:PORT until told to stop, reconnecting whenever
// the server closes it, and counts what the server did to it. Every socket call is bounded by
// a 200 ms socket timeout, so Stop() returns promptly.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "robot/link.h"

namespace hnnstereo::robot::testing {

/// A blocking TCP socket to 127.0.0.1:port with send/receive timeouts; -1 when refused.
/// `source`: the local address to connect from (any of 127.0.0.0/8 works on Linux's loopback),
/// so that hostile clients are other hosts than the PLC, as on a cell network.
inline int ConnectTcp(int port, int timeout_ms = 200, const char* source = nullptr) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  timeval timeout{timeout_ms / 1000, (timeout_ms % 1000) * 1000};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
  const int one = 1;
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  if (source != nullptr) {
    // The port is chosen at connect(), not at bind(): a bind to port 0 searches the bound
    // ports (thousands in TIME_WAIT here) and cost the crowd more CPU than the server spent.
    setsockopt(fd, IPPROTO_IP, IP_BIND_ADDRESS_NO_PORT, &one, sizeof one);
    sockaddr_in local{};
    local.sin_family = AF_INET;
    inet_pton(AF_INET, source, &local.sin_addr);
    if (bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
      close(fd);
      return -1;
    }
  }
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

/// What the server did to one hostile client (all threads of one kind add up here).
struct HostileCounters {
  std::atomic<int> connections{0};       ///< connects that succeeded
  std::atomic<int> closed_by_server{0};  ///< EOF or reset seen while the client still wanted more
  std::atomic<int> replies{0};           ///< complete replies read
  std::atomic<int> exception_codes[16] = {};  ///< Modbus exception replies, by code
  std::atomic<int> status_minus_4{0};         ///< vision-server: "(-4,...)" replies
  std::atomic<int> send_stalls{0};            ///< sends that timed out: the server stopped reading
};

/// One misbehaviour: called with a connected socket; returns when the server closed it (after
/// counting that) or when `stop` is set. The fd is closed by the caller.
using Behaviour = std::function<void(int fd, const std::atomic<bool>& stop, HostileCounters&)>;

/// True when the server has closed `fd` (EOF or reset): one receive, bounded by the socket
/// timeout. Bytes that arrive are read and dropped.
inline bool ServerClosed(int fd) {
  char buffer[512];
  const ssize_t n = recv(fd, buffer, sizeof buffer, 0);
  if (n == 0) return true;
  if (n < 0 && (errno == ECONNRESET || errno == EPIPE)) return true;
  return false;
}

/// Sends all of `bytes`; false when the server closed the connection (or the send timed out).
inline bool SendBytes(int fd, const std::string& bytes) {
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

/// Runs `count` threads of one behaviour until Stop() (or destruction).
class HostileCrowd {
 public:
  HostileCrowd() = default;
  HostileCrowd(const HostileCrowd&) = delete;
  HostileCrowd& operator=(const HostileCrowd&) = delete;
  ~HostileCrowd() { Stop(); }

  /// Starts `count` clients behaving as `behaviour`, connecting from 127.0.0.N for N in
  /// first_source..first_source + sources - 1 in turn; returns their shared counters.
  HostileCounters& Add(int port, int count, Behaviour behaviour, int first_source = 2,
                       int sources = 1) {
    counters_.push_back(std::make_unique<HostileCounters>());
    HostileCounters* counters = counters_.back().get();
    for (int i = 0; i < count; ++i) {
      const std::string source = "127.0.0." + std::to_string(first_source + i % sources);
      threads_.emplace_back([this, port, behaviour, counters, source] {
        while (!stop_) {
          const int fd = ConnectTcp(port, 200, source.c_str());
          if (fd < 0) {
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
            continue;
          }
          ++counters->connections;
          behaviour(fd, stop_, *counters);
          close(fd);
          // At most ~1000 reconnects a second per client: unthrottled, the crowd's own TCP
          // churn (kernel time for ~10k connections/s, measured with perf) takes this 2-core
          // machine's CPU from everyone, the server and the PLC included.
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
      });
    }
    return *counters;
  }

  void Stop() {
    stop_ = true;
    for (std::thread& thread : threads_) {
      if (thread.joinable()) thread.join();
    }
    threads_.clear();
  }

 private:
  std::atomic<bool> stop_{false};
  std::vector<std::unique_ptr<HostileCounters>> counters_;
  std::vector<std::thread> threads_;
};

/// The cell side, in its own thread as in `hnnstereo serve`: waits for triggers, publishes
/// `picks(request_sequence)`, waits up to `ack_timeout` for the acknowledge.
class CellThread {
 public:
  CellThread(RobotLink& link, std::function<std::vector<PickCommand>(std::uint32_t)> picks,
             std::chrono::milliseconds ack_timeout)
      : thread_([this, &link, picks = std::move(picks), ack_timeout] {
          while (!stop_) {
            const Trigger trigger = link.WaitForTrigger(std::chrono::milliseconds(50));
            if (trigger.kind != TriggerKind::kTrigger) continue;
            CycleResult cycle;
            cycle.request_sequence = trigger.request_sequence;
            cycle.picks = picks(trigger.request_sequence);
            link.Publish(cycle);
            link.WaitForAcknowledge(ack_timeout);
          }
        }) {}
  ~CellThread() {
    stop_ = true;
    thread_.join();
  }
  CellThread(const CellThread&) = delete;
  CellThread& operator=(const CellThread&) = delete;

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// Waits (at most 10 s, threads start late on a loaded machine) until every kind in `started`
/// has connected once; a kind that never did fails the test.
inline bool AllConnected(const std::vector<HostileCounters*>& started) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  bool all = true;
  for (HostileCounters* counters : started) {
    while (counters->connections == 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    all = all && counters->connections > 0;
  }
  return all;
}

// ---- behaviours common to both servers --------------------------------------------------

/// Connects and never sends; stays until the server closes it.
inline void HeldOpen(int fd, const std::atomic<bool>& stop, HostileCounters& counters) {
  while (!stop) {
    if (ServerClosed(fd)) {
      ++counters.closed_by_server;
      return;
    }
  }
}

/// Sends `bytes` one byte every `gap`, over and over, until the server closes it.
inline Behaviour ByteAtATime(std::string bytes, std::chrono::milliseconds gap) {
  return [bytes, gap](int fd, const std::atomic<bool>& stop, HostileCounters& counters) {
    for (std::size_t i = 0; !stop; i = (i + 1) % bytes.size()) {
      if (!SendBytes(fd, bytes.substr(i, 1))) {
        ++counters.closed_by_server;
        return;
      }
      const auto until = std::chrono::steady_clock::now() + gap;
      while (!stop && std::chrono::steady_clock::now() < until) {
        // Drain replies (and notice a close) while waiting.
        timeval short_wait{0, 20000};
        setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &short_wait, sizeof short_wait);
        if (ServerClosed(fd)) {
          ++counters.closed_by_server;
          return;
        }
      }
    }
  };
}

/// 1..300 random bytes, then hangs up (a port scanner, a wrong protocol).
inline void GarbageAndHangUp(int fd, const std::atomic<bool>&, HostileCounters&) {
  thread_local std::mt19937 random(
      12345u + static_cast<unsigned>(std::hash<std::thread::id>()(std::this_thread::get_id())));
  std::string bytes(1 + random() % 300, '\0');
  for (char& c : bytes) c = static_cast<char>(random());
  SendBytes(fd, bytes);
}

/// Sends `request` as fast as it can and never reads a reply.
inline Behaviour FloodWithoutReading(std::string request) {
  return [request](int fd, const std::atomic<bool>& stop, HostileCounters& counters) {
    std::string burst;
    for (int i = 0; i < 64; ++i) burst += request;
    while (!stop) {
      if (!SendBytes(fd, burst)) {
        // A send timeout means the server stopped reading (its window is full): not a close.
        if (errno == EAGAIN || errno == EWOULDBLOCK) {
          ++counters.send_stalls;
          continue;
        }
        ++counters.closed_by_server;
        return;
      }
    }
  };
}

}  // namespace hnnstereo::robot::testing
