// CAL.yml (and calib.txt, told apart by content) through LoadCalibration: a usable calibration or
// a std::exception (what the CLI turns into one line).
#include <cstddef>
#include <cstdint>
#include <exception>

#include "calib/calibration.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = hnnstereo::fuzz::WriteScratch("CAL.yml", data, size);
  try {
    const hnnstereo::calib::StereoCalibration calibration = hnnstereo::calib::LoadCalibration(path);
    if (!calibration.Check().empty()) __builtin_trap();  // loaded but not usable
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
