// Images through the project's loader (size and header limits, then cv::imdecode with the codecs'
// complaints captured): any file is an image within the limits or a std::exception (what the CLI turns into one line).
#include <cstddef>
#include <cstdint>
#include <opencv2/imgcodecs.hpp>
#include <exception>

#include "common/input_limits.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = hnnstereo::fuzz::WriteScratch("image", data, size);
  hnnstereo::calib::ImageLimits limits;
  limits.max_pixels = 1 << 22;  // keep each run small; the limit logic is the same
  try {
    const cv::Mat image = hnnstereo::calib::ReadImageFileWithin(path, cv::IMREAD_UNCHANGED, limits);
    if (image.cols < limits.min_side_px || image.rows < limits.min_side_px ||
        static_cast<long long>(image.cols) * image.rows > limits.max_pixels) {
      __builtin_trap();  // an image outside the limits got through
    }
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
