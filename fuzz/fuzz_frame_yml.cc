// FRAME.yml (the robot frame file, robot/frame_io.h) through LoadRobotFrame: a frame that passes
// its own Check() or a std::exception (what the CLI turns into one line).
#include <cstddef>
#include <cstdint>
#include <exception>

#include "fuzz_support.h"
#include "robot/frame_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = hnnstereo::fuzz::WriteScratch("FRAME.yml", data, size);
  try {
    const hnnstereo::robot::RobotFrame frame = hnnstereo::robot::LoadRobotFrame(path);
    if (!frame.Check().empty()) __builtin_trap();  // loaded but not a usable frame
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
