#pragma once
// The data term: how alike a left and a right window are, in [-1, 1]. Zero-mean normalised
// cross-correlation (ZNCC; thesis eq. 6.9, with the square root the printed equation lost), or
// an aggregated census similarity (DataTermOptions).

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "vision/stereo/lens_distortion.h"

namespace hnnstereo::vision {

/// Which similarity the matcher's candidates, biases, compatibilities and left-right check use
/// (docs/accuracy.md, "The data term").
struct DataTermOptions {
  enum class Kind {
    kZncc,    ///< ZNCC of window x window squares (thesis eq. 6.9)
    kCensus,  ///< census transform, Hamming costs summed over an adaptively weighted square
  };
  Kind kind = Kind::kZncc;
  /// Census: side of the census transform (Zabih & Woodfill 1994): each pixel's code holds one
  /// bit per other pixel of this square, set when that pixel is darker than the centre. 3 or 5.
  int census_window = 5;
  /// Census: side of the square over which the Hamming distances of the two windows' codes are
  /// summed (odd, 1..31).
  int aggregation_window = 13;
  /// Census: adaptive support weights (Yoon & Kweon 2006, grey similarity only): a pixel q of
  /// the aggregation square counts exp(-|I(q) - I(p)| / gamma) of the centre p, in the window's
  /// reference image (the left one; the right one in the reverse search). Grey levels;
  /// 0 = plain box sum.
  double support_gamma = 30.0;
  /// The point route of lens distortion (LensRoute::kPoints): the points asked about are
  /// undistorted pixels, and each window is read from the captured image around the point's
  /// captured pixel (CameraLens::Distort, then rounded as without a lens). The row searches
  /// (RowProfile, ReverseRowProfile) refuse it. Null: the points are the images' own pixels.
  std::shared_ptr<const StereoLens> lens;
  std::string Check() const;
  bool operator==(const DataTermOptions&) const = default;
};

/// "zncc" or "census": the names of `--data-term`, REPORT.json and EVAL.json.
std::string_view DataTermKindName(DataTermOptions::Kind kind);
std::optional<DataTermOptions::Kind> ParseDataTermKind(std::string_view name);

/// Per-pixel statistics of the window x window square centred on each pixel of a CV_8UC1
/// image, as CV_32FC2: the window sum of I and the inverse norm 1 / sqrt(sum (I - mean)^2)
/// (the denominator terms of eq. 6.9). Both come from exact integer sums; a flat window gets
/// an inverse norm of 0, as does every pixel whose window leaves the image (its sum too).
/// `window`: odd, 1..15.
cv::Mat ZnccWindowStatistics(const cv::Mat& image, int window);

/// Precomputes window means and norms of both images so that each ZNCC costs one pass over the
/// window. Windows are square, side 5 or 7 (thesis), centred on the rounded pixel. With a census
/// data term it holds both images' census codes instead, and every similarity below is the
/// census one: s = 1 - 2 sum_q w_q H_q / (bits sum_q w_q), H_q the Hamming distance of the two
/// codes at offset q of the aggregation square, w_q the reference window's support weight;
/// s = 1 for identical codes, -1 for complementary ones. Near a border the square sees the
/// image's edge replicated (as the codes do); a point outside its image gives 0.
class ZnccMatcher {
 public:
  /// `left`, `right`: CV_8U grey images (any sizes). `window`: odd side, 3..15 (ZNCC).
  ZnccMatcher(const cv::Mat& left, const cv::Mat& right, int window,
              const DataTermOptions& data_term = {});

  /// The similarity of the windows centred at the (rounded) points, in [-1, 1]: ZNCC, or the
  /// census similarity with the left window's support weights. A window that leaves either
  /// image, or a flat ZNCC window (zero variance), gives 0 (no evidence either way).
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
  /// (round(right_point.x) + d, round(right_point.y)), right_point), bit for bit; with the census
  /// data term the right window is the reference, so its support weights are used
  /// (ReverseSimilarity).
  void ReverseRowProfile(const Eigen::Vector2f& right_point, int d_min, int d_max,
                         float* out) const;
  /// The census similarity with the right window's support weights (the reverse search's
  /// reference), for the (rounded) points; operator() when the data term is ZNCC.
  float ReverseSimilarity(const Eigen::Vector2f& left_point,
                          const Eigen::Vector2f& right_point) const;

  const DataTermOptions& data_term() const { return data_term_; }

 private:
  // The captured pixel of a point asked about (itself without data_term.lens).
  Eigen::Vector2f InLeftImage(const Eigen::Vector2f& point) const;
  Eigen::Vector2f InRightImage(const Eigen::Vector2f& point) const;
  // Throws std::logic_error naming `what` when data_term.lens is set.
  void RefuseLens(const char* what) const;
  // operator() and ReverseSimilarity at the images' own pixels.
  float ImageSimilarity(const Eigen::Vector2f& left_point, const Eigen::Vector2f& right_point) const;
  float ImageReverseSimilarity(const Eigen::Vector2f& left_point,
                               const Eigen::Vector2f& right_point) const;
  // Window dot products of the fixed window with top-left corner `fixed` against `count`
  // windows of `run` whose top-left corners are run_corner, run_corner + 1, ... (one row).
  void RunDots(const float* fixed, std::size_t fixed_stride, const float* run_corner,
               std::size_t run_stride, int count, float* dots) const;
  // ZNCC from a window dot product and the two windows' statistics (sum, inverse norm).
  float Normalise(float dot, const float* left_stats, const float* right_stats) const;

  // Census. `reference_left`: whose support weights (left: forward, right: reverse search).
  // Pixels (integers) inside their images (the arrays are padded for their squares).
  float CensusSimilarity(int lx, int ly, int rx, int ry, bool reference_left) const;
  // The support weights of the aggregation square centred at (x, y) of `grey`; returns their sum.
  std::int64_t SupportWeights(const cv::Mat& grey, int x, int y, std::uint16_t* weights) const;
  // Census similarities of the fixed square at (fx, fy) of the reference image against the
  // squares of the other image at (ox_first + e, oy), e = 0..count-1 (all inside).
  void CensusRun(bool reference_left, int fx, int fy, int ox_first, int oy, int count,
                 float* similarity) const;
  float CensusFromCost(std::int64_t cost, std::int64_t weight_sum) const;
  void CensusRowProfile(const Eigen::Vector2f& left_point, int d_min, int d_max, float* out) const;

  cv::Mat left_, right_;  // CV_32F copies
  // Per pixel, interleaved so that one call reads one cache line per image: the window sum
  // (an integer, exact in float) and 1 / sqrt(sum (I - mean)^2), 0 for a flat window or one
  // that leaves the image. CV_32FC2.
  cv::Mat left_stats_, right_stats_;
  int window_;
  int radius_;
  DataTermOptions data_term_;
  // Census data term only, padded by the aggregation radius (edges replicated): CV_32S codes
  // and CV_32F grey levels for the support weights.
  cv::Mat left_census_, right_census_, left_support_, right_support_;
  std::array<std::uint16_t, 256> support_lut_{};  // weight of a grey difference, 1..255
  int census_bits_ = 0;
  int aggregation_radius_ = 0;
};

}  // namespace hnnstereo::vision
