#pragma once
// The Modbus TCP server's request path without the sockets (modbus-server, robot/modbus_link.cc):
// cutting MBAP frames out of the bytes a client sent, and answering one frame on the holding
// registers (function codes 3, 6, 16, 22, 23; the coil and input tables are empty). Pure: no I/O,
// no clock, no lock - the caller holds the registers' lock. Fuzzed by fuzz/fuzz_modbus_frame.cc.
//
// Messaging on TCP/IP Implementation Guide V1.0b, 3.1.3 (MBAP header); Modbus Application
// Protocol V1.1b3, 4.1 and 6 (PDU sizes, function codes, exceptions).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hnnstereo::robot::modbus {

/// The MBAP header: transaction id (2 bytes), protocol id (2), length (2: the bytes that
/// follow, unit id included), unit id.
constexpr std::size_t kMbapHeaderBytes = 7;
constexpr int kMinMbapLength = 2;    ///< unit id + function code
constexpr int kMaxMbapLength = 254;  ///< unit id + the largest PDU (253 bytes)

/// The first frame in a connection's received bytes.
struct MbapCut {
  enum class Kind {
    kIncomplete,  ///< fewer bytes than the header, or than the length it announces
    kWhole,       ///< `frame_bytes` bytes (header + PDU) make one frame
    kMalformed,   ///< protocol id not 0 or length outside 2..254: not a Modbus TCP peer, or a
                  ///< stream that lost its frame boundary; `problem` says which
  };
  Kind kind = Kind::kIncomplete;
  std::size_t frame_bytes = 0;
  std::string problem;
};
MbapCut CutMbapFrame(const std::uint8_t* bytes, std::size_t size);

/// Executes one request PDU (`length` >= 1 bytes) on `registers` (`register_count` holding
/// registers); returns the response PDU or an exception PDU (function | 0x80, code): 1 illegal
/// function, 2 illegal data address, 3 illegal data value (a length or quantity that does not
/// fit the function). `wrote_command`: a write that succeeded and covered register 0.
std::vector<std::uint8_t> ExecuteRequestPdu(const std::uint8_t* pdu, int length,
                                            std::uint16_t* registers, int register_count,
                                            bool* wrote_command);

/// The answer to one frame.
struct ModbusAnswer {
  std::string frame;           ///< the reply: MBAP header (request's transaction and unit id) + PDU
  bool addressed = false;      ///< the unit id is served here: the PDU ran on the registers
  bool exception = false;      ///< the reply is an exception PDU
  bool wrote_command = false;  ///< a write that succeeded covered register 0
};

/// Answers one whole frame (`frame_bytes` as CutMbapFrame's kWhole). `unit`: the only unit id
/// served (another gets exception 0x0B, gateway target failed to respond, and the registers are
/// not touched); nullopt serves every unit id.
ModbusAnswer HandleModbusFrame(const std::uint8_t* frame, std::size_t frame_bytes,
                               std::optional<int> unit, std::uint16_t* registers,
                               int register_count);

}  // namespace hnnstereo::robot::modbus
