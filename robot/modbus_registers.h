#pragma once
// The Modbus TCP register map of the robot link (issue 5; docs/robot_modbus.md) and the pure
// word codec for it: no I/O, no logging. Holding registers, 0-based (PDU) addresses.
//
// Values are signed 32-bit integers, high word first ("big-endian word order", what mbpoll
// shows with -B and most PLCs call a DINT split over two words). The words are built here, not
// with libmodbus 3.1.6's modbus_set_float_*/modbus_get_float_* helpers, which do not
// round-trip on every variant of that release.

#include <array>
#include <cstdint>

#include "robot/pick_command.h"

namespace hnnstereo::robot::modbus {

// Register addresses (0-based).
constexpr int kCommandRegister = 0;          ///< written by the PLC: kCommand*
constexpr int kRequestSequenceRegister = 1;  ///< written by the PLC before a trigger
constexpr int kHeartbeatRegister = 10;       ///< +1 each heartbeat_period, wraps 65535 -> 0
constexpr int kStatusRegister = 11;          ///< kStatus* or a negative LinkErrorCode (int16)
constexpr int kResultSequenceRegister = 12;  ///< request sequence the result answers
constexpr int kPoseCountRegister = 13;       ///< poses in the result
constexpr int kFirstPoseRegister = 20;       ///< pose i starts at 20 + 8 * i
constexpr int kWordsPerPose = 8;             ///< x, y, z, yaw: int32 each, high word first

// Values of the command register (written by the PLC).
constexpr std::uint16_t kCommandNone = 0;
constexpr std::uint16_t kCommandTrigger = 1;
constexpr std::uint16_t kCommandAcknowledge = 2;
constexpr std::uint16_t kCommandStop = 99;

// Values of the status register (written by the vision side); negative: LinkErrorCode.
constexpr int kStatusIdle = 0;
constexpr int kStatusBusy = 1;
constexpr int kStatusResultReady = 2;

// Fixed-point scales of the pose words.
constexpr double kPositionUnitsPerMm = 100.0;  ///< 0.01 mm
constexpr double kYawUnitsPerDegree = 1000.0;  ///< 0.001 degree

/// Holding registers needed for `max_poses` poses: 20 + 8 * max_poses.
constexpr int RegisterCount(int max_poses) { return kFirstPoseRegister + kWordsPerPose * max_poses; }

/// The two words of `value`, high word first.
std::array<std::uint16_t, 2> EncodeInt32(std::int32_t value);
/// Inverse of EncodeInt32.
std::int32_t DecodeInt32(std::uint16_t high, std::uint16_t low);

/// round(value * scale) as int32. Throws std::out_of_range naming `what` when the value is not
/// finite or the scaled value does not fit int32 (never wraps).
std::int32_t ToFixedPoint(double value, double scale, const char* what);

/// A status (0, 1, 2 or a negative LinkErrorCode) as the int16 two's complement word.
/// Throws std::out_of_range outside -32768..32767.
std::uint16_t EncodeStatus(int status);
/// Inverse of EncodeStatus.
int DecodeStatus(std::uint16_t word);

/// The decoded values of one pose block.
struct PoseWords {
  double x_mm = 0.0;
  double y_mm = 0.0;
  double z_mm = 0.0;
  double yaw_deg = 0.0;
};

/// The 8 words of one pose: position_mm (robot base frame) in 0.01 mm and yaw_deg in
/// 0.001 degree. Throws std::out_of_range when a value does not fit (see ToFixedPoint).
std::array<std::uint16_t, kWordsPerPose> EncodePose(const PickCommand& pick);
/// Inverse of EncodePose (up to the fixed-point resolution).
PoseWords DecodePose(const std::uint16_t* words);

}  // namespace hnnstereo::robot::modbus
