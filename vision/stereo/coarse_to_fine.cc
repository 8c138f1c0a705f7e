#include "vision/stereo/coarse_to_fine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "common/timing.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {
namespace {

constexpr float kNoMatch = std::numeric_limits<float>::max();

// Per coarse pixel, the smallest and largest disparity of the coarse matches within a square of
// half-side h around it (+/-kNoMatch where there is none): the matches' disparities written at
// their left pixels, then a grey erosion (min) and dilation (max) by the square.
struct CoarseSupport {
  std::vector<cv::Mat> low, high;  // per support half-side: CV_32F

  CoarseSupport(const std::vector<StereoMatch>& matches, cv::Size size,
                const std::array<int, 3>& half_sides) {
    cv::Mat low0(size, CV_32F, cv::Scalar(kNoMatch)), high0(size, CV_32F, cv::Scalar(-kNoMatch));
    for (const StereoMatch& m : matches) {
      const int x = static_cast<int>(std::lround(m.left.x()));
      const int y = static_cast<int>(std::lround(m.left.y()));
      if (x < 0 || y < 0 || x >= size.width || y >= size.height) continue;
      const float d = m.left.x() - m.right.x();
      low0.at<float>(y, x) = std::min(low0.at<float>(y, x), d);
      high0.at<float>(y, x) = std::max(high0.at<float>(y, x), d);
    }
    for (int h : half_sides) {
      const cv::Mat square =
          cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * h + 1, 2 * h + 1));
      cv::Mat l, u;
      cv::erode(low0, l, square, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(kNoMatch));
      cv::dilate(high0, u, square, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
                 cv::Scalar(-kNoMatch));
      low.push_back(l);
      high.push_back(u);
    }
  }
};

}  // namespace

std::string CoarseToFineOptions::Check() const {
  if (!(min_megapixels >= 0.0) || !std::isfinite(min_megapixels)) {
    return "coarse-to-fine min_megapixels must be >= 0";
  }
  if (band_margin < 0) return "coarse-to-fine band_margin must be >= 0";
  if (!(coarse_feature_share > 0.0 && coarse_feature_share <= 1.0)) {
    return "coarse-to-fine coarse_feature_share must be in (0, 1]";
  }
  for (int h : support_half_sides) {
    if (h < 0 || h > 256) return "coarse-to-fine support half-sides must be in 0..256";
  }
  return {};
}

bool CoarseToFineApplies(const MatcherOptions& options, cv::Size image_size) {
  const CandidateOptions& c = options.candidates;
  return options.coarse_to_fine.min_megapixels > 0.0 && c.rectified && !c.dense &&
         c.kind == hnn::NetworkKind::kFeatureVsDisparity &&
         static_cast<double>(image_size.area()) > 1e6 * options.coarse_to_fine.min_megapixels &&
         image_size.width >= 64 && image_size.height >= 64;
}

CoarseBands CoarseDisparityBands(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                 const std::vector<Eigen::Vector2f>& left_points,
                                 const MatcherOptions& options, ocl::Runtime* runtime,
                                 CoarseToFineReport* report) {
  const auto start = std::chrono::steady_clock::now();
  // The half-size pair: pixel (i, j) averages full-size pixels 2i..2i+1, 2j..2j+1, so a
  // full-size x is 2 x_coarse + 0.5 and every disparity halves.
  cv::Mat left_half, right_half;
  cv::resize(left_grey, left_half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
  cv::resize(right_grey, right_half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
  MatcherOptions coarse = options;
  coarse.candidates.min_disparity = std::floor(options.candidates.min_disparity / 2.0);
  coarse.candidates.max_disparity = std::ceil(options.candidates.max_disparity / 2.0);
  coarse.min_confidence = 0.0;
  coarse.network_observer = nullptr;
  // The half-size match only has to back the bands: a spread share of the features does.
  const int coarse_cap =
      std::max(1000, static_cast<int>(options.coarse_to_fine.coarse_feature_share *
                                      static_cast<double>(left_points.size())));
  coarse.features.max_features = options.features.max_features > 0
                                     ? std::min(options.features.max_features, coarse_cap)
                                     : coarse_cap;
  MatchReport coarse_match = MatchStereo(left_half, right_half, nullptr, coarse, runtime);
  // Only the coarse matches a reverse search confirms back a band (the sub-pixel fit halves
  // their disparity's rounding error).
  RefinementOptions checked;
  checked.left_right_check = true;
  checked.subpixel = true;
  RefineMatches(left_half, right_half, nullptr, coarse, checked, &coarse_match);

  const CoarseSupport support(coarse_match.matches, left_half.size(),
                              options.coarse_to_fine.support_half_sides);
  const int d_min = static_cast<int>(std::ceil(options.candidates.min_disparity));
  const int d_max = static_cast<int>(std::floor(options.candidates.max_disparity));
  const int margin = options.coarse_to_fine.band_margin;
  CoarseBands bands;
  bands.search.assign(left_points.size(), DisparityBand{d_min, d_max});
  bands.check.assign(left_points.size(), DisparityBand{d_min, d_max});
  auto scaled = [&](float low, float high) {
    return DisparityBand{std::max(d_min, static_cast<int>(std::floor(2.0f * low)) - margin),
                         std::min(d_max, static_cast<int>(std::ceil(2.0f * high)) + margin)};
  };
  double levels_searched = 0.0;
  int whole_range = 0;
  for (std::size_t i = 0; i < left_points.size(); ++i) {
    const int x = std::clamp(static_cast<int>(std::lround((left_points[i].x() - 0.5f) / 2.0f)), 0,
                             left_half.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround((left_points[i].y() - 0.5f) / 2.0f)), 0,
                             left_half.rows - 1);
    bool backed = false;
    for (std::size_t s = 0; s < support.low.size() && !backed; ++s) {
      const float low = support.low[s].at<float>(y, x), high = support.high[s].at<float>(y, x);
      if (low > high) continue;  // no coarse match within this square
      bands.search[i] = scaled(low, high);
      backed = true;
    }
    if (!backed) ++whole_range;
    if (const float low = support.low.back().at<float>(y, x),
        high = support.high.back().at<float>(y, x);
        low <= high) {
      bands.check[i] = scaled(low, high);
    }
    levels_searched += std::max(0, bands.search[i].hi - bands.search[i].lo + 1);
  }
  if (report) {
    report->applied = true;
    report->levels = 1 + coarse_match.coarse_to_fine.levels;
    report->coarse_size = left_half.size();
    report->coarse_matches = static_cast<int>(coarse_match.matches.size());
    report->mean_band_levels =
        left_points.empty() ? 0.0 : levels_searched / static_cast<double>(left_points.size());
    report->features_whole_range = whole_range;
    report->ms = common::MillisecondsSince(start);
  }
  return bands;
}

}  // namespace hnnstereo::vision
