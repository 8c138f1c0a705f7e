#pragma once
// Zero-mean normalised cross-correlation (ZNCC) between windows of the two images
// (thesis eq. 6.9, with the square root the printed equation lost): range [-1, 1].

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace hnnstereo::vision {

/// Per-pixel statistics of the window x window square centred on each pixel of a CV_8UC1
/// image, as CV_32FC2: the window sum of I and the inverse norm 1 / sqrt(sum (I - mean)^2)
/// (the denominator terms of eq. 6.9). Both come from exact integer sums; a flat window gets
/// an inverse norm of 0, as does every pixel whose window leaves the image (its sum too).
/// `window`: odd, 1..15.
cv::Mat ZnccWindowStatistics(const cv::Mat& image, int window);

/// Precomputes window means and norms of both images so that each ZNCC costs one pass over the
/// window. Windows are square, side 5 or 7 (thesis), centred on the rounded pixel.
class ZnccMatcher {
 public:
  /// `left`, `right`: CV_8U grey images (any sizes). `window`: odd side, 3..15.
  ZnccMatcher(const cv::Mat& left, const cv::Mat& right, int window);

  /// ZNCC of the windows centred at the (rounded) points, in [-1, 1]. A window that leaves
  /// either image, or a flat window (zero variance), gives 0 (no evidence either way).
  float operator()(const Eigen::Vector2f& left_point, const Eigen::Vector2f& right_point) const;

  int window() const { return window_; }
  /// Width of the right image (px).
  int right_width() const { return right_.cols; }

  /// True when the window centred at the (rounded) right point lies inside the right image.
  bool RightWindowInside(const Eigen::Vector2f& right_point) const;

  /// The ZNCC profile along a row: out[d - d_min] = (*this)(left_point, right point
  /// (left_point.x - d, left_point.y)) for d = d_min..d_max, bit for bit, computed for all
  /// disparities at once (window dot products are integer sums, exact in float in any order,
  /// so the shifted-row accumulation vectorises over d without changing a result).
  void RowProfile(const Eigen::Vector2f& left_point, int d_min, int d_max, float* out) const;
  /// The reverse search of a left-right check: out[d - d_min] = (*this)(left point
  /// (round(right_point.x) + d, round(right_point.y)), right_point), bit for bit.
  void ReverseRowProfile(const Eigen::Vector2f& right_point, int d_min, int d_max,
                         float* out) const;

 private:
  // Window dot products of the fixed window with top-left corner `fixed` against `count`
  // windows of `run` whose top-left corners are run_corner, run_corner + 1, ... (one row).
  void RunDots(const float* fixed, std::size_t fixed_stride, const float* run_corner,
               std::size_t run_stride, int count, float* dots) const;
  // ZNCC from a window dot product and the two windows' statistics (sum, inverse norm).
  float Normalise(float dot, const float* left_stats, const float* right_stats) const;

  cv::Mat left_, right_;  // CV_32F copies
  // Per pixel, interleaved so that one call reads one cache line per image: the window sum
  // (an integer, exact in float) and 1 / sqrt(sum (I - mean)^2), 0 for a flat window or one
  // that leaves the image. CV_32FC2.
  cv::Mat left_stats_, right_stats_;
  int window_;
  int radius_;
};

}  // namespace hnnstereo::vision
