#pragma once
// Image loading at the edge of the system (OpenCV), with clear errors.

#include <opencv2/core.hpp>
#include <string>

#include "common/input_limits.h"

namespace hnnstereo::vision {

/// A loaded image: the original pixels and a grey working copy.
struct LoadedImage {
  std::string path;
  cv::Mat original;  ///< as stored (8/16-bit, grey or colour), for overlays
  cv::Mat grey;      ///< CV_8U single channel (16-bit inputs scaled to 8 bits by their range)
  int bit_depth = 8;
  int channels = 1;
};

/// The limits an image file is held to (file size, header size; defaults documented there).
using ImageLimits = calib::ImageLimits;

/// Loads an image file (PNG, PGM/PPM, JPEG, TIFF...; 8 or 16 bit; grey or colour).
/// Throws std::runtime_error with a one-line reason: missing file, unreadable or empty image, or
/// outside `limits` (checked on the file size and the header before decoding).
LoadedImage LoadImage(const std::string& path, const ImageLimits& limits = {});

/// The CV_8U grey working copy of an image already in memory (8/16-bit, grey, grey + alpha, BGR
/// or BGRA), exactly as LoadImage makes `grey`. Throws std::invalid_argument for an empty image.
cv::Mat GreyWorkingCopy(const cv::Mat& original);

/// Throws std::runtime_error unless both images have the same size (names both sizes).
void CheckSameSize(const LoadedImage& left, const LoadedImage& right);

/// Writes a PNG atomically; throws std::runtime_error naming the path on failure.
void WritePngAtomically(const std::string& path, const cv::Mat& image);

}  // namespace hnnstereo::vision
