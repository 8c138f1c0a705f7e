// The Modbus register codec (robot/modbus_registers.h): int32 words high first, fixed-point
// poses, int16 status, and refusal (never wrap) of values that do not fit. The server's request
// path without sockets (robot/modbus_frames.h): MBAP frames cut and answered.
#include "robot/modbus_registers.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "robot/link.h"
#include "robot/modbus_frames.h"

namespace hnnstereo::robot::modbus {
namespace {

TEST(ModbusRegisters, Int32HighWordFirst) {
  const auto words = EncodeInt32(0x12345678);
  EXPECT_EQ(words[0], 0x1234);
  EXPECT_EQ(words[1], 0x5678);
  const auto minus_one = EncodeInt32(-1);
  EXPECT_EQ(minus_one[0], 0xFFFF);
  EXPECT_EQ(minus_one[1], 0xFFFF);
  const auto minus_two_to_16 = EncodeInt32(-65536);
  EXPECT_EQ(minus_two_to_16[0], 0xFFFF);
  EXPECT_EQ(minus_two_to_16[1], 0x0000);
}

TEST(ModbusRegisters, Int32RoundTripIncludingExtremes) {
  const std::int32_t values[] = {0,      1,          -1,         32767,      -32768, 65535,
                                 65536,  -65536,     123456789,  -123456789,
                                 std::numeric_limits<std::int32_t>::max(),
                                 std::numeric_limits<std::int32_t>::min()};
  for (const std::int32_t value : values) {
    const auto words = EncodeInt32(value);
    EXPECT_EQ(DecodeInt32(words[0], words[1]), value);
  }
  std::mt19937 random(20261122);  // seeded
  std::uniform_int_distribution<std::int32_t> any(std::numeric_limits<std::int32_t>::min(),
                                                  std::numeric_limits<std::int32_t>::max());
  for (int i = 0; i < 10000; ++i) {
    const std::int32_t value = any(random);
    const auto words = EncodeInt32(value);
    ASSERT_EQ(DecodeInt32(words[0], words[1]), value) << "seed 20261122, draw " << i;
  }
}

TEST(ModbusRegisters, FixedPointRoundsAndRefusesWhatDoesNotFit) {
  EXPECT_EQ(ToFixedPoint(123.456, kPositionUnitsPerMm, "x"), 12346);
  EXPECT_EQ(ToFixedPoint(-123.456, kPositionUnitsPerMm, "x"), -12346);
  EXPECT_EQ(ToFixedPoint(-0.004, kPositionUnitsPerMm, "x"), 0);
  // The largest position that fits: (2^31 - 1) / 100 mm.
  EXPECT_EQ(ToFixedPoint(21474836.47, kPositionUnitsPerMm, "x"), 2147483647);
  EXPECT_EQ(ToFixedPoint(-21474836.48, kPositionUnitsPerMm, "x"), -2147483647 - 1);
  EXPECT_THROW(ToFixedPoint(21474836.48, kPositionUnitsPerMm, "x"), std::out_of_range);
  EXPECT_THROW(ToFixedPoint(-21474836.49, kPositionUnitsPerMm, "x"), std::out_of_range);
  EXPECT_THROW(ToFixedPoint(1e12, kPositionUnitsPerMm, "x"), std::out_of_range);
  EXPECT_THROW(ToFixedPoint(std::nan(""), kPositionUnitsPerMm, "x"), std::out_of_range);
  EXPECT_THROW(ToFixedPoint(std::numeric_limits<double>::infinity(), kYawUnitsPerDegree, "yaw"),
               std::out_of_range);
}

TEST(ModbusRegisters, PoseRoundTripWithNegatives) {
  PickCommand pick;
  pick.position_mm = Eigen::Vector3d(-399.99, 250.01, 0.0);
  pick.yaw_deg = -89.999;
  const auto words = EncodePose(pick);
  // x = -39999 = 0xFFFF63C1, high word first.
  EXPECT_EQ(words[0], 0xFFFF);
  EXPECT_EQ(words[1], 0x63C1);
  const PoseWords pose = DecodePose(words.data());
  EXPECT_NEAR(pose.x_mm, -399.99, 1e-9);
  EXPECT_NEAR(pose.y_mm, 250.01, 1e-9);
  EXPECT_NEAR(pose.z_mm, 0.0, 1e-9);
  EXPECT_NEAR(pose.yaw_deg, -89.999, 1e-9);
  // Resolution: 0.005 mm and 0.0005 degree at worst.
  pick.position_mm = Eigen::Vector3d(1.234567, -2.345678, 3.456789);
  pick.yaw_deg = 45.67891;
  const PoseWords rounded = DecodePose(EncodePose(pick).data());
  EXPECT_NEAR(rounded.x_mm, 1.234567, 0.005);
  EXPECT_NEAR(rounded.y_mm, -2.345678, 0.005);
  EXPECT_NEAR(rounded.z_mm, 3.456789, 0.005);
  EXPECT_NEAR(rounded.yaw_deg, 45.67891, 0.0005);
}

TEST(ModbusRegisters, PoseOutOfRangeIsRefusedNotWrapped) {
  PickCommand pick;
  pick.position_mm = Eigen::Vector3d(0.0, 0.0, 3e7);  // 3e9 units > 2^31 - 1
  EXPECT_THROW(EncodePose(pick), std::out_of_range);
  pick.position_mm = Eigen::Vector3d::Zero();
  pick.yaw_deg = 3e6;  // 3e9 units
  EXPECT_THROW(EncodePose(pick), std::out_of_range);
}

TEST(ModbusRegisters, StatusIsInt16TwosComplement) {
  EXPECT_EQ(EncodeStatus(kStatusResultReady), 2);
  EXPECT_EQ(EncodeStatus(kErrorSensingFailed), 0xFFFF);
  EXPECT_EQ(EncodeStatus(kErrorAllRefused), 0xFFFD);
  EXPECT_EQ(EncodeStatus(kErrorMalformedRequest), 0xFFFC);
  for (const int status : {0, 1, 2, -1, -2, -3, -4, 32767, -32768}) {
    EXPECT_EQ(DecodeStatus(EncodeStatus(status)), status);
  }
  EXPECT_THROW(EncodeStatus(32768), std::out_of_range);
  EXPECT_THROW(EncodeStatus(-32769), std::out_of_range);
}

TEST(ModbusRegisters, MapSize) {
  EXPECT_EQ(RegisterCount(1), 28);
  EXPECT_EQ(RegisterCount(16), 148);
  EXPECT_EQ(RegisterCount(64), 532);
}


// An MBAP frame: transaction id, protocol 0, length (unit id + PDU), unit id, PDU.
std::vector<std::uint8_t> Frame(std::uint16_t transaction, std::uint8_t unit,
                                const std::vector<std::uint8_t>& pdu) {
  const std::size_t length = pdu.size() + 1;
  std::vector<std::uint8_t> frame(kMbapHeaderBytes + pdu.size(), 0);
  frame[0] = static_cast<std::uint8_t>(transaction >> 8);
  frame[1] = static_cast<std::uint8_t>(transaction & 0xFF);
  frame[4] = static_cast<std::uint8_t>(length >> 8);
  frame[5] = static_cast<std::uint8_t>(length & 0xFF);
  frame[6] = unit;
  std::copy(pdu.begin(), pdu.end(), frame.begin() + kMbapHeaderBytes);
  return frame;
}

std::string Bytes(const std::vector<std::uint8_t>& bytes) {
  return std::string(bytes.begin(), bytes.end());
}

TEST(ModbusFrames, CutWaitsForWholeFramesAndRefusesBrokenHeaders) {
  const std::vector<std::uint8_t> read = Frame(7, 1, {0x03, 0x00, 0x0A, 0x00, 0x04});
  EXPECT_EQ(CutMbapFrame(read.data(), 6).kind, MbapCut::Kind::kIncomplete);
  EXPECT_EQ(CutMbapFrame(read.data(), read.size() - 1).kind, MbapCut::Kind::kIncomplete);
  std::vector<std::uint8_t> two = read;
  two.insert(two.end(), read.begin(), read.end());
  const MbapCut cut = CutMbapFrame(two.data(), two.size());
  EXPECT_EQ(cut.kind, MbapCut::Kind::kWhole);
  EXPECT_EQ(cut.frame_bytes, read.size());
  std::vector<std::uint8_t> bad = read;
  bad[3] = 1;  // protocol id 1
  EXPECT_EQ(CutMbapFrame(bad.data(), bad.size()).kind, MbapCut::Kind::kMalformed);
  EXPECT_EQ(CutMbapFrame(bad.data(), bad.size()).problem,
            "malformed MBAP header (protocol id 1, length 6)");
  for (const int length : {0, 1, 255, 65535}) {
    bad = read;
    bad[3] = 0;
    bad[4] = static_cast<std::uint8_t>(length >> 8);
    bad[5] = static_cast<std::uint8_t>(length & 0xFF);
    EXPECT_EQ(CutMbapFrame(bad.data(), bad.size()).kind, MbapCut::Kind::kMalformed) << length;
  }
}

TEST(ModbusFrames, AnswersReadsAndWritesOnTheRegisters) {
  std::vector<std::uint16_t> registers(static_cast<std::size_t>(RegisterCount(1)), 0);
  const int count = static_cast<int>(registers.size());
  registers[kStatusRegister] = 0x1234;
  // 3: read status .. pose count
  std::vector<std::uint8_t> request = Frame(0x0102, 1, {0x03, 0x00, 0x0B, 0x00, 0x02});
  ModbusAnswer answer = HandleModbusFrame(request.data(), request.size(), std::nullopt,
                                          registers.data(), count);
  EXPECT_TRUE(answer.addressed);
  EXPECT_FALSE(answer.exception);
  EXPECT_FALSE(answer.wrote_command);
  EXPECT_EQ(answer.frame, Bytes(Frame(0x0102, 1, {0x03, 0x04, 0x12, 0x34, 0x00, 0x00})));
  // 6: the trigger into register 0, echoed
  request = Frame(3, 1, {0x06, 0x00, 0x00, 0x00, 0x01});
  answer = HandleModbusFrame(request.data(), request.size(), 1, registers.data(), count);
  EXPECT_TRUE(answer.wrote_command);
  EXPECT_EQ(answer.frame, Bytes(request));
  EXPECT_EQ(registers[kCommandRegister], kCommandTrigger);
  // 16: sequence and command in one write; 22: mask write; 23: write then read
  request = Frame(4, 1, {0x10, 0x00, 0x00, 0x00, 0x02, 0x04, 0x00, 0x02, 0x00, 0x2A});
  answer = HandleModbusFrame(request.data(), request.size(), std::nullopt, registers.data(), count);
  EXPECT_TRUE(answer.wrote_command);
  EXPECT_EQ(answer.frame, Bytes(Frame(4, 1, {0x10, 0x00, 0x00, 0x00, 0x02})));
  EXPECT_EQ(registers[kRequestSequenceRegister], 42);
  request = Frame(5, 1, {0x16, 0x00, 0x01, 0xFF, 0x00, 0x00, 0x07});
  answer = HandleModbusFrame(request.data(), request.size(), std::nullopt, registers.data(), count);
  EXPECT_FALSE(answer.wrote_command);
  EXPECT_EQ(registers[kRequestSequenceRegister], 7);
  request = Frame(6, 1, {0x17, 0x00, 0x01, 0x00, 0x01, 0x00, 0x01, 0x00, 0x01, 0x02, 0x00, 0x09});
  answer = HandleModbusFrame(request.data(), request.size(), std::nullopt, registers.data(), count);
  EXPECT_EQ(answer.frame, Bytes(Frame(6, 1, {0x17, 0x02, 0x00, 0x09})));
}

TEST(ModbusFrames, ExceptionsLeaveTheRegistersAlone) {
  std::vector<std::uint16_t> registers(static_cast<std::size_t>(RegisterCount(1)), 5);
  const std::vector<std::uint16_t> before = registers;
  const int count = static_cast<int>(registers.size());
  const auto exception_of = [&](const std::vector<std::uint8_t>& request, std::optional<int> unit) {
    const ModbusAnswer answer =
        HandleModbusFrame(request.data(), request.size(), unit, registers.data(), count);
    EXPECT_TRUE(answer.exception);
    EXPECT_FALSE(answer.wrote_command);
    EXPECT_EQ(answer.frame.size(), 9u);
    return answer.frame.size() == 9u ? static_cast<int>(static_cast<std::uint8_t>(answer.frame[8])) : -1;
  };
  // Another unit id than the one served: gateway target (0x0B), not executed.
  EXPECT_EQ(exception_of(Frame(1, 2, {0x06, 0x00, 0x00, 0x00, 0x01}), 1), 0x0B);
  EXPECT_EQ(exception_of(Frame(1, 1, {0x2B, 0x0E, 0x01, 0x00}), std::nullopt), 1);   // function
  EXPECT_EQ(exception_of(Frame(1, 1, {0x03, 0x00, 0x1B, 0x00, 0x02}), std::nullopt), 2);  // past the map
  EXPECT_EQ(exception_of(Frame(1, 1, {0x06, 0x00, 0x00, 0x00}), std::nullopt), 3);  // short PDU
  EXPECT_EQ(exception_of(Frame(1, 1, {0x10, 0x00, 0x00, 0x00, 0x02, 0x04, 0x00, 0x01}),
                         std::nullopt), 3);  // fewer value bytes than announced
  EXPECT_EQ(exception_of(Frame(1, 1, {0x03}), std::nullopt), 3);  // function code alone
  EXPECT_EQ(registers, before);
}

}  // namespace
}  // namespace hnnstereo::robot::modbus
