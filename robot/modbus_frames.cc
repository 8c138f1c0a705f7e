#include "robot/modbus_frames.h"

#include <modbus/modbus.h>

#include "robot/modbus_registers.h"

namespace hnnstereo::robot::modbus {
namespace {

std::uint16_t Word(const std::uint8_t* bytes) {
  return static_cast<std::uint16_t>((bytes[0] << 8) | bytes[1]);
}

std::vector<std::uint8_t> ExceptionPdu(std::uint8_t function, std::uint8_t code) {
  return {static_cast<std::uint8_t>(function | 0x80), code};
}

}  // namespace

MbapCut CutMbapFrame(const std::uint8_t* bytes, std::size_t size) {
  MbapCut cut;
  if (size < kMbapHeaderBytes) return cut;
  const int protocol = Word(bytes + 2);
  const int length = Word(bytes + 4);
  // The protocol identifier of Modbus is 0, and the length counts the unit id and the PDU - at
  // least 2 bytes (unit id and function code) and at most 254. Anything else: drop the
  // connection rather than wait for 65535 bytes.
  if (protocol != 0 || length < kMinMbapLength || length > kMaxMbapLength) {
    cut.kind = MbapCut::Kind::kMalformed;
    cut.problem = "malformed MBAP header (protocol id " + std::to_string(protocol) + ", length " +
                  std::to_string(length) + ")";
    return cut;
  }
  const std::size_t frame_bytes = 6u + static_cast<std::size_t>(length);
  if (size < frame_bytes) return cut;
  cut.kind = MbapCut::Kind::kWhole;
  cut.frame_bytes = frame_bytes;
  return cut;
}

std::vector<std::uint8_t> ExecuteRequestPdu(const std::uint8_t* pdu, int length,
                                            std::uint16_t* registers, int register_count,
                                            bool* wrote_command) {
  const std::uint8_t function = pdu[0];
  const auto in_map = [register_count](int address, int count) {
    return address + count <= register_count;
  };
  const auto words_reply = [&](int address, int count) {
    std::vector<std::uint8_t> reply = {function, static_cast<std::uint8_t>(2 * count)};
    for (int i = 0; i < count; ++i) {
      reply.push_back(static_cast<std::uint8_t>(registers[address + i] >> 8));
      reply.push_back(static_cast<std::uint8_t>(registers[address + i] & 0xFF));
    }
    return reply;
  };
  const auto write_words = [&](int address, int count, const std::uint8_t* values) {
    for (int i = 0; i < count; ++i) registers[address + i] = Word(values + 2 * i);
    *wrote_command = address == kCommandRegister;
  };
  // A PDU whose length does not match its function is an illegal data value (exception 3).
  switch (function) {
    case MODBUS_FC_READ_HOLDING_REGISTERS: {  // 6.3: quantity 1..125
      if (length != 5) break;
      const int address = Word(pdu + 1);
      const int count = Word(pdu + 3);
      if (count < 1 || count > MODBUS_MAX_READ_REGISTERS) break;
      if (!in_map(address, count)) return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
      return words_reply(address, count);
    }
    case MODBUS_FC_WRITE_SINGLE_REGISTER: {  // 6.6: the response echoes the request
      if (length != 5) break;
      const int address = Word(pdu + 1);
      if (!in_map(address, 1)) return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
      write_words(address, 1, pdu + 3);
      return {pdu, pdu + 5};
    }
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {  // 6.12: quantity 1..123, bytes = 2 x quantity
      if (length < 6) break;
      const int address = Word(pdu + 1);
      const int count = Word(pdu + 3);
      const int bytes = pdu[5];
      if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || bytes != 2 * count ||
          length != 6 + bytes) {
        break;
      }
      if (!in_map(address, count)) return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
      write_words(address, count, pdu + 6);
      return {pdu, pdu + 5};
    }
    case MODBUS_FC_MASK_WRITE_REGISTER: {  // 6.16: (current AND and) OR (or AND NOT and)
      if (length != 7) break;
      const int address = Word(pdu + 1);
      if (!in_map(address, 1)) return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
      const std::uint16_t and_mask = Word(pdu + 3);
      const std::uint16_t or_mask = Word(pdu + 5);
      registers[address] = static_cast<std::uint16_t>((registers[address] & and_mask) |
                                                      (or_mask & ~and_mask));
      *wrote_command = address == kCommandRegister;
      return {pdu, pdu + 7};
    }
    case MODBUS_FC_WRITE_AND_READ_REGISTERS: {  // 6.17: read 1..125, write 1..121; write first
      if (length < 10) break;
      const int read_address = Word(pdu + 1);
      const int read_count = Word(pdu + 3);
      const int write_address = Word(pdu + 5);
      const int write_count = Word(pdu + 7);
      const int bytes = pdu[9];
      if (read_count < 1 || read_count > MODBUS_MAX_WR_READ_REGISTERS || write_count < 1 ||
          write_count > MODBUS_MAX_WR_WRITE_REGISTERS || bytes != 2 * write_count ||
          length != 10 + bytes) {
        break;
      }
      if (!in_map(read_address, read_count) || !in_map(write_address, write_count)) {
        return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
      }
      write_words(write_address, write_count, pdu + 10);
      return words_reply(read_address, read_count);
    }
    case MODBUS_FC_READ_COILS:
    case MODBUS_FC_READ_DISCRETE_INPUTS:
    case MODBUS_FC_READ_INPUT_REGISTERS:
    case MODBUS_FC_WRITE_SINGLE_COIL:
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
      // Tables this server has with no entries: every address is illegal (exception 2, as
      // libmodbus's modbus_reply answered with empty tables).
      return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
    default:
      return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
  }
  return ExceptionPdu(function, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
}

ModbusAnswer HandleModbusFrame(const std::uint8_t* frame, std::size_t frame_bytes,
                               std::optional<int> unit, std::uint16_t* registers,
                               int register_count) {
  ModbusAnswer answer;
  const std::uint8_t request_unit = frame[6];
  const std::uint8_t* pdu = frame + kMbapHeaderBytes;
  const int pdu_length = static_cast<int>(frame_bytes - kMbapHeaderBytes);
  std::vector<std::uint8_t> reply;
  if (unit && request_unit != *unit) {
    reply = ExceptionPdu(pdu[0], MODBUS_EXCEPTION_GATEWAY_TARGET);
  } else {
    answer.addressed = true;
    reply = ExecuteRequestPdu(pdu, pdu_length, registers, register_count, &answer.wrote_command);
  }
  answer.exception = (reply[0] & 0x80) != 0;
  // The reply's MBAP header: the request's transaction id and unit id, protocol id 0, the
  // length of unit id + PDU.
  const std::size_t length = reply.size() + 1;
  const char header[kMbapHeaderBytes] = {
      static_cast<char>(frame[0]), static_cast<char>(frame[1]), 0, 0,
      static_cast<char>(length >> 8), static_cast<char>(length & 0xFF),
      static_cast<char>(request_unit)};
  answer.frame.assign(header, kMbapHeaderBytes);
  answer.frame.append(reply.begin(), reply.end());
  return answer;
}

}  // namespace hnnstereo::robot::modbus
