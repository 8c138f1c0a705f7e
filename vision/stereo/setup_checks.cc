// Setup checks run before matching: one image given twice, a swapped rectified pair, a disparity
// range wider than the image (see setup_checks.h for the test and its measured thresholds).
#include "vision/stereo/setup_checks.h"
#include "common/format.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace hnnstereo::vision {
namespace {

using common::Fixed;

// Sum of absolute differences of the block at (x, y) in `left` and (x - shift, y) in `right`.
long BlockSad(const cv::Mat& left, const cv::Mat& right, int x, int y, int shift, int side) {
  long sad = 0;
  for (int r = 0; r < side; ++r) {
    const unsigned char* a = left.ptr<unsigned char>(y + r) + x;
    const unsigned char* b = right.ptr<unsigned char>(y + r) + x - shift;
    for (int c = 0; c < side; ++c) sad += std::abs(static_cast<int>(a[c]) - static_cast<int>(b[c]));
  }
  return sad;
}

}  // namespace

std::string DistinctPairOptions::Check() const {
  if (block_px < 4) return "block_px must be >= 4 (got " + std::to_string(block_px) + ")";
  if (max_shift_px < 1) return "max_shift_px must be >= 1 (got " + std::to_string(max_shift_px) + ")";
  if (!(min_block_stddev_grey >= 0.0)) return "min_block_stddev_grey must be >= 0";
  if (min_textured_blocks < 1) return "min_textured_blocks must be >= 1";
  if (!(max_zero_shift_fraction > 0.0 && max_zero_shift_fraction <= 1.0)) {
    return "max_zero_shift_fraction must be in (0, 1]";
  }
  if (!(min_negative_fraction_for_swap > 0.5 && min_negative_fraction_for_swap <= 1.0)) {
    return "min_negative_fraction_for_swap must be in (0.5, 1]";
  }
  return {};
}

PairComparison ComparePair(const cv::Mat& left_grey, const cv::Mat& right_grey,
                           const DistinctPairOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (auto problem = options.Check(); !problem.empty()) throw std::invalid_argument(problem);
  if (left_grey.empty() || right_grey.empty() || left_grey.type() != CV_8UC1 ||
      right_grey.type() != CV_8UC1 || left_grey.size() != right_grey.size()) {
    throw std::invalid_argument("ComparePair needs two non-empty 8-bit grey images of one size");
  }
  PairComparison result;
  const int width = left_grey.cols, height = left_grey.rows;
  double total_abs = 0.0;
  long identical = 0;
  for (int y = 0; y < height; ++y) {
    const unsigned char* a = left_grey.ptr<unsigned char>(y);
    const unsigned char* b = right_grey.ptr<unsigned char>(y);
    long row_abs = 0;
    for (int x = 0; x < width; ++x) {
      const int d = std::abs(static_cast<int>(a[x]) - static_cast<int>(b[x]));
      row_abs += d;
      identical += d == 0;
    }
    total_abs += static_cast<double>(row_abs);
  }
  const double pixels = static_cast<double>(width) * height;
  result.mean_abs_difference_grey = total_abs / pixels;
  result.identical_pixel_fraction = static_cast<double>(identical) / pixels;

  // Blocks on a grid; a coarser step on large images keeps the test near 2,000 blocks.
  const int side = options.block_px;
  const int shift_limit = std::max(1, std::min(options.max_shift_px, width / 4));
  const int step = std::max(side, static_cast<int>(std::sqrt(pixels / 2000.0)));
  int zero = 0, positive = 0, negative = 0;
  for (int y = 0; y + side <= height; y += step) {
    for (int x = 0; x + side <= width; x += step) {
      double sum = 0.0, sum_sq = 0.0;
      for (int r = 0; r < side; ++r) {
        const unsigned char* a = left_grey.ptr<unsigned char>(y + r) + x;
        for (int c = 0; c < side; ++c) {
          sum += a[c];
          sum_sq += static_cast<double>(a[c]) * a[c];
        }
      }
      const double n = static_cast<double>(side) * side;
      const double variance = sum_sq / n - (sum / n) * (sum / n);
      if (variance < options.min_block_stddev_grey * options.min_block_stddev_grey) continue;
      ++result.textured_blocks;
      // Shift 0 first: ties go to "not moved".
      long best = BlockSad(left_grey, right_grey, x, y, 0, side);
      int best_shift = 0;
      for (int shift = -shift_limit; shift <= shift_limit; ++shift) {
        if (shift == 0 || x - shift < 0 || x - shift + side > width) continue;
        const long sad = BlockSad(left_grey, right_grey, x, y, shift, side);
        if (sad < best) best = sad, best_shift = shift;
      }
      if (best_shift == 0) {
        ++zero;
      } else if (best_shift > 0) {
        ++positive;
      } else {
        ++negative;
      }
    }
  }
  if (result.textured_blocks > 0) {
    result.zero_shift_fraction = static_cast<double>(zero) / result.textured_blocks;
  }
  if (positive + negative > 0) {
    result.positive_shift_fraction = static_cast<double>(positive) / (positive + negative);
    result.negative_shift_fraction = static_cast<double>(negative) / (positive + negative);
  }
  // Identical pixels are one image twice whatever the texture; otherwise the block test decides
  // when it has enough textured blocks to speak.
  const bool enough = result.textured_blocks >= options.min_textured_blocks;
  result.near_identical = result.mean_abs_difference_grey == 0.0 ||
                          (enough && result.zero_shift_fraction >= options.max_zero_shift_fraction);
  result.looks_swapped = enough && !result.near_identical && positive + negative >= options.min_textured_blocks &&
                         result.negative_shift_fraction >= options.min_negative_fraction_for_swap;
  result.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string DistinctViewsProblem(const PairComparison& comparison, const std::string& what) {
  if (!comparison.near_identical) return {};
  if (comparison.mean_abs_difference_grey == 0.0) {
    return what + " are identical (the same pixels): give the two cameras' images";
  }
  return what + " are nearly identical (" + Fixed(100.0 * comparison.zero_shift_fraction, 0) +
         "% of " + std::to_string(comparison.textured_blocks) +
         " textured blocks unmoved, mean difference " +
         Fixed(comparison.mean_abs_difference_grey, 2) + " grey levels): give the two cameras' images";
}

void CheckDistinctViews(const cv::Mat& left_grey, const cv::Mat& right_grey, const std::string& what,
                        const DistinctPairOptions& options) {
  const std::string problem = DistinctViewsProblem(ComparePair(left_grey, right_grey, options), what);
  if (!problem.empty()) throw std::invalid_argument(problem);
}

std::string DisparityRangeProblem(double min_disparity, double max_disparity, int image_width) {
  if (!std::isfinite(min_disparity) || !std::isfinite(max_disparity)) {
    return "--min-disparity/--max-disparity must be finite (got " + Fixed(min_disparity, 1) + ", " +
           Fixed(max_disparity, 1) + ")";
  }
  if (!(min_disparity < max_disparity)) {
    return "--max-disparity " + Fixed(max_disparity, 1) + " must be above --min-disparity " +
           Fixed(min_disparity, 1) + " (the disparity search range)";
  }
  if (image_width > 0) {
    const double limit = image_width - 1;
    if (max_disparity > limit) {
      return "--max-disparity " + Fixed(max_disparity, 1) + " is beyond the image width (" +
             std::to_string(image_width) + " px: at most " + Fixed(limit, 0) + ")";
    }
    if (min_disparity < -limit) {
      return "--min-disparity " + Fixed(min_disparity, 1) + " is beyond the image width (" +
             std::to_string(image_width) + " px: at least " + Fixed(-limit, 0) + ")";
    }
  }
  return {};
}

}  // namespace hnnstereo::vision
