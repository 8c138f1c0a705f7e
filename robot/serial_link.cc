// serial:DEVICE?baud=2400&flow=rtscts|none - the thesis's RS-232 link (THESIS.md section 5):
// write-only, CR-terminated ASCII commands of a Movemaster-class arm, 8 data bits, no parity,
// 2 stop bits. Each admitted pick becomes the thesis pick sequence (robot/thesis_arm.h); a pick
// the arm cannot reach is refused whole before any of its lines is written. Protocol, defaults
// and the cell-command mapping: docs/robot_ascii.md.
//
// Plain POSIX termios and poll(): a write-only line at 2400 baud needs nothing more, and no
// Debian library would do it better. The descriptor is non-blocking so a missing CTS (hardware
// flow control with nothing on the other end) gives a bounded timeout, never a hang.
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <stdexcept>
#include <thread>

#include "robot/link.h"
#include "robot/thesis_arm.h"

namespace hnnstereo::robot {
namespace {

using Clock = std::chrono::steady_clock;

std::string Errno(const std::string& what) { return what + ": " + std::strerror(errno); }

speed_t StandardBaud(const LinkUri& uri, const std::string& text) {
  int baud = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), baud);
  if (error == std::errc() && end == text.data() + text.size()) {
    switch (baud) {
      case 300: return B300;
      case 600: return B600;
      case 1200: return B1200;
      case 1800: return B1800;
      case 2400: return B2400;
      case 4800: return B4800;
      case 9600: return B9600;
      case 19200: return B19200;
      case 38400: return B38400;
      case 57600: return B57600;
      case 115200: return B115200;
      default: break;
    }
  }
  throw std::invalid_argument("robot URI '" + uri.text + "': baud '" + text +
                              "' is not a standard rate (300, 600, 1200, 1800, 2400, 4800, "
                              "9600, 19200, 38400, 57600, 115200)");
}

class SerialLink final : public RobotLink {
 public:
  SerialLink(const LinkUri& uri, SafetyGate gate, LinkOptions options)
      : RobotLink(std::move(gate), std::move(options)), device_(uri.path) {
    std::string baud_text = "2400";
    std::string flow = "rtscts";  // the thesis's CTS/DSR handshake (termios has CTS only)
    for (const auto& [key, value] : uri.query) {
      if (key == "baud") {
        baud_text = value;
      } else if (key == "flow") {
        flow = value;
      } else {
        throw std::invalid_argument("robot URI '" + uri.text + "': unknown serial option '" + key +
                                    "' (baud, flow)");
      }
    }
    if (flow != "rtscts" && flow != "none") {
      throw std::invalid_argument("robot URI '" + uri.text + "': flow must be rtscts or none, not '" +
                                  flow + "'");
    }
    const speed_t baud = StandardBaud(uri, baud_text);
    describe_ = "serial:" + device_ + "?baud=" + baud_text + "&flow=" + flow;

    fd_ = open(device_.c_str(), O_WRONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) throw std::runtime_error(Errno("serial: cannot open '" + device_ + "'"));
    termios tio{};
    if (tcgetattr(fd_, &tio) != 0) {
      const std::string error = Errno("serial: '" + device_ + "' is not a terminal");
      close(fd_);
      throw std::runtime_error(error);
    }
    cfmakeraw(&tio);  // no echo, no CR/LF translation, 8 bits
    tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | CRTSCTS);
    tio.c_cflag |= CS8 | CSTOPB | CLOCAL | CREAD;  // 8N2; ignore modem-status lines
    if (flow == "rtscts") tio.c_cflag |= CRTSCTS;
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    cfsetispeed(&tio, baud);
    cfsetospeed(&tio, baud);
    if (tcsetattr(fd_, TCSANOW, &tio) != 0) {
      const std::string error = Errno("serial: cannot configure '" + device_ + "'");
      close(fd_);
      throw std::runtime_error(error);
    }
  }

  ~SerialLink() override {
    if (fd_ >= 0) close(fd_);
  }

  std::string Describe() const override { return describe_; }

  Trigger WaitForTrigger(std::chrono::milliseconds) override {
    if (stop_requested_.exchange(false)) return {TriggerKind::kStop, request_sequence_};
    ++stats_.triggers;
    return {TriggerKind::kTrigger, ++request_sequence_};
  }

  AckKind WaitForAcknowledge(std::chrono::milliseconds timeout) override {
    if (stop_requested_.load()) return AckKind::kStop;
    // Every byte handed to the driver has left (TIOCOUTQ 0), then tcdrain for the UART's own
    // buffer. Polled so that a line held back by CTS cannot block past the timeout.
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      int queued = 0;
      if (ioctl(fd_, TIOCOUTQ, &queued) != 0) {
        Log(Errno("serial: TIOCOUTQ"));
        return AckKind::kPeerLost;
      }
      if (queued == 0) break;
      if (Clock::now() >= deadline) return AckKind::kTimeout;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (tcdrain(fd_) != 0) {
      Log(Errno("serial: tcdrain"));
      return AckKind::kPeerLost;
    }
    return AckKind::kAcknowledged;
  }

  void SendCellCommand(CellCommand command) override {
    switch (command) {
      case CellCommand::kHome: WriteLines({"OG"}); return;        // the listing's HOME()
      case CellCommand::kOpen: WriteLines({"GO", "GF 0"}); return;  // OnRobotOpen
      case CellCommand::kClose: WriteLines({"GC", "GF 1"}); return;
      case CellCommand::kStop:
        // The command set has no stop: discard what has not left yet and end the loop; the arm
        // finishes the move it already received (a real cell wires an emergency stop).
        stop_requested_ = true;
        tcflush(fd_, TCOFLUSH);
        return;
    }
  }

  LinkStats Stats() const override { return stats_; }

 protected:
  void Send(const CycleResult& admitted) override {
    ++stats_.cycles_published;
    if (admitted.status < 0) {
      // Write-only: the arm cannot be told; nothing moves this cycle.
      Log("cycle " + std::to_string(admitted.request_sequence) + " status " +
          std::to_string(admitted.status) + (admitted.error.empty() ? "" : ": " + admitted.error) +
          "; nothing sent");
      return;
    }
    int drop_index = 0;
    for (const PickCommand& pick : admitted.picks) {
      if (stop_requested_.load()) return;
      std::vector<std::string> lines;
      try {
        lines = ThesisPickLines(geometry_, pick_options_, pick, drop_index);
      } catch (const std::runtime_error& refusal) {
        Log("object " + std::to_string(pick.object_id) + " (sequence " +
            std::to_string(pick.sequence) + ") not sent: " + refusal.what());
        ++stats_.transport_refused;
        continue;
      }
      WriteLines(lines);
      ++stats_.poses_sent;
      ++drop_index;
    }
    if (drop_index > 0 && !stop_requested_.load()) {
      try {
        WriteLines(ThesisAsideLines(geometry_, pick_options_));
      } catch (const std::runtime_error& refusal) {
        Log(std::string("move aside not sent: ") + refusal.what());
      }
    }
  }

 private:
  // One pick's lines go out as one buffer: all of them or (on an I/O error) a thrown error.
  void WriteLines(const std::vector<std::string>& lines) {
    std::string bytes;
    for (const std::string& line : lines) bytes += line + "\r";
    const auto budget = options().io_timeout * static_cast<int>(lines.size());
    const auto deadline = Clock::now() + budget;
    std::size_t written = 0;
    while (written < bytes.size()) {
      const ssize_t n = write(fd_, bytes.data() + written, bytes.size() - written);
      if (n > 0) {
        written += static_cast<std::size_t>(n);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
        throw std::runtime_error(Errno("serial: write to '" + device_ + "' failed"));
      }
      pollfd fd{fd_, POLLOUT, 0};
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0 || poll(&fd, 1, static_cast<int>(left)) <= 0 || (fd.revents & POLLERR)) {
        throw std::runtime_error("serial: '" + device_ + "' did not take the data within " +
                                 std::to_string(budget.count()) +
                                 " ms (flow control holding, or nothing connected)");
      }
    }
  }

  std::string device_;
  std::string describe_;
  int fd_ = -1;
  ThesisArmGeometry geometry_;
  ThesisPickOptions pick_options_;
  std::atomic<bool> stop_requested_{false};
  std::uint32_t request_sequence_ = 0;
  LinkStats stats_;
};

}  // namespace

std::unique_ptr<RobotLink> MakeSerialLink(const LinkUri& uri, SafetyGate gate, LinkOptions options) {
  return std::make_unique<SerialLink>(uri, std::move(gate), std::move(options));
}

}  // namespace hnnstereo::robot
