// A PFM file (Middlebury 2014 ground truth, vision/middlebury.h) through ReadPfm: a CV_32F /
// CV_32FC3 image no larger than the file's data, or a std::exception (the CLI's one line).
#include <cstddef>
#include <cstdint>
#include <exception>

#include "fuzz_support.h"
#include "vision/middlebury.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = hnnstereo::fuzz::WriteScratch("disp0.pfm", data, size);
  try {
    const cv::Mat image = hnnstereo::vision::ReadPfm(path);
    if (image.empty() || (image.type() != CV_32F && image.type() != CV_32FC3)) __builtin_trap();
    // Every pixel comes from the file: the header must not size the image beyond its data.
    if (image.total() * image.elemSize() > size) __builtin_trap();
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
