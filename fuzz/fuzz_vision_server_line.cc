// The vision-server's ASCII requests (robot/vision_server_protocol.h) on the bytes of one client
// connection, handled as the transport does: received in chunks (the first input byte sets
// their size), appended with AppendReceived until a tail without a newline passes the line
// limit (ServerLimits::max_line_bytes; the server closes the connection), whole lines taken
// with TakeLine, parsed with ParseRequest and answered with ReplyLine (a NEXT with a pose
// pending, a malformed request with the error code, its text logged through Printable). Traps
// on a line that still holds a newline or untrimmed blanks, a tail miscounted, a log text that
// is not printable ASCII of at most 43 characters, or a reply that is not one line.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "robot/link.h"
#include "robot/vision_server_protocol.h"

namespace vs = hnnstereo::robot::vision_server;

namespace {

void CheckReply(const std::string& reply) {
  if (reply.size() < 3 || reply.front() != '(' || reply.find('\n') != reply.size() - 1 ||
      reply[reply.size() - 2] != ')' || std::count(reply.begin(), reply.end(), ',') != 6) {
    __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::size_t chunk = 1 + data[0] % 64;
  const std::string stream(reinterpret_cast<const char*>(data + 1), size - 1);
  const std::size_t max_line_bytes = hnnstereo::robot::ServerLimits{}.max_line_bytes;
  const std::size_t read_ahead = 4 * max_line_bytes;  // VisionServerLink::ReadAheadBytes
  hnnstereo::robot::PickCommand pick;
  pick.position_mm = Eigen::Vector3d(350.0, -120.5, 42.0);
  pick.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  int pending = 2;
  std::string input;
  std::size_t at = 0;
  while (at < stream.size()) {
    const std::size_t room = read_ahead - std::min(read_ahead, input.size());
    const std::size_t count = std::min({chunk, room, stream.size() - at});
    if (count == 0) __builtin_trap();  // a full buffer always holds a line (or was refused)
    const std::size_t old_size = input.size();
    const vs::Appended appended = vs::AppendReceived(&input, stream.data() + at, count);
    at += count;
    const auto newline = input.rfind('\n');
    const std::size_t tail = newline == std::string::npos ? input.size() : input.size() - 1 - newline;
    if (appended.tail != tail || input.size() != old_size + count) __builtin_trap();
    if (appended.tail > max_line_bytes) {  // the server answers -4 and closes the connection
      CheckReply(vs::ReplyLine(hnnstereo::robot::kErrorMalformedRequest, nullptr));
      return 0;
    }
    while (vs::HasCompleteLine(input)) {
      const std::size_t before = input.size();
      const std::string line = vs::TakeLine(&input);
      if (input.size() >= before || line.find('\n') != std::string::npos) __builtin_trap();
      if (!line.empty() && (std::string(" \t\r").find(line.front()) != std::string::npos ||
                            std::string(" \t\r").find(line.back()) != std::string::npos)) {
        __builtin_trap();
      }
      switch (vs::ParseRequest(line)) {
        case vs::Request::kTrigger:
        case vs::Request::kStop:
          if (line != "TRIG" && line != "STOP") __builtin_trap();
          break;
        case vs::Request::kNext:
          if (line != "NEXT") __builtin_trap();
          CheckReply(pending > 0 ? vs::ReplyLine(1, &pick) : vs::ReplyLine(0, nullptr));
          if (pending > 0) --pending;
          break;
        case vs::Request::kMalformed: {
          const std::string shown = vs::Printable(line);
          if (shown.size() > 43) __builtin_trap();
          for (char c : shown) {
            if (c < 32 || c > 126) __builtin_trap();
          }
          CheckReply(vs::ReplyLine(hnnstereo::robot::kErrorMalformedRequest, nullptr));
          break;
        }
      }
    }
  }
  return 0;
}
