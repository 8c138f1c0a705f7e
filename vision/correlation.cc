#include "vision/correlation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

/// Per-pixel window statistics of a CV_8UC1 image as CV_32FC2: the window sum and the inverse
/// of the norm sqrt(sum (I - mean)^2) (the denominator terms of eq. 6.9), from integral images.
/// Sums of 8-bit values and of their squares are integers, held exactly (CV_32S, and CV_64F
/// below 2^53), and so is the variance numerator n * sum I^2 - (sum I)^2 (below 2^33), so a
/// flat window is recognised exactly; it gets an inverse norm of 0, as do pixels whose window
/// leaves the image.
cv::Mat WindowStatistics(const cv::Mat& image, int window) {
  cv::Mat sum, square_sum;
  cv::integral(image, sum, square_sum, CV_32S, CV_64F);
  cv::Mat statistics = cv::Mat::zeros(image.size(), CV_32FC2);
  const int radius = window / 2;
  const double n = static_cast<double>(window) * window;
  for (int y = radius; y < image.rows - radius; ++y) {
    // Integral image row i holds sums over rows [0, i).
    const int* sum_top = sum.ptr<int>(y - radius);
    const int* sum_bottom = sum.ptr<int>(y + radius + 1);
    const double* square_top = square_sum.ptr<double>(y - radius);
    const double* square_bottom = square_sum.ptr<double>(y + radius + 1);
    float* out = statistics.ptr<float>(y);
    for (int x = radius; x < image.cols - radius; ++x) {
      const int left = x - radius;
      const int right = x + radius + 1;
      const auto window_sum = static_cast<double>(sum_bottom[right] - sum_bottom[left] -
                                                  sum_top[right] + sum_top[left]);
      const double window_square_sum =
          square_bottom[right] - square_bottom[left] - square_top[right] + square_top[left];
      const double scaled_variance = n * window_square_sum - window_sum * window_sum;
      out[2 * x] = static_cast<float>(window_sum);
      out[2 * x + 1] =
          scaled_variance > 0.5 ? static_cast<float>(std::sqrt(n / scaled_variance)) : 0.0f;
    }
  }
  return statistics;
}

void CheckImage(const cv::Mat& image, const char* name) {
  if (image.empty() || image.type() != CV_8UC1) {
    throw std::invalid_argument(
        std::string("ZnccMatcher: the ") + name +
        " image must be a non-empty CV_8UC1 grey image (got " +
        (image.empty() ? std::string("empty") : cv::typeToString(image.type())) + ")");
  }
}

/// Sum over the window of left * right, for a window side known at compile time (fully
/// unrolled). Products and partial sums of 8-bit values are integers below 2^24 for windows up to
/// 15 x 15, so float arithmetic is exact here.
template <int kWindow>
float WindowDot(const float* left, std::size_t left_stride, const float* right,
                std::size_t right_stride) {
  // One accumulator per window column: the columns are independent lanes, which the compiler
  // turns into SIMD multiply-adds over whole rows without reordering any sum.
  float column_sums[kWindow] = {};
  for (int dy = 0; dy < kWindow; ++dy) {
    for (int k = 0; k < kWindow; ++k) column_sums[k] += left[k] * right[k];
    left += left_stride;
    right += right_stride;
  }
  float total = 0.0f;
  for (int k = 0; k < kWindow; ++k) total += column_sums[k];
  return total;
}

float WindowDot(int window, const float* left, std::size_t left_stride, const float* right,
                std::size_t right_stride) {
  float total = 0.0f;
  for (int dy = 0; dy < window; ++dy) {
    float row_sum = 0.0f;
    for (int k = 0; k < window; ++k) row_sum += left[k] * right[k];
    total += row_sum;
    left += left_stride;
    right += right_stride;
  }
  return total;
}

}  // namespace

ZnccMatcher::ZnccMatcher(const cv::Mat& left, const cv::Mat& right, int window)
    : window_(window), radius_(window / 2) {
  if (window < 3 || window > 15 || window % 2 == 0) {
    throw std::invalid_argument("ZnccMatcher: window must be odd and in 3..15 (got " +
                                std::to_string(window) + ")");
  }
  CheckImage(left, "left");
  CheckImage(right, "right");
  left.convertTo(left_, CV_32F);
  right.convertTo(right_, CV_32F);
  left_stats_ = WindowStatistics(left, window);
  right_stats_ = WindowStatistics(right, window);
}

float ZnccMatcher::operator()(const Eigen::Vector2f& left_point,
                              const Eigen::Vector2f& right_point) const {
  // Round to the nearest pixel: for x + 1/2 >= radius >= 0, truncation is floor(x + 1/2). The
  // comparisons are false for NaN, so NaN gives 0 as well; no huge float reaches the casts.
  const float left_x = left_point.x() + 0.5f;
  const float left_y = left_point.y() + 0.5f;
  const float right_x = right_point.x() + 0.5f;
  const float right_y = right_point.y() + 0.5f;
  const auto radius = static_cast<float>(radius_);
  if (!(left_x >= radius && left_x < static_cast<float>(left_.cols - radius_) && left_y >= radius &&
        left_y < static_cast<float>(left_.rows - radius_) && right_x >= radius &&
        right_x < static_cast<float>(right_.cols - radius_) && right_y >= radius &&
        right_y < static_cast<float>(right_.rows - radius_))) {
    return 0.0f;
  }
  const int lx = static_cast<int>(left_x);
  const int ly = static_cast<int>(left_y);
  const int rx = static_cast<int>(right_x);
  const int ry = static_cast<int>(right_y);

  const float* left_stats = left_stats_.ptr<float>(ly) + 2 * lx;
  const float* right_stats = right_stats_.ptr<float>(ry) + 2 * rx;
  if (left_stats[1] == 0.0f || right_stats[1] == 0.0f) return 0.0f;  // flat: no evidence

  const std::size_t left_stride = left_.step[0] / sizeof(float);
  const std::size_t right_stride = right_.step[0] / sizeof(float);
  const float* left_corner = left_.ptr<float>(ly - radius_) + (lx - radius_);
  const float* right_corner = right_.ptr<float>(ry - radius_) + (rx - radius_);
  float dot = 0.0f;
  double inverse_n = 0.0;  // 1 / window area, a constant for the thesis's 5 x 5 and 7 x 7
  switch (window_) {
    case 5:
      dot = WindowDot<5>(left_corner, left_stride, right_corner, right_stride);
      inverse_n = 1.0 / 25.0;
      break;
    case 7:
      dot = WindowDot<7>(left_corner, left_stride, right_corner, right_stride);
      inverse_n = 1.0 / 49.0;
      break;
    default:
      dot = WindowDot(window_, left_corner, left_stride, right_corner, right_stride);
      inverse_n = 1.0 / (static_cast<double>(window_) * window_);
      break;
  }

  // ZNCC = sum (L - mean_L)(R - mean_R) / (norm_L norm_R)
  //      = (sum L R - sum L * sum R / n) / (norm_L norm_R)   (eq. 6.9, square root restored).
  // The subtraction is done in double: both terms are large and nearly equal for low-contrast
  // windows, and both are exact there (integers, and a product of two integers below 2^53).
  const double covariance = static_cast<double>(dot) - static_cast<double>(left_stats[0]) *
                                                           static_cast<double>(right_stats[0]) *
                                                           inverse_n;
  const double zncc =
      covariance * static_cast<double>(left_stats[1]) * static_cast<double>(right_stats[1]);
  return static_cast<float>(std::clamp(zncc, -1.0, 1.0));
}

bool ZnccMatcher::RightWindowInside(const Eigen::Vector2f& right_point) const {
  if (!right_point.allFinite()) return false;
  const long x = std::lround(right_point.x()), y = std::lround(right_point.y());
  return x - radius_ >= 0 && y - radius_ >= 0 && x + radius_ < right_.cols &&
         y + radius_ < right_.rows;
}

}  // namespace hnnstereo::vision
