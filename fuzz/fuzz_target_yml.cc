// target.yml of a circle-target folder through LoadTargetDirectory: a checked description or a
// std::exception (what the CLI turns into one line). The two image names it may refer to exist (empty files).
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <exception>

#include "calib/circle_calibration.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool images = [] {
    std::ofstream(hnnstereo::fuzz::ScratchFolder() / "l.png") << "x";
    std::ofstream(hnnstereo::fuzz::ScratchFolder() / "r.png") << "x";
    return true;
  }();
  (void)images;
  hnnstereo::fuzz::WriteScratch("target.yml", data, size);
  try {
    const hnnstereo::calib::TargetDescription target =
        hnnstereo::calib::LoadTargetDirectory(hnnstereo::fuzz::ScratchFolder().string());
    if (!target.Check().empty()) __builtin_trap();
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
