// The modbus-server request path (robot/modbus_frames.h) on the bytes of one client connection:
// frames cut by CutMbapFrame and answered by HandleModbusFrame on the server's holding
// registers (20 + 8 x 16, the default max_poses), as ProcessFrames does, until the bytes run out
// or the header is malformed (the server drops the connection). The first input byte picks the
// unit-id rule (any, or only unit 1). Traps on a reply that is not one well-formed MBAP frame
// answering the request, or on registers changed by a refused or unaddressed request.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "robot/modbus_frames.h"
#include "robot/modbus_registers.h"

namespace mb = hnnstereo::robot::modbus;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::optional<int> unit = (data[0] & 1) ? std::optional<int>(1) : std::nullopt;
  const std::vector<std::uint8_t> stream(data + 1, data + size);
  const int register_count = mb::RegisterCount(16);
  std::vector<std::uint16_t> registers(static_cast<std::size_t>(register_count));
  for (int i = 0; i < register_count; ++i) registers[i] = static_cast<std::uint16_t>(0x1111 * i);
  std::size_t at = 0;
  while (true) {
    const mb::MbapCut cut = mb::CutMbapFrame(stream.data() + at, stream.size() - at);
    if (cut.kind != mb::MbapCut::Kind::kWhole) {
      if (cut.kind == mb::MbapCut::Kind::kMalformed && cut.problem.empty()) __builtin_trap();
      break;
    }
    if (cut.frame_bytes < mb::kMbapHeaderBytes + 1 || at + cut.frame_bytes > stream.size()) {
      __builtin_trap();
    }
    // The frame in a buffer of its own size, so that ASan sees any read past its end.
    const std::vector<std::uint8_t> frame(stream.begin() + static_cast<std::ptrdiff_t>(at),
                                          stream.begin() +
                                              static_cast<std::ptrdiff_t>(at + cut.frame_bytes));
    const std::vector<std::uint16_t> before = registers;
    const mb::ModbusAnswer answer = mb::HandleModbusFrame(frame.data(), frame.size(), unit,
                                                          registers.data(), register_count);
    const auto* reply = reinterpret_cast<const std::uint8_t*>(answer.frame.data());
    // One MBAP frame: the request's transaction and unit id, protocol 0, the length of what
    // follows, a PDU of 2..253 bytes for the request's function.
    if (answer.frame.size() < mb::kMbapHeaderBytes + 2 ||
        answer.frame.size() > 6 + static_cast<std::size_t>(mb::kMaxMbapLength) ||
        reply[0] != frame[0] || reply[1] != frame[1] || reply[2] != 0 || reply[3] != 0 ||
        static_cast<std::size_t>((reply[4] << 8) | reply[5]) != answer.frame.size() - 6 ||
        reply[6] != frame[6] || (reply[7] & 0x7F) != (frame[7] & 0x7F) ||
        answer.exception != ((reply[7] & 0x80) != 0) ||
        (answer.exception && answer.frame.size() != mb::kMbapHeaderBytes + 2)) {
      __builtin_trap();
    }
    if (!answer.addressed && (!answer.exception || answer.wrote_command)) __builtin_trap();
    if ((answer.exception || !answer.addressed) && registers != before) __builtin_trap();
    at += cut.frame_bytes;
  }
  return 0;
}
