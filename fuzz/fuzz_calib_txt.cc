// Middlebury calib.txt: any text gives a calibration that passes Check() or a std::exception (what the CLI turns into one line).
#include <cstddef>
#include <cstdint>
#include <exception>

#include "calib/calibration.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const hnnstereo::calib::StereoCalibration calibration =
        hnnstereo::calib::ParseMiddleburyCalib(hnnstereo::fuzz::AsText(data, size));
    calibration.Check();
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
