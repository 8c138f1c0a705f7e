#include "common/image.h"

#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/atomic_file.h"

namespace hnnstereo::vision {
namespace {

std::string SizeText(const cv::Mat& image) {
  return std::to_string(image.cols) + "x" + std::to_string(image.rows);
}

int BitDepth(int depth) {
  switch (depth) {
    case CV_8U:
    case CV_8S:
      return 8;
    case CV_16U:
    case CV_16S:
    case CV_16F:
      return 16;
    case CV_32S:
    case CV_32F:
      return 32;
    default:
      return 64;
  }
}

/// One channel at the original depth: colour goes through the usual luma weights (BGR order, as
/// cv::imread gives it); an alpha channel is ignored.
cv::Mat ToSingleChannel(const cv::Mat& original) {
  cv::Mat single;
  switch (original.channels()) {
    case 1:
      single = original;
      break;
    case 2:  // grey + alpha
      cv::extractChannel(original, single, 0);
      break;
    case 3:
      cv::cvtColor(original, single, cv::COLOR_BGR2GRAY);
      break;
    default:  // 4: BGRA
      cv::cvtColor(original, single, cv::COLOR_BGRA2GRAY);
      break;
  }
  return single;
}

/// CV_8U working copy. 8-bit data is kept as is; any other depth (16-bit PNG/TIFF, float TIFF) is
/// stretched linearly so that its own min..max range maps to 0..255, which keeps the contrast of
/// a 12-bit camera image stored in 16 bits. A flat image maps to 0.
cv::Mat ToGrey8(const cv::Mat& single) {
  if (single.depth() == CV_8U) return single.clone();  // never aliases `original`
  cv::Mat as_double;
  single.convertTo(as_double, CV_64F);
  double min_value = 0.0;
  double max_value = 0.0;
  cv::minMaxLoc(as_double, &min_value, &max_value);
  cv::Mat grey;
  const double range = max_value - min_value;
  const double scale = range > 0.0 ? 255.0 / range : 0.0;
  as_double.convertTo(grey, CV_8U, scale, -min_value * scale);
  return grey;
}

}  // namespace

LoadedImage LoadImage(const std::string& path, const ImageLimits& limits) {
  const cv::Mat original = calib::ReadImageFileWithin(path, cv::IMREAD_UNCHANGED, limits);

  LoadedImage image;
  image.path = path;
  image.original = original;
  image.bit_depth = BitDepth(original.depth());
  image.channels = original.channels();
  image.grey = ToGrey8(ToSingleChannel(original));
  return image;
}

cv::Mat GreyWorkingCopy(const cv::Mat& original) {
  if (original.empty()) throw std::invalid_argument("image is empty (0x0)");
  return ToGrey8(ToSingleChannel(original));
}

void CheckSameSize(const LoadedImage& left, const LoadedImage& right) {
  if (left.grey.size() != right.grey.size()) {
    throw std::runtime_error("left and right images differ in size: left '" + left.path + "' is " +
                             SizeText(left.grey) + ", right '" + right.path + "' is " +
                             SizeText(right.grey));
  }
}

void WritePngAtomically(const std::string& path, const cv::Mat& image) {
  calib::WriteAtomically(path, [&](const std::string& temporary) {
    bool written = false;
    try {
      written = cv::imwrite(temporary, image);
    } catch (const cv::Exception& e) {
      throw std::runtime_error("cannot write image '" + path + "': " + e.err);
    }
    if (!written) throw std::runtime_error("cannot write image '" + path + "'");
  });
}

}  // namespace hnnstereo::vision
