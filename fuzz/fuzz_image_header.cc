// The image header reader that decides, before decoding, whether an image is within the limits
// (PNG, JPEG, BMP, PNM/PAM, TIFF): any bytes, no read outside them, no crash.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/input_limits.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<unsigned char> encoded(data, data + size);
  int width = 0, height = 0;
  hnnstereo::calib::ReadImageHeaderSize(encoded, &width, &height);
  return 0;
}
