// SUSAN edges and corners, written by hand after Smith & Brady (IJCV 1997) and the authors'
// reference program susan2l.c, because OpenCV has no SUSAN detector.
//
// Every pixel (the nucleus) is compared with the pixels of a circular mask around it through the
// smooth similarity c(r, r0) = exp(-((I(r) - I(r0)) / t)^6) (paper eq. 4). Their sum n(r0) is the
// USAN area (eq. 2). A pixel is an edge (corner) candidate when n falls below the geometric
// threshold g = 3/4 n_max (1/2 n_max), with response R = g - n (eq. 3).

#include "vision/features/susan.h"

#include <array>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

namespace hnnstereo::vision {
namespace {

struct MaskOffset {
  int dx;
  int dy;
};

/// The 37-pixel mask: rows dy = -3..3 span |dx| <= 1, 2, 3, 3, 3, 2, 1.
constexpr std::array<MaskOffset, kSusanMaskPixels> MakeMask() {
  std::array<MaskOffset, kSusanMaskPixels> mask{};
  constexpr int kHalfWidth[7] = {1, 2, 3, 3, 3, 2, 1};
  int k = 0;
  for (int dy = -3; dy <= 3; ++dy) {
    const int half_width = kHalfWidth[dy + 3];
    for (int dx = -half_width; dx <= half_width; ++dx) mask[k++] = {dx, dy};
  }
  return mask;
}
constexpr std::array<MaskOffset, kSusanMaskPixels> kMask = MakeMask();

// n_max for this mask: the USAN of a flat region is the whole mask, nucleus included (c = 1).
constexpr float kNMax = static_cast<float>(kSusanMaskPixels);

/// c(I - I0) for every brightness difference -255..255 (eq. 4), indexed by difference + 255.
std::array<float, 511> SimilarityTable(int brightness_threshold) {
  std::array<float, 511> table{};
  const double t = brightness_threshold;
  for (int difference = -255; difference <= 255; ++difference) {
    const double ratio = difference / t;
    const double ratio2 = ratio * ratio;
    table[difference + 255] = static_cast<float>(std::exp(-ratio2 * ratio2 * ratio2));
  }
  return table;
}

void CheckGrey(const cv::Mat& grey, int brightness_threshold) {
  if (grey.empty() || grey.type() != CV_8UC1) {
    throw std::invalid_argument("SUSAN needs a non-empty CV_8UC1 image");
  }
  if (brightness_threshold < 1 || brightness_threshold > 255) {
    throw std::invalid_argument("SUSAN brightness threshold must be in 1..255 (got " +
                                std::to_string(brightness_threshold) + ")");
  }
}

/// Mask offsets turned into pointer offsets for images with row step `step` (bytes).
std::array<std::ptrdiff_t, kSusanMaskPixels> PointerOffsets(std::size_t step) {
  std::array<std::ptrdiff_t, kSusanMaskPixels> offsets{};
  for (int k = 0; k < kSusanMaskPixels; ++k) {
    offsets[k] =
        static_cast<std::ptrdiff_t>(kMask[k].dy) * static_cast<std::ptrdiff_t>(step) + kMask[k].dx;
  }
  return offsets;
}

/// R = g - n where n < g, else 0, at every pixel whose mask lies inside the image (eq. 2-3).
cv::Mat UsanResponse(const cv::Mat& grey, const std::array<float, 511>& similarity,
                     float geometric_threshold) {
  cv::Mat response = cv::Mat::zeros(grey.size(), CV_32F);
  const auto offsets = PointerOffsets(grey.step);
  const float* table = similarity.data() + 255;  // table[d] for d in -255..255
  for (int y = kSusanMaskRadius; y < grey.rows - kSusanMaskRadius; ++y) {
    const unsigned char* row = grey.ptr<unsigned char>(y);
    float* response_row = response.ptr<float>(y);
    for (int x = kSusanMaskRadius; x < grey.cols - kSusanMaskRadius; ++x) {
      const unsigned char* nucleus = row + x;
      const int brightness = *nucleus;
      float usan_area = 0.0f;
      for (const std::ptrdiff_t offset : offsets) usan_area += table[nucleus[offset] - brightness];
      if (usan_area < geometric_threshold) response_row[x] = geometric_threshold - usan_area;
    }
  }
  return response;
}

/// USAN moments about the nucleus at (x, y): area n, first moments (centre of gravity times n)
/// and second moments, all weighted by c.
struct UsanMoments {
  float area = 0.0f;
  float sum_dx = 0.0f, sum_dy = 0.0f;
  float sum_dx2 = 0.0f, sum_dy2 = 0.0f, sum_dxdy = 0.0f;
};

UsanMoments Moments(const cv::Mat& grey, int x, int y, const std::array<float, 511>& similarity) {
  UsanMoments moments;
  const int brightness = grey.at<unsigned char>(y, x);
  for (const MaskOffset& offset : kMask) {
    const float c =
        similarity[grey.at<unsigned char>(y + offset.dy, x + offset.dx) - brightness + 255];
    const auto dx = static_cast<float>(offset.dx);
    const auto dy = static_cast<float>(offset.dy);
    moments.area += c;
    moments.sum_dx += c * dx;
    moments.sum_dy += c * dy;
    moments.sum_dx2 += c * dx * dx;
    moments.sum_dy2 += c * dy * dy;
    moments.sum_dxdy += c * dx * dy;
  }
  return moments;
}

}  // namespace

cv::Mat SusanEdgeResponse(const cv::Mat& grey, int brightness_threshold) {
  CheckGrey(grey, brightness_threshold);
  const auto similarity = SimilarityTable(brightness_threshold);
  const cv::Mat response = UsanResponse(grey, similarity, 0.75f * kNMax);

  // Non-maximum suppression across the edge (paper section 3.2 and susan2l.c). The edge direction
  // comes from the USAN: in the inter-pixel case (USAN bigger than the mask's diameter and its
  // centre of gravity more than ~1 pixel from the nucleus) the edge normal points from the
  // nucleus to the centre of gravity; otherwise (intra-pixel case, e.g. a thin line) the edge
  // runs along the USAN's longer second-moment axis. The normal is quantised to 4 directions and
  // R must beat its neighbours at distance 1 and 2 along it (strict on one side, so that a
  // two-pixel-wide plateau of equal R keeps exactly one pixel).
  cv::Mat thinned = cv::Mat::zeros(grey.size(), CV_32F);
  constexpr int kMargin = kSusanMaskRadius;  // neighbours at +-2 stay inside the response map
  for (int y = kMargin; y < grey.rows - kMargin; ++y) {
    const float* response_row = response.ptr<float>(y);
    for (int x = kMargin; x < grey.cols - kMargin; ++x) {
      const float strength = response_row[x];
      if (strength <= 0.0f) continue;
      const UsanMoments moments = Moments(grey, x, y, similarity);
      int normal_x = 0;  // (normal_x, normal_y): step across the edge
      int normal_y = 0;
      const float gravity_norm = std::hypot(moments.sum_dx, moments.sum_dy);
      if (moments.area > 6.0f && gravity_norm > 0.9f * moments.area) {
        // Inter-pixel case: normal along the centre of gravity's direction.
        const float slope = moments.sum_dx == 0.0f ? 1e6f : moments.sum_dy / moments.sum_dx;
        const float abs_slope = std::fabs(slope);
        if (abs_slope < 0.5f) {
          normal_x = 1;  // vertical edge
        } else if (abs_slope > 2.0f) {
          normal_y = 1;  // horizontal edge
        } else {
          normal_x = 1;
          normal_y = slope > 0.0f ? 1 : -1;
        }
      } else {
        // Intra-pixel case: the edge runs along the larger second moment, the normal across it.
        const float ratio = moments.sum_dy2 == 0.0f ? 1e6f : moments.sum_dx2 / moments.sum_dy2;
        if (ratio < 0.5f) {
          normal_x = 1;  // USAN elongated vertically: vertical edge
        } else if (ratio > 2.0f) {
          normal_y = 1;
        } else {
          // USAN elongated along (1, 1) when sum dx dy > 0: the normal is (1, -1).
          normal_x = 1;
          normal_y = moments.sum_dxdy > 0.0f ? -1 : 1;
        }
      }
      const auto at = [&](int k) { return response.at<float>(y + k * normal_y, x + k * normal_x); };
      if (strength > at(1) && strength >= at(-1) && strength > at(2) && strength >= at(-2)) {
        thinned.at<float>(y, x) = strength;
      }
    }
  }
  return thinned;
}

cv::Mat SusanCornerResponse(const cv::Mat& grey, int brightness_threshold) {
  CheckGrey(grey, brightness_threshold);
  const auto similarity = SimilarityTable(brightness_threshold);
  const cv::Mat raw = UsanResponse(grey, similarity, 0.5f * kNMax);

  // False-positive tests (paper section 4): the USAN's centre of gravity must lie away from the
  // nucleus (a thin line or a blurred edge has it near the nucleus), and the USAN must be
  // contiguous towards it: the pixels at 1, 2, 3 steps from the nucleus in that direction must
  // all belong to the USAN (susan2l.c requires their summed similarity above 2.9 of 3).
  constexpr int kMargin = kSusanMaskRadius;
  cv::Mat response = cv::Mat::zeros(grey.size(), CV_32F);
  for (int y = kMargin; y < grey.rows - kMargin; ++y) {
    const float* raw_row = raw.ptr<float>(y);
    for (int x = kMargin; x < grey.cols - kMargin; ++x) {
      if (raw_row[x] <= 0.0f) continue;
      const UsanMoments moments = Moments(grey, x, y, similarity);
      const float gx = moments.sum_dx;
      const float gy = moments.sum_dy;
      if (gx * gx + gy * gy <= 0.5f * moments.area * moments.area) continue;  // |cog| <= 0.71 px
      const int brightness = grey.at<unsigned char>(y, x);
      float contiguity = 0.0f;
      for (int step = 1; step <= 3; ++step) {
        int px = x;
        int py = y;
        if (std::fabs(gy) < std::fabs(gx)) {
          px += gx > 0.0f ? step : -step;
          py += static_cast<int>(std::lround(static_cast<float>(step) * gy / std::fabs(gx)));
        } else {
          py += gy > 0.0f ? step : -step;
          px += static_cast<int>(std::lround(static_cast<float>(step) * gx / std::fabs(gy)));
        }
        contiguity += similarity[grey.at<unsigned char>(py, px) - brightness + 255];
      }
      if (contiguity > 2.9f) response.at<float>(y, x) = raw_row[x];
    }
  }

  // 7x7 non-maximum suppression; equal responses go to the first in raster order.
  constexpr int kRadius = 3;
  cv::Mat corners = cv::Mat::zeros(grey.size(), CV_32F);
  for (int y = kMargin; y < grey.rows - kMargin; ++y) {
    for (int x = kMargin; x < grey.cols - kMargin; ++x) {
      const float strength = response.at<float>(y, x);
      if (strength <= 0.0f) continue;
      bool is_maximum = true;
      for (int dy = -kRadius; dy <= kRadius && is_maximum; ++dy) {
        const int ny = y + dy;
        if (ny < 0 || ny >= grey.rows) continue;
        const float* row = response.ptr<float>(ny);
        for (int dx = -kRadius; dx <= kRadius; ++dx) {
          const int nx = x + dx;
          if ((dx == 0 && dy == 0) || nx < 0 || nx >= grey.cols) continue;
          const bool earlier = dy < 0 || (dy == 0 && dx < 0);
          if (earlier ? row[nx] >= strength : row[nx] > strength) {
            is_maximum = false;
            break;
          }
        }
      }
      if (is_maximum) corners.at<float>(y, x) = strength;
    }
  }
  return corners;
}

}  // namespace hnnstereo::vision
