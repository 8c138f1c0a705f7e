// A PFM file (Middlebury 2014 ground truth, vision/middlebury.h) through ReadPfm, and as the
// disp0GT.pfm and disp1GT.pfm of a 2014 set (two 4x3 images) through LoadMiddlebury: the
// ground-truth range check, the left-right check, the search range. Accepted: a CV_32F /
// CV_32FC3 image no larger than the file's data, and a pair whose known disparities lie in
// [0, width] inside the search range; refused: a std::exception (the CLI's one line).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <opencv2/imgcodecs.hpp>

#include "fuzz_support.h"
#include "vision/eval/middlebury.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace fuzz = hnnstereo::fuzz;
  static const std::string set = [] {
    const std::filesystem::path folder = fuzz::ScratchFolder() / "set2014";
    std::filesystem::create_directories(folder);
    cv::Mat left(3, 4, CV_8U), right(3, 4, CV_8U);
    for (int i = 0; i < 12; ++i) {
      left.at<std::uint8_t>(i / 4, i % 4) = static_cast<std::uint8_t>(20 * i);
      right.at<std::uint8_t>(i / 4, i % 4) = static_cast<std::uint8_t>(250 - 20 * i);
    }
    cv::imwrite((folder / "im0.png").string(), left);
    cv::imwrite((folder / "im1.png").string(), right);
    return folder.string();
  }();
  const std::string path = fuzz::WriteScratch("set2014/disp0GT.pfm", data, size);
  fuzz::WriteScratch("set2014/disp1GT.pfm", data, size);
  try {
    const cv::Mat image = hnnstereo::vision::ReadPfm(path);
    if (image.empty() || (image.type() != CV_32F && image.type() != CV_32FC3)) __builtin_trap();
    // Every pixel comes from the file: the header must not size the image beyond its data.
    if (image.total() * image.elemSize() > size) __builtin_trap();
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  try {
    const hnnstereo::vision::MiddleburyPair pair = hnnstereo::vision::LoadMiddlebury(set);
    if (pair.disparity.type() != CV_32F || pair.disparity.size() != pair.left_grey.size() ||
        pair.nonoccluded.type() != CV_8U || pair.nonoccluded.size() != pair.disparity.size()) {
      __builtin_trap();
    }
    for (int y = 0; y < pair.disparity.rows; ++y) {
      for (int x = 0; x < pair.disparity.cols; ++x) {
        const float d = pair.disparity.at<float>(y, x);
        if (std::isnan(d)) continue;  // unknown
        if (!(d >= 0.0f && d <= static_cast<float>(pair.disparity.cols)) ||
            d > pair.max_disparity) {
          __builtin_trap();
        }
      }
    }
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
