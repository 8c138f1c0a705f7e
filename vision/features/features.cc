#include "vision/features/features.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "vision/features/moravec.h"
#include "vision/features/susan.h"

namespace hnnstereo::vision {
namespace {

/// A detected pixel before the cap.
struct Candidate {
  int x;
  int y;
  float strength;
};

/// Pixels on which features may lie: at least `border_px` from every image border.
struct KeptArea {
  int x_begin, x_end;  // [begin, end)
  int y_begin, y_end;
};

KeptArea AreaInside(const cv::Mat& image, int border_px) {
  return {border_px, image.cols - border_px, border_px, image.rows - border_px};
}

/// Every non-zero pixel of a CV_32F response map inside `area`, in raster order.
std::vector<Candidate> NonZeroResponses(const cv::Mat& response, const KeptArea& area) {
  std::vector<Candidate> candidates;
  for (int y = area.y_begin; y < area.y_end; ++y) {
    const float* row = response.ptr<float>(y);
    for (int x = area.x_begin; x < area.x_end; ++x) {
      if (row[x] > 0.0f) candidates.push_back({x, y, row[x]});
    }
  }
  return candidates;
}

/// L1 magnitude of the 3x3 Sobel gradient at one pixel (border pixels replicated). Canny's own
/// gradient is not returned by cv::Canny; computing it only at edge pixels is much cheaper than
/// a full gradient image.
float SobelL1At(const cv::Mat& grey, int x, int y) {
  const int x0 = std::max(x - 1, 0);
  const int x2 = std::min(x + 1, grey.cols - 1);
  const unsigned char* above = grey.ptr<unsigned char>(std::max(y - 1, 0));
  const unsigned char* row = grey.ptr<unsigned char>(y);
  const unsigned char* below = grey.ptr<unsigned char>(std::min(y + 1, grey.rows - 1));
  const int gx = (above[x2] + 2 * row[x2] + below[x2]) - (above[x0] + 2 * row[x0] + below[x0]);
  const int gy = (below[x0] + 2 * below[x] + below[x2]) - (above[x0] + 2 * above[x] + above[x2]);
  return static_cast<float>(std::abs(gx) + std::abs(gy));
}

std::vector<Candidate> DetectCanny(const cv::Mat& grey, const FeatureOptions& options,
                                   const KeptArea& area) {
  cv::Mat edges;
  cv::Canny(grey, edges, options.canny_low, options.canny_high, options.canny_aperture,
            /*L2gradient=*/false);
  std::vector<Candidate> candidates;
  for (int y = area.y_begin; y < area.y_end; ++y) {
    const unsigned char* row = edges.ptr<unsigned char>(y);
    for (int x = area.x_begin; x < area.x_end; ++x) {
      if (row[x] != 0) candidates.push_back({x, y, SobelL1At(grey, x, y)});
    }
  }
  return candidates;
}

/// Sobel edges: L2 magnitude of the 3x3 Sobel gradient above `sobel_threshold`, thinned by
/// non-maximum suppression along the gradient direction quantised to 0, 45, 90, 135 degrees
/// (as in Canny's first stage, without hysteresis). Equal magnitudes on both sides of a step keep
/// one of the two pixels, so a step edge gives a one-pixel-wide line.
std::vector<Candidate> DetectSobel(const cv::Mat& grey, const FeatureOptions& options,
                                   const KeptArea& area) {
  cv::Mat gradient_x, gradient_y;
  cv::Sobel(grey, gradient_x, CV_16S, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(grey, gradient_y, CV_16S, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Mat magnitude(grey.size(), CV_32F);
  for (int y = 0; y < grey.rows; ++y) {
    const short* gx = gradient_x.ptr<short>(y);
    const short* gy = gradient_y.ptr<short>(y);
    float* out = magnitude.ptr<float>(y);
    for (int x = 0; x < grey.cols; ++x) {
      out[x] = std::sqrt(static_cast<float>(gx[x] * gx[x] + gy[x] * gy[x]));
    }
  }

  constexpr float kTan22 = 0.41421356f;  // tan(22.5 deg)
  constexpr float kTan67 = 2.41421356f;  // tan(67.5 deg)
  const auto threshold = static_cast<float>(options.sobel_threshold);
  std::vector<Candidate> candidates;
  // The suppression reads the 8 neighbours: stay one pixel inside the image.
  for (int y = std::max(area.y_begin, 1); y < std::min(area.y_end, grey.rows - 1); ++y) {
    const short* gx_row = gradient_x.ptr<short>(y);
    const short* gy_row = gradient_y.ptr<short>(y);
    const float* above = magnitude.ptr<float>(y - 1);
    const float* row = magnitude.ptr<float>(y);
    const float* below = magnitude.ptr<float>(y + 1);
    for (int x = std::max(area.x_begin, 1); x < std::min(area.x_end, grey.cols - 1); ++x) {
      const float strength = row[x];
      if (!(strength > threshold)) continue;
      const float abs_gx = std::fabs(static_cast<float>(gx_row[x]));
      const float abs_gy = std::fabs(static_cast<float>(gy_row[x]));
      // The two neighbours across the edge, along the quantised gradient direction.
      float forward = 0.0f;
      float backward = 0.0f;
      if (abs_gy <= kTan22 * abs_gx) {
        forward = row[x + 1];
        backward = row[x - 1];
      } else if (abs_gy >= kTan67 * abs_gx) {
        forward = below[x];
        backward = above[x];
      } else if ((gx_row[x] > 0) == (gy_row[x] > 0)) {
        forward = below[x + 1];
        backward = above[x - 1];
      } else {
        forward = above[x + 1];
        backward = below[x - 1];
      }
      // >= on one side, > on the other: of two equal pixels across the ridge exactly one stays.
      if (strength >= forward && strength > backward) candidates.push_back({x, y, strength});
    }
  }
  return candidates;
}

/// Keeps at most `max_features` candidates spread over the image (grid bucketing). The image is
/// cut into square cells sized so that there are about max_features / kFeaturesPerCell cells;
/// each cell's candidates are ranked by strength (ties: raster order). Round r keeps the r-th
/// strongest of every cell that has one; full rounds are taken while they fit, and the last,
/// partial round keeps the strongest of its candidates (ties: raster order). Deterministic; a
/// cell full of texture cannot starve the rest of the image. Returns a keep flag per candidate.
std::vector<bool> CapSpread(const std::vector<Candidate>& candidates, const cv::Size& image_size,
                            int max_features) {
  const std::size_t count = candidates.size();
  std::vector<bool> keep(count, true);
  if (max_features <= 0 || count <= static_cast<std::size_t>(max_features)) return keep;

  constexpr double kFeaturesPerCell = 4.0;
  const double area = static_cast<double>(image_size.width) * image_size.height;
  const int cell_px =
      std::max(4, static_cast<int>(std::ceil(std::sqrt(area * kFeaturesPerCell / max_features))));
  const int cells_x = (image_size.width + cell_px - 1) / cell_px;
  const int cells_y = (image_size.height + cell_px - 1) / cell_px;
  const int n_cells = cells_x * cells_y;

  // Counting sort of candidate indices by cell (stable: raster order inside a cell).
  std::vector<int> cell_of(count);
  std::vector<int> cell_begin(static_cast<std::size_t>(n_cells) + 1, 0);
  for (std::size_t i = 0; i < count; ++i) {
    cell_of[i] = (candidates[i].y / cell_px) * cells_x + candidates[i].x / cell_px;
    ++cell_begin[static_cast<std::size_t>(cell_of[i]) + 1];
  }
  std::partial_sum(cell_begin.begin(), cell_begin.end(), cell_begin.begin());
  std::vector<int> by_cell(count);
  {
    std::vector<int> next(cell_begin.begin(), cell_begin.end() - 1);
    for (std::size_t i = 0; i < count; ++i) by_cell[next[cell_of[i]]++] = static_cast<int>(i);
  }
  const auto stronger = [&](int a, int b) {
    if (candidates[a].strength != candidates[b].strength) {
      return candidates[a].strength > candidates[b].strength;
    }
    return a < b;  // raster order
  };
  for (int cell = 0; cell < n_cells; ++cell) {
    std::sort(by_cell.begin() + cell_begin[cell], by_cell.begin() + cell_begin[cell + 1], stronger);
  }

  // Rounds: cells_longer_than[r] = number of cells with more than r candidates.
  std::vector<int> cell_size(n_cells);
  int largest_cell = 0;
  for (int cell = 0; cell < n_cells; ++cell) {
    cell_size[cell] = cell_begin[cell + 1] - cell_begin[cell];
    largest_cell = std::max(largest_cell, cell_size[cell]);
  }
  std::vector<int> cells_longer_than(static_cast<std::size_t>(largest_cell) + 1, 0);
  for (const int size : cell_size) {
    for (int r = 0; r < size; ++r) ++cells_longer_than[r];
  }
  int full_rounds = 0;
  long taken = 0;
  while (full_rounds < largest_cell && taken + cells_longer_than[full_rounds] <= max_features) {
    taken += cells_longer_than[full_rounds];
    ++full_rounds;
  }

  std::fill(keep.begin(), keep.end(), false);
  std::vector<int> last_round;
  for (int cell = 0; cell < n_cells; ++cell) {
    const int* ranked = by_cell.data() + cell_begin[cell];
    for (int r = 0; r < std::min(full_rounds, cell_size[cell]); ++r) keep[ranked[r]] = true;
    if (cell_size[cell] > full_rounds) last_round.push_back(ranked[full_rounds]);
  }
  const auto remaining = static_cast<std::size_t>(max_features - taken);
  if (remaining > 0 && !last_round.empty()) {
    const std::size_t n = std::min(remaining, last_round.size());
    std::partial_sort(last_round.begin(), last_round.begin() + static_cast<std::ptrdiff_t>(n),
                      last_round.end(), stronger);
    for (std::size_t i = 0; i < n; ++i) keep[last_round[i]] = true;
  }
  return keep;
}

}  // namespace

std::string_view FeatureDetectorName(FeatureDetector detector) {
  switch (detector) {
    case FeatureDetector::kCanny:
      return "canny";
    case FeatureDetector::kSusanEdge:
      return "susan-edge";
    case FeatureDetector::kSusanCorner:
      return "susan-corner";
    case FeatureDetector::kMoravec:
      return "moravec";
    case FeatureDetector::kSobel:
      return "sobel";
  }
  return "unknown";
}

std::optional<FeatureDetector> ParseFeatureDetector(std::string_view name) {
  for (const FeatureDetector detector :
       {FeatureDetector::kCanny, FeatureDetector::kSusanEdge, FeatureDetector::kSusanCorner,
        FeatureDetector::kMoravec, FeatureDetector::kSobel}) {
    if (name == FeatureDetectorName(detector)) return detector;
  }
  return std::nullopt;
}

std::string FeatureOptions::Check() const {
  std::ostringstream reason;
  // Written as !(a >= b) so that NaN fails too.
  if (!(canny_low >= 0.0) || !(canny_low <= canny_high)) {
    reason << "canny_low must be >= 0 and <= canny_high (got canny_low=" << canny_low
           << ", canny_high=" << canny_high << ")";
  } else if (!std::isfinite(canny_high)) {
    reason << "canny_high must be finite (got " << canny_high << ")";
  } else if (canny_aperture != 3 && canny_aperture != 5 && canny_aperture != 7) {
    reason << "canny_aperture must be 3, 5 or 7 (got " << canny_aperture << ")";
  } else if (susan_brightness_threshold < 1 || susan_brightness_threshold > 255) {
    reason << "susan_brightness_threshold must be in 1..255 grey levels (got "
           << susan_brightness_threshold << ")";
  } else if (moravec_window < 3 || moravec_window > 15 || moravec_window % 2 == 0) {
    reason << "moravec_window must be odd and in 3..15 (got " << moravec_window << ")";
  } else if (!(moravec_threshold >= 0.0) || !std::isfinite(moravec_threshold)) {
    reason << "moravec_threshold must be finite and >= 0 (got " << moravec_threshold << ")";
  } else if (!(sobel_threshold >= 0.0) || !std::isfinite(sobel_threshold)) {
    reason << "sobel_threshold must be finite and >= 0 (got " << sobel_threshold << ")";
  } else if (border_px < 0) {
    reason << "border_px must be >= 0 (got " << border_px << ")";
  } else if (max_features < 0) {
    reason << "max_features must be >= 0, 0 meaning no cap (got " << max_features << ")";
  }
  return reason.str();
}

FeatureReport DetectFeatures(const cv::Mat& grey, const FeatureOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (grey.empty()) {
    throw std::invalid_argument("DetectFeatures: the image is empty");
  }
  if (grey.type() != CV_8UC1) {
    throw std::invalid_argument("DetectFeatures: the image must be CV_8UC1 grey (got " +
                                cv::typeToString(grey.type()) + ")");
  }
  if (const std::string reason = options.Check(); !reason.empty()) {
    throw std::invalid_argument("DetectFeatures: " + reason);
  }

  const KeptArea area = AreaInside(grey, options.border_px);
  std::vector<Candidate> candidates;
  if (area.x_begin < area.x_end && area.y_begin < area.y_end) {
    switch (options.detector) {
      case FeatureDetector::kCanny:
        candidates = DetectCanny(grey, options, area);
        break;
      case FeatureDetector::kSusanEdge:
        candidates =
            NonZeroResponses(SusanEdgeResponse(grey, options.susan_brightness_threshold), area);
        break;
      case FeatureDetector::kSusanCorner:
        candidates =
            NonZeroResponses(SusanCornerResponse(grey, options.susan_brightness_threshold), area);
        break;
      case FeatureDetector::kMoravec:
        candidates = NonZeroResponses(
            MoravecResponse(grey, options.moravec_window, options.moravec_threshold), area);
        break;
      case FeatureDetector::kSobel:
        candidates = DetectSobel(grey, options, area);
        break;
    }
  }

  FeatureReport report;
  report.n_detected = static_cast<int>(candidates.size());
  const std::vector<bool> keep = CapSpread(candidates, grey.size(), options.max_features);
  // Candidates are in raster order (y, then x), so the kept ones are too.
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (!keep[i]) continue;
    report.points.emplace_back(static_cast<float>(candidates[i].x),
                               static_cast<float>(candidates[i].y));
    report.strength.push_back(candidates[i].strength);
  }
  if (options.map_points) options.map_points(grey, &report.points);
  report.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace hnnstereo::vision
