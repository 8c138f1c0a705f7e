#include "vision/stereo/correlation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "common/cpu_clones.h"

namespace hnnstereo::vision {
namespace {

// ZnccWindowStatistics's rows (the image at least a window wide and high). Box sums by two
// running passes instead of integral images: per column the sums of I and I^2 over the
// window's rows (slid down the image: add the row entering, subtract the one leaving), then
// per row the sum of `window` consecutive column sums. Every value is an integer: I^2 <= 65025,
// so a window's sum of squares is below 225 x 65025 < 2^31 and int32 holds it exactly, as it
// does the column sums, and n sum I^2 - (sum I)^2 < 2^33 is exact in double: the result is the
// one any exact summation gives, bit for bit, and the passes run over whole rows as SIMD
// lanes. Measured on the 718 x 496 pair (Adirondack Q): the ZNCC set-up of both images
// took 5.6 ms with double integral images, 1.6 ms this way, the two images side by side.
void WindowStatisticsKernel(const cv::Mat& image, int window, cv::Mat& statistics) {
  const int radius = window / 2;
  const int rows = image.rows, cols = image.cols;
  const int span = cols - window + 1;  // windows whose centre x = radius .. cols - radius - 1
  const double n = static_cast<double>(window) * window;
  std::vector<std::int32_t> column_sum(static_cast<std::size_t>(cols), 0);
  std::vector<std::int32_t> column_square(static_cast<std::size_t>(cols), 0);
  std::vector<std::int32_t> window_sum(static_cast<std::size_t>(span), 0);
  std::vector<std::int32_t> window_square(static_cast<std::size_t>(span), 0);
  std::int32_t* const cs = column_sum.data();
  std::int32_t* const cq = column_square.data();
  std::int32_t* const ws = window_sum.data();
  std::int32_t* const wq = window_square.data();
  auto add_row = [&](int y, std::int32_t sign) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y);
    for (int x = 0; x < cols; ++x) {
      const std::int32_t v = row[x];
      cs[x] += sign * v;
      cq[x] += sign * v * v;
    }
  };
  for (int y = 0; y < window - 1; ++y) add_row(y, 1);
  for (int y = radius; y < rows - radius; ++y) {
    add_row(y + radius, 1);  // the window's rows are now y - radius .. y + radius
    for (int x = 0; x < span; ++x) {
      ws[x] = cs[x];
      wq[x] = cq[x];
    }
    for (int k = 1; k < window; ++k) {
      for (int x = 0; x < span; ++x) {
        ws[x] += cs[x + k];
        wq[x] += cq[x + k];
      }
    }
    float* out = statistics.ptr<float>(y) + 2 * radius;
    for (int x = 0; x < span; ++x) {
      const auto sum = static_cast<double>(ws[x]);
      const double scaled_variance = n * static_cast<double>(wq[x]) - sum * sum;
      out[2 * x] = static_cast<float>(sum);
      out[2 * x + 1] =
          scaled_variance > 0.5 ? static_cast<float>(std::sqrt(n / scaled_variance)) : 0.0f;
    }
    add_row(y - radius, -1);  // leaves the window before the next row
  }
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

// One bit more of a row of census codes: out = out << 1 | (neighbour < centre). Restricted
// pointers so that it runs as SIMD lanes (through uint8 pointers, which alias anything, it did
// not: 11 % of a 1,000-feature match on Teddy went to this loop scalar).
HNNSTEREO_TARGET_CLONES("avx2", "default")
void CensusBit(std::uint32_t* __restrict out, const std::uint8_t* __restrict neighbour,
               const std::uint8_t* __restrict centre, int cols) {
  for (int x = 0; x < cols; ++x) out[x] = (out[x] << 1) | (neighbour[x] < centre[x] ? 1u : 0u);
}

// Census codes of a CV_8UC1 image (Zabih & Woodfill 1994): per pixel one bit per other pixel of
// the window x window square (row by row), set when that pixel is darker than the centre;
// borders replicated. Written by hand: OpenCV's census lives in the optional contrib modules.
cv::Mat CensusCodes(const cv::Mat& image, int window) {
  const int r = window / 2;
  cv::Mat padded;
  cv::copyMakeBorder(image, padded, r, r, r, r, cv::BORDER_REPLICATE);
  cv::Mat codes = cv::Mat::zeros(image.size(), CV_32S);
  for (int y = 0; y < image.rows; ++y) {
    auto* out = reinterpret_cast<std::uint32_t*>(codes.ptr<std::int32_t>(y));
    const std::uint8_t* centre = padded.ptr<std::uint8_t>(y + r) + r;
    for (int dy = -r; dy <= r; ++dy) {
      const std::uint8_t* row = padded.ptr<std::uint8_t>(y + r + dy) + r;
      for (int dx = -r; dx <= r; ++dx) {
        if (dx == 0 && dy == 0) continue;
        CensusBit(out, row + dx, centre, image.cols);
      }
    }
  }
  return codes;
}

// Weighted Hamming costs of one fixed square of codes (side x side, top-left `fixed`) against
// `count` squares of a row whose top-left corners are run, run + 1, ...: costs[e] =
// sum_q weights[q] popcount(fixed[q] ^ run[q + e]). Integer sums, so any order gives the same
// result; the lanes e run as SIMD lanes.
// One block of kBlock lanes from e0, its sums in registers over the whole square.
template <int kBlock>
__attribute__((always_inline)) inline void CensusBlock(
    int side, const std::uint32_t* fixed, std::size_t fixed_stride, const std::uint32_t* run,
    std::size_t run_stride, const std::uint16_t* weights, int e0, std::int32_t* costs) {
  std::int32_t sum[kBlock] = {};
  for (int qy = 0; qy < side; ++qy) {
    const std::uint32_t* fixed_row = fixed + static_cast<std::size_t>(qy) * fixed_stride;
    const std::uint32_t* run_row = run + static_cast<std::size_t>(qy) * run_stride + e0;
    const std::uint16_t* weight_row = weights + qy * side;
    for (int qx = 0; qx < side; ++qx) {
      const std::int32_t w = weight_row[qx];
      const std::uint32_t c = fixed_row[qx];
      for (int e = 0; e < kBlock; ++e) sum[e] += w * __builtin_popcount(c ^ run_row[qx + e]);
    }
  }
  for (int e = 0; e < kBlock; ++e) costs[e0 + e] = sum[e];
}

__attribute__((always_inline)) inline void CensusRunBody(
    int side, const std::uint32_t* fixed, std::size_t fixed_stride, const std::uint32_t* run,
    std::size_t run_stride, const std::uint16_t* weights, int count, std::int32_t* costs) {
  // Blocks of 32, then 16, then 4 lanes whose sums stay in registers over the whole square (a
  // sum kept in memory made the store of every step the bottleneck), then lane by lane.
  int e0 = 0;
  for (; e0 + 32 <= count; e0 += 32)
    CensusBlock<32>(side, fixed, fixed_stride, run, run_stride, weights, e0, costs);
  for (; e0 + 16 <= count; e0 += 16)
    CensusBlock<16>(side, fixed, fixed_stride, run, run_stride, weights, e0, costs);
  for (; e0 + 4 <= count; e0 += 4)
    CensusBlock<4>(side, fixed, fixed_stride, run, run_stride, weights, e0, costs);
  for (; e0 < count; ++e0)
    CensusBlock<1>(side, fixed, fixed_stride, run, run_stride, weights, e0, costs);
}

using CensusRunFunction = void (*)(int, const std::uint32_t*, std::size_t, const std::uint32_t*,
                                   std::size_t, const std::uint16_t*, int, std::int32_t*);

void CensusRunDefault(int side, const std::uint32_t* fixed, std::size_t fixed_stride,
                      const std::uint32_t* run, std::size_t run_stride,
                      const std::uint16_t* weights, int count, std::int32_t* costs) {
  CensusRunBody(side, fixed, fixed_stride, run, run_stride, weights, count, costs);
}

#if defined(__x86_64__) && defined(__GNUC__)
// The same body built for CPUs with a vector popcount (AVX-512 VPOPCNTDQ: 16 lanes an
// instruction) or a scalar one, picked at run time. (GCC 12's target_clones does not take
// avx512vpopcntdq, so host/cpu_clones.h's macro cannot express it.)
__attribute__((target("avx512f,avx512vpopcntdq"))) void CensusRunVpopcnt(
    int side, const std::uint32_t* fixed, std::size_t fixed_stride, const std::uint32_t* run,
    std::size_t run_stride, const std::uint16_t* weights, int count, std::int32_t* costs) {
  CensusRunBody(side, fixed, fixed_stride, run, run_stride, weights, count, costs);
}
__attribute__((target("popcnt"))) void CensusRunPopcnt(
    int side, const std::uint32_t* fixed, std::size_t fixed_stride, const std::uint32_t* run,
    std::size_t run_stride, const std::uint16_t* weights, int count, std::int32_t* costs) {
  CensusRunBody(side, fixed, fixed_stride, run, run_stride, weights, count, costs);
}
CensusRunFunction PickCensusRun() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512vpopcntdq") && __builtin_cpu_supports("avx512f")) {
    return CensusRunVpopcnt;
  }
  if (__builtin_cpu_supports("popcnt")) return CensusRunPopcnt;
  return CensusRunDefault;
}
#else
CensusRunFunction PickCensusRun() { return CensusRunDefault; }
#endif

void CensusRunKernel(int side, const std::uint32_t* fixed, std::size_t fixed_stride,
                     const std::uint32_t* run, std::size_t run_stride, const std::uint16_t* weights,
                     int count, std::int32_t* costs) {
  static const CensusRunFunction function = PickCensusRun();
  function(side, fixed, fixed_stride, run, run_stride, weights, count, costs);
}

// The pixel a point rounds to (x + 1/2 truncated, as ZnccMatcher::operator() rounds), when it
// lies in the image; false for NaN and points outside.
bool RoundToPixel(const Eigen::Vector2f& point, const cv::Mat& image, int* x, int* y) {
  const float px = point.x() + 0.5f, py = point.y() + 0.5f;
  if (!(px >= 0.0f && px < static_cast<float>(image.cols) && py >= 0.0f &&
        py < static_cast<float>(image.rows))) {
    return false;
  }
  *x = static_cast<int>(px);
  *y = static_cast<int>(py);
  return true;
}

}  // namespace

std::string_view DataTermKindName(DataTermOptions::Kind kind) {
  return kind == DataTermOptions::Kind::kCensus ? "census" : "zncc";
}

std::optional<DataTermOptions::Kind> ParseDataTermKind(std::string_view name) {
  if (name == "zncc") return DataTermOptions::Kind::kZncc;
  if (name == "census") return DataTermOptions::Kind::kCensus;
  return std::nullopt;
}

std::string DataTermOptions::Check() const {
  if (kind == Kind::kZncc) return "";
  if (census_window != 3 && census_window != 5) {
    return "data_term.census_window must be 3 or 5 (got " + std::to_string(census_window) + ")";
  }
  if (aggregation_window < 1 || aggregation_window > 31 || aggregation_window % 2 == 0) {
    return "data_term.aggregation_window must be odd, 1..31 (got " +
           std::to_string(aggregation_window) + ")";
  }
  if (!(support_gamma >= 0.0 && support_gamma <= 1e6)) {
    return "data_term.support_gamma must be in [0, 1e6] grey levels (0 = box)";
  }
  return "";
}

cv::Mat ZnccWindowStatistics(const cv::Mat& image, int window) {
  CheckImage(image, "window statistics");
  if (window < 1 || window > 15 || window % 2 == 0) {
    throw std::invalid_argument("ZnccWindowStatistics: window must be odd and in 1..15 (got " +
                                std::to_string(window) + ")");
  }
  cv::Mat statistics = cv::Mat::zeros(image.size(), CV_32FC2);
  if (image.rows >= window && image.cols >= window) {
    WindowStatisticsKernel(image, window, statistics);
  }
  return statistics;
}

ZnccMatcher::ZnccMatcher(const cv::Mat& left, const cv::Mat& right, int window,
                         const DataTermOptions& data_term)
    : window_(window), radius_(window / 2), data_term_(data_term) {
  if (window < 3 || window > 15 || window % 2 == 0) {
    throw std::invalid_argument("ZnccMatcher: window must be odd and in 3..15 (got " +
                                std::to_string(window) + ")");
  }
  if (std::string problem = data_term.Check(); !problem.empty()) {
    throw std::invalid_argument("ZnccMatcher: " + problem);
  }
  const bool census = data_term.kind == DataTermOptions::Kind::kCensus;
  if (census) {
    census_bits_ = data_term.census_window * data_term.census_window - 1;
    aggregation_radius_ = data_term.aggregation_window / 2;
    for (int k = 0; k < 256; ++k) {
      support_lut_[static_cast<std::size_t>(k)] =
          data_term.support_gamma > 0.0 ? static_cast<std::uint16_t>(std::lround(
                                              255.0 * std::exp(-k / data_term.support_gamma)))
                                        : std::uint16_t{1};
    }
  }
  CheckImage(left, "left");
  CheckImage(right, "right");
  // The two images side by side on OpenCV's thread pool; an exception in either (out of
  // memory) is carried out of the pool and rethrown here.
  std::exception_ptr failed[2];
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& range) {
    for (int side = range.start; side < range.end; ++side) {
      try {
        const cv::Mat& image = side == 0 ? left : right;
        image.convertTo(side == 0 ? left_ : right_, CV_32F);
        if (census) {
          // Codes and grey levels padded by the aggregation radius (edges replicated), so that
          // the square of every pixel of the image is inside the arrays.
          const int h = data_term.aggregation_window / 2;
          cv::copyMakeBorder(CensusCodes(image, data_term.census_window),
                             side == 0 ? left_census_ : right_census_, h, h, h, h,
                             cv::BORDER_REPLICATE);
          cv::copyMakeBorder(side == 0 ? left_ : right_, side == 0 ? left_support_ : right_support_,
                             h, h, h, h, cv::BORDER_REPLICATE);
        } else {
          (side == 0 ? left_stats_ : right_stats_) = ZnccWindowStatistics(image, window);
        }
      } catch (...) {
        failed[side] = std::current_exception();
      }
    }
  });
  for (const std::exception_ptr& error : failed) {
    if (error) std::rethrow_exception(error);
  }
}

std::int64_t ZnccMatcher::SupportWeights(const cv::Mat& grey, int x, int y,
                                         std::uint16_t* weights) const {
  const int h = aggregation_radius_, side = 2 * h + 1;
  const auto centre = static_cast<int>(grey.at<float>(y + h, x + h));  // padded by h
  std::int64_t sum = 0;
  for (int qy = 0; qy < side; ++qy) {
    const float* row = grey.ptr<float>(y + qy) + x;
    for (int qx = 0; qx < side; ++qx) {
      const std::uint16_t w =
          support_lut_[static_cast<std::size_t>(std::abs(static_cast<int>(row[qx]) - centre))];
      weights[qy * side + qx] = w;
      sum += w;
    }
  }
  return sum;
}

float ZnccMatcher::CensusFromCost(std::int64_t cost, std::int64_t weight_sum) const {
  return static_cast<float>(
      1.0 - 2.0 * static_cast<double>(cost) /
                (static_cast<double>(census_bits_) * static_cast<double>(weight_sum)));
}

void ZnccMatcher::CensusRun(bool reference_left, int fx, int fy, int ox_first, int oy, int count,
                            float* similarity) const {
  const int h = aggregation_radius_, side = 2 * h + 1;
  const cv::Mat& reference_codes = reference_left ? left_census_ : right_census_;
  const cv::Mat& other_codes = reference_left ? right_census_ : left_census_;
  thread_local std::vector<std::uint16_t> weights;
  thread_local std::vector<std::int32_t> costs;
  weights.resize(static_cast<std::size_t>(side) * side);
  costs.resize(static_cast<std::size_t>(count));
  const std::int64_t weight_sum =
      SupportWeights(reference_left ? left_support_ : right_support_, fx, fy, weights.data());
  const auto stride = [](const cv::Mat& m) { return m.step[0] / sizeof(std::uint32_t); };
  CensusRunKernel(
      side, reinterpret_cast<const std::uint32_t*>(reference_codes.ptr<std::int32_t>(fy)) + fx,
      stride(reference_codes),
      reinterpret_cast<const std::uint32_t*>(other_codes.ptr<std::int32_t>(oy)) + ox_first,
      stride(other_codes), weights.data(), count, costs.data());
  for (int e = 0; e < count; ++e)
    similarity[e] = CensusFromCost(costs[static_cast<std::size_t>(e)], weight_sum);
}

float ZnccMatcher::CensusSimilarity(int lx, int ly, int rx, int ry, bool reference_left) const {
  float similarity = 0.0f;
  if (reference_left) {
    CensusRun(true, lx, ly, rx, ry, 1, &similarity);
  } else {
    CensusRun(false, rx, ry, lx, ly, 1, &similarity);
  }
  return similarity;
}

Eigen::Vector2f ZnccMatcher::InLeftImage(const Eigen::Vector2f& point) const {
  return data_term_.lens ? data_term_.lens->left.Distort(point.cast<double>()).cast<float>() : point;
}

Eigen::Vector2f ZnccMatcher::InRightImage(const Eigen::Vector2f& point) const {
  return data_term_.lens ? data_term_.lens->right.Distort(point.cast<double>()).cast<float>() : point;
}

void ZnccMatcher::RefuseLens(const char* what) const {
  if (data_term_.lens) {
    std::string message = "ZnccMatcher::";
    message.append(what).append(" searches image rows: not with a lens (data_term.lens)");
    throw std::logic_error(message);
  }
}

float ZnccMatcher::ReverseSimilarity(const Eigen::Vector2f& left_point,
                                     const Eigen::Vector2f& right_point) const {
  return ImageReverseSimilarity(InLeftImage(left_point), InRightImage(right_point));
}

float ZnccMatcher::operator()(const Eigen::Vector2f& left_point,
                              const Eigen::Vector2f& right_point) const {
  return ImageSimilarity(InLeftImage(left_point), InRightImage(right_point));
}

float ZnccMatcher::ImageReverseSimilarity(const Eigen::Vector2f& left_point,
                                          const Eigen::Vector2f& right_point) const {
  if (data_term_.kind != DataTermOptions::Kind::kCensus) return ImageSimilarity(left_point, right_point);
  int lx = 0, ly = 0, rx = 0, ry = 0;
  if (!RoundToPixel(left_point, left_, &lx, &ly) || !RoundToPixel(right_point, right_, &rx, &ry)) {
    return 0.0f;
  }
  return CensusSimilarity(lx, ly, rx, ry, false);
}

float ZnccMatcher::ImageSimilarity(const Eigen::Vector2f& left_point,
                                   const Eigen::Vector2f& right_point) const {
  if (data_term_.kind == DataTermOptions::Kind::kCensus) {
    int lx = 0, ly = 0, rx = 0, ry = 0;
    if (!RoundToPixel(left_point, left_, &lx, &ly) ||
        !RoundToPixel(right_point, right_, &rx, &ry)) {
      return 0.0f;
    }
    return CensusSimilarity(lx, ly, rx, ry, true);
  }
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
  switch (window_) {
    case 5: dot = WindowDot<5>(left_corner, left_stride, right_corner, right_stride); break;
    case 7: dot = WindowDot<7>(left_corner, left_stride, right_corner, right_stride); break;
    default: dot = WindowDot(window_, left_corner, left_stride, right_corner, right_stride); break;
  }
  return Normalise(dot, left_stats, right_stats);
}

float ZnccMatcher::Normalise(float dot, const float* left_stats, const float* right_stats) const {
  const double inverse_n = 1.0 / (static_cast<double>(window_) * window_);
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

namespace {

// Dots of one fixed window against `count` consecutive windows of a row, 16 at a time held in
// two 8-lane vectors (GCC/Clang vector extensions, lowered to whatever the target has) over the
// whole window; the rest one by one. The sums are exact integers, so neither the order nor an
// FMA changes them. Cloned for AVX2 where the CPU has it (host/cpu_clones.h).
typedef float Lanes8 __attribute__((vector_size(32)));
HNNSTEREO_TARGET_CLONES("avx2", "default")
void RunDotsKernel(int window, const float* fixed, std::size_t fixed_stride,
                   const float* run_corner, std::size_t run_stride, int count, float* dots) {
  int e0 = 0;
  for (; e0 + 16 <= count; e0 += 16) {
    Lanes8 low = {}, high = {};
    for (int dy = 0; dy < window; ++dy) {
      const float* fixed_row = fixed + static_cast<std::size_t>(dy) * fixed_stride;
      const float* run_row = run_corner + static_cast<std::size_t>(dy) * run_stride + e0;
      for (int k = 0; k < window; ++k) {
        Lanes8 x_low, x_high;
        std::memcpy(&x_low, run_row + k, sizeof x_low);  // unaligned loads
        std::memcpy(&x_high, run_row + k + 8, sizeof x_high);
        low += fixed_row[k] * x_low;
        high += fixed_row[k] * x_high;
      }
    }
    std::memcpy(dots + e0, &low, sizeof low);
    std::memcpy(dots + e0 + 8, &high, sizeof high);
  }
  for (int e = e0; e < count; ++e) {
    float dot = 0.0f;
    for (int dy = 0; dy < window; ++dy) {
      const float* fixed_row = fixed + static_cast<std::size_t>(dy) * fixed_stride;
      const float* run_row = run_corner + static_cast<std::size_t>(dy) * run_stride + e;
      for (int k = 0; k < window; ++k) dot += fixed_row[k] * run_row[k];
    }
    dots[e] = dot;
  }
}

}  // namespace

void ZnccMatcher::RunDots(const float* fixed, std::size_t fixed_stride, const float* run_corner,
                          std::size_t run_stride, int count, float* dots) const {
  RunDotsKernel(window_, fixed, fixed_stride, run_corner, run_stride, count, dots);
}

void ZnccMatcher::RowProfile(const Eigen::Vector2f& left_point, int d_min, int d_max,
                             float* out) const {
  RefuseLens("RowProfile");
  const int count = d_max - d_min + 1;
  if (count <= 0) return;
  if (data_term_.kind == DataTermOptions::Kind::kCensus) {
    CensusRowProfile(left_point, d_min, d_max, out);
    return;
  }
  // The fast path needs the left window inside and not flat, a right row inside, and the
  // rounded right x to step by exactly one pixel a disparity; anything else (and every
  // disparity whose right window leaves the image) is computed one by one.
  auto one_by_one = [&](int d) {
    out[d - d_min] = (*this)(left_point, Eigen::Vector2f(left_point.x() - static_cast<float>(d),
                                                          left_point.y()));
  };
  const float left_x = left_point.x() + 0.5f, left_y = left_point.y() + 0.5f;
  const auto radius = static_cast<float>(radius_);
  const bool left_inside = left_x >= radius && left_x < static_cast<float>(left_.cols - radius_) &&
                           left_y >= radius && left_y < static_cast<float>(left_.rows - radius_) &&
                           left_y < static_cast<float>(right_.rows - radius_);
  if (!left_inside) {
    for (int d = d_min; d <= d_max; ++d) one_by_one(d);
    return;
  }
  const int lx = static_cast<int>(left_x), ly = static_cast<int>(left_y);
  const float* left_stats = left_stats_.ptr<float>(ly) + 2 * lx;
  // The disparities whose rounded right x is rx(d_first) - (d - d_first), window inside.
  auto right_x_of = [&](int d) { return left_point.x() - static_cast<float>(d) + 0.5f; };
  int d_first = d_min;
  while (d_first <= d_max && !(right_x_of(d_first) >= radius &&
                               right_x_of(d_first) < static_cast<float>(right_.cols - radius_))) {
    one_by_one(d_first++);
  }
  if (d_first > d_max) return;
  const int rx_first = static_cast<int>(right_x_of(d_first));
  int d_last = d_first;
  while (d_last + 1 <= d_max && right_x_of(d_last + 1) >= radius &&
         static_cast<int>(right_x_of(d_last + 1)) == rx_first - (d_last + 1 - d_first)) {
    ++d_last;
  }
  for (int d = d_last + 1; d <= d_max; ++d) one_by_one(d);
  if (left_stats[1] == 0.0f) {
    for (int d = d_first; d <= d_last; ++d) out[d - d_min] = 0.0f;  // flat: no evidence
    return;
  }
  const int run = d_last - d_first + 1;
  const int rx_low = rx_first - (run - 1);  // the right x of d_last
  thread_local std::vector<float> dots;
  dots.resize(static_cast<std::size_t>(run));
  RunDots(left_.ptr<float>(ly - radius_) + (lx - radius_), left_.step[0] / sizeof(float),
          right_.ptr<float>(ly - radius_) + (rx_low - radius_), right_.step[0] / sizeof(float), run,
          dots.data());
  const float* right_stats_row = right_stats_.ptr<float>(ly);
  for (int d = d_first; d <= d_last; ++d) {
    const int rx = rx_first - (d - d_first);
    const float* right_stats = right_stats_row + 2 * rx;
    out[d - d_min] = right_stats[1] == 0.0f
                         ? 0.0f
                         : Normalise(dots[static_cast<std::size_t>(rx - rx_low)], left_stats, right_stats);
  }
}

void ZnccMatcher::CensusRowProfile(const Eigen::Vector2f& left_point, int d_min, int d_max,
                                   float* out) const {
  // Each disparity's right pixel as operator() rounds it; the disparities whose squares lie
  // inside and whose right x steps down by one pixel form runs, each one kernel call (the same
  // integer costs operator() computes, so the same floats); the rest are 0 (outside).
  int lx = 0, ly = 0;
  const bool left_inside = RoundToPixel(left_point, left_, &lx, &ly);
  const auto right_pixel = [&](int level, int* x, int* y) {
    return left_inside &&
           RoundToPixel(Eigen::Vector2f(left_point.x() - static_cast<float>(level), left_point.y()),
                        right_, x, y);
  };
  thread_local std::vector<float> run_similarity;
  int d = d_min;
  while (d <= d_max) {
    int rx = 0, ry = 0;
    if (!right_pixel(d, &rx, &ry)) {
      out[d - d_min] = 0.0f;
      ++d;
      continue;
    }
    int last = d, x = 0, y = 0;
    while (last + 1 <= d_max && right_pixel(last + 1, &x, &y) && y == ry &&
           x == rx - (last + 1 - d))
      ++last;
    const int run = last - d + 1;
    run_similarity.resize(static_cast<std::size_t>(run));
    const int x_low = rx - (run - 1);  // the right x of `last`
    CensusRun(true, lx, ly, x_low, ry, run, run_similarity.data());
    for (int k = d; k <= last; ++k) {
      out[k - d_min] = run_similarity[static_cast<std::size_t>(rx - (k - d) - x_low)];
    }
    d = last + 1;
  }
}

void ZnccMatcher::ReverseRowProfile(const Eigen::Vector2f& right_point, int d_min, int d_max,
                                    float* out) const {
  RefuseLens("ReverseRowProfile");
  const int count = d_max - d_min + 1;
  if (count <= 0) return;
  if (data_term_.kind == DataTermOptions::Kind::kCensus) {
    // Left points (x0 + d, y0): integers, so they round to themselves; the ones whose square
    // lies inside are one run of consecutive x, one kernel call with the right square fixed.
    const float x0 = std::round(right_point.x()), y0 = std::round(right_point.y());
    int rx = 0, ry = 0;
    const bool right_inside =
        RoundToPixel(right_point, right_, &rx, &ry) && std::abs(x0) < 1e6f && std::abs(y0) < 1e6f;
    const int ly = right_inside ? static_cast<int>(y0) : 0;
    const int x_base = right_inside ? static_cast<int>(x0) : 0;
    int d_first = d_max + 1, d_last = d_min - 1;
    if (right_inside && ly >= 0 && ly < left_.rows) {
      d_first = std::max(d_min, -x_base);
      d_last = std::min(d_max, left_.cols - 1 - x_base);
    }
    for (int d = d_min; d <= d_max; ++d) {
      if (d < d_first || d > d_last) {
        out[d - d_min] =
            ReverseSimilarity(Eigen::Vector2f(x0 + static_cast<float>(d), y0), right_point);
      }
    }
    if (d_first <= d_last)
      CensusRun(false, rx, ry, x_base + d_first, ly, d_last - d_first + 1, out + (d_first - d_min));
    return;
  }
  const float x0 = std::round(right_point.x()), y0 = std::round(right_point.y());
  auto one_by_one = [&](int d) {
    out[d - d_min] = (*this)(Eigen::Vector2f(x0 + static_cast<float>(d), y0), right_point);
  };
  const float right_x = right_point.x() + 0.5f, right_y = right_point.y() + 0.5f;
  const auto radius = static_cast<float>(radius_);
  // The left point (x0 + d, y0) rounds to itself (integers), and y0 to the right point's row
  // exactly when right_y truncates to y0 (not so for a NaN or for x.5 ties rounded the other
  // way): then the left windows of a run of d are consecutive.
  const bool right_inside = right_x >= radius &&
                            right_x < static_cast<float>(right_.cols - radius_) &&
                            right_y >= radius && right_y < static_cast<float>(right_.rows - radius_) &&
                            y0 + 0.5f >= radius && y0 + 0.5f < static_cast<float>(left_.rows - radius_) &&
                            static_cast<int>(right_y) == static_cast<int>(y0 + 0.5f) &&
                            std::abs(x0) < 1e6f;
  if (!right_inside) {
    for (int d = d_min; d <= d_max; ++d) one_by_one(d);
    return;
  }
  const int rx = static_cast<int>(right_x), ry = static_cast<int>(right_y);
  const float* right_stats = right_stats_.ptr<float>(ry) + 2 * rx;
  // Left x = x0 + d (an integer): inside for radius <= x < cols - radius.
  const int x_base = static_cast<int>(x0);
  const int d_first = std::max(d_min, radius_ - x_base);
  const int d_last = std::min(d_max, left_.cols - radius_ - 1 - x_base);
  for (int d = d_min; d <= d_max; ++d) {
    if (d < d_first || d > d_last) one_by_one(d);
  }
  if (d_first > d_last) return;
  if (right_stats[1] == 0.0f) {
    for (int d = d_first; d <= d_last; ++d) out[d - d_min] = 0.0f;  // flat: no evidence
    return;
  }
  const int run = d_last - d_first + 1;
  thread_local std::vector<float> dots;
  dots.resize(static_cast<std::size_t>(run));
  RunDots(right_.ptr<float>(ry - radius_) + (rx - radius_), right_.step[0] / sizeof(float),
          left_.ptr<float>(ry - radius_) + (x_base + d_first - radius_), left_.step[0] / sizeof(float),
          run, dots.data());
  const float* left_stats_row = left_stats_.ptr<float>(ry);
  for (int d = d_first; d <= d_last; ++d) {
    const float* left_stats = left_stats_row + 2 * (x_base + d);
    out[d - d_min] = left_stats[1] == 0.0f
                         ? 0.0f
                         : Normalise(dots[static_cast<std::size_t>(d - d_first)], left_stats, right_stats);
  }
}

bool ZnccMatcher::RightWindowInside(const Eigen::Vector2f& right_point) const {
  if (!right_point.allFinite()) return false;
  const long x = std::lround(right_point.x()), y = std::lround(right_point.y());
  return x - radius_ >= 0 && y - radius_ >= 0 && x + radius_ < right_.cols &&
         y + radius_ < right_.rows;
}

}  // namespace hnnstereo::vision
