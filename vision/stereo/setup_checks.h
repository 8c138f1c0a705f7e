#pragma once
// Checks of a stereo setup that run before any matching (milliseconds, not seconds): are the two
// images two views at all (not the same file twice, nor a re-saved or noisy copy), do they look
// swapped, is a disparity range sane for the image width. A fake part sensed from identical
// images would be sent to a robot, so the position-sensing entry points call these too.

#include <opencv2/core.hpp>
#include <string>
#include <utility>

#include "calib/calibration.h"

namespace hnnstereo::vision {

/// How the near-identical and swapped tests look at a pair.
///
/// The pair is cut into blocks; on every textured block of the left image the right image is
/// searched along the row (shifts -max_shift_px..max_shift_px, sum of absolute differences).
/// Two views of a 3D scene displace their texture; a copy of one image (the same file given
/// twice, a re-saved JPEG, a noisy copy) matches best at shift 0 nearly everywhere.
/// Measured (tests/vision/setup_checks_test.cc prints them): share of the textured blocks
/// best at shift 0 - Teddy im2/im6 0.008; rendered cells, seeds 1-5, 0.007-0.024; the same
/// image twice 1.00; copies with Gaussian noise of sigma 1, 3 or 8 grey levels, a 1 px blur or
/// a JPEG at quality 50: 0.99-1.00. Hence the 0.8 threshold. For Teddy given
/// right-left, 0.97 of the moved blocks move the wrong way (0.05 the right way round); the
/// rendered cells' cameras are not side by side along x, so there the sign test stays silent.
struct DistinctPairOptions {
  int block_px = 16;                   ///< block side (px)
  int max_shift_px = 64;               ///< row search range, each way (px; clipped to width / 4)
  double min_block_stddev_grey = 8.0;  ///< a block is textured above this grey-level std. dev.
  int min_textured_blocks = 8;         ///< fewer textured blocks: the test abstains (no verdict)
  /// A pair whose textured blocks match at shift 0 in at least this fraction is one image twice.
  double max_zero_shift_fraction = 0.8;
  /// Swapped: at least this fraction of the textured blocks that moved moved the wrong way
  /// (x_left - x_right < 0). Only meaningful for rectified pairs (epipolar lines = rows).
  double min_negative_fraction_for_swap = 0.7;
  /// "" when valid, else the first problem, naming the field.
  std::string Check() const;
};

/// What the comparison of a pair measured.
struct PairComparison {
  double mean_abs_difference_grey = 0.0;  ///< over all pixels (0 = the same pixels)
  double identical_pixel_fraction = 0.0;  ///< pixels with exactly the same grey level
  int textured_blocks = 0;                ///< blocks above min_block_stddev_grey
  double zero_shift_fraction = 0.0;       ///< of textured blocks, best at shift 0
  double positive_shift_fraction = 0.0;   ///< of moved blocks, best at x_left - x_right > 0
  double negative_shift_fraction = 0.0;   ///< of moved blocks, best at x_left - x_right < 0
  double time_ms = 0.0;
  /// True when the pair is one image twice (identical or a near-identical copy).
  bool near_identical = false;
  /// True when the pair looks like a rectified pair given right-left (see options).
  bool looks_swapped = false;
};

/// Compares two grey images (CV_8U, same size). Throws std::invalid_argument on bad input.
PairComparison ComparePair(const cv::Mat& left_grey, const cv::Mat& right_grey,
                           const DistinctPairOptions& options = {});

/// "" when the compared pair is two views, else the one-line reason ("WHAT are identical ..." or
/// "WHAT are nearly identical (..% of N textured blocks unmoved ...)").
std::string DistinctViewsProblem(const PairComparison& comparison, const std::string& what);

/// Throws std::invalid_argument("left and right images are identical ..." or "... nearly
/// identical ...", one line with the figures) when the pair is one image twice. `what` names the
/// pair in the message (e.g. "--left/--right").
void CheckDistinctViews(const cv::Mat& left_grey, const cv::Mat& right_grey,
                        const std::string& what = "left and right images",
                        const DistinctPairOptions& options = {});

/// "" when [min_disparity, max_disparity] fits an image `image_width` px wide (|d| < width and
/// min <= max, both finite), else a one-line reason naming --min-disparity / --max-disparity.
std::string DisparityRangeProblem(double min_disparity, double max_disparity, int image_width);

}  // namespace hnnstereo::vision
