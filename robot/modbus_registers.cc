#include "robot/modbus_registers.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace hnnstereo::robot::modbus {

std::array<std::uint16_t, 2> EncodeInt32(std::int32_t value) {
  // Two's complement bits of the int32, split into words; high word first.
  const auto bits = static_cast<std::uint32_t>(value);
  return {static_cast<std::uint16_t>(bits >> 16), static_cast<std::uint16_t>(bits & 0xFFFFu)};
}

std::int32_t DecodeInt32(std::uint16_t high, std::uint16_t low) {
  const std::uint32_t bits = (static_cast<std::uint32_t>(high) << 16) | low;
  // Conversion of an out-of-range unsigned value to int32 is modular since C++20.
  return static_cast<std::int32_t>(bits);
}

std::int32_t ToFixedPoint(double value, double scale, const char* what) {
  const double scaled = std::round(value * scale);
  constexpr double kLowest = static_cast<double>(std::numeric_limits<std::int32_t>::min());
  constexpr double kHighest = static_cast<double>(std::numeric_limits<std::int32_t>::max());
  if (!std::isfinite(scaled) || scaled < kLowest || scaled > kHighest) {
    throw std::out_of_range(std::string("modbus: ") + what + " = " + std::to_string(value) +
                            " does not fit a signed 32-bit register pair at scale " +
                            std::to_string(scale));
  }
  return static_cast<std::int32_t>(scaled);
}

std::uint16_t EncodeStatus(int status) {
  if (status < std::numeric_limits<std::int16_t>::min() ||
      status > std::numeric_limits<std::int16_t>::max()) {
    throw std::out_of_range("modbus: status " + std::to_string(status) +
                            " does not fit the int16 status register");
  }
  return static_cast<std::uint16_t>(static_cast<std::int16_t>(status));
}

int DecodeStatus(std::uint16_t word) { return static_cast<std::int16_t>(word); }

std::array<std::uint16_t, kWordsPerPose> EncodePose(const PickCommand& pick) {
  const std::int32_t values[4] = {
      ToFixedPoint(pick.position_mm.x(), kPositionUnitsPerMm, "x_mm"),
      ToFixedPoint(pick.position_mm.y(), kPositionUnitsPerMm, "y_mm"),
      ToFixedPoint(pick.position_mm.z(), kPositionUnitsPerMm, "z_mm"),
      ToFixedPoint(pick.yaw_deg, kYawUnitsPerDegree, "yaw_deg")};
  std::array<std::uint16_t, kWordsPerPose> words{};
  for (int i = 0; i < 4; ++i) {
    const auto pair = EncodeInt32(values[i]);
    words[static_cast<std::size_t>(2 * i)] = pair[0];
    words[static_cast<std::size_t>(2 * i + 1)] = pair[1];
  }
  return words;
}

PoseWords DecodePose(const std::uint16_t* words) {
  PoseWords pose;
  pose.x_mm = DecodeInt32(words[0], words[1]) / kPositionUnitsPerMm;
  pose.y_mm = DecodeInt32(words[2], words[3]) / kPositionUnitsPerMm;
  pose.z_mm = DecodeInt32(words[4], words[5]) / kPositionUnitsPerMm;
  pose.yaw_deg = DecodeInt32(words[6], words[7]) / kYawUnitsPerDegree;
  return pose;
}

}  // namespace hnnstereo::robot::modbus
