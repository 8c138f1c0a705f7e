// The Modbus register codec (robot/modbus_registers.h): int32 words high first, fixed-point
// poses, int16 status, and refusal (never wrap) of values that do not fit.
#include "robot/modbus_registers.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>

#include "robot/link.h"

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

}  // namespace
}  // namespace hnnstereo::robot::modbus
