#include "vision/stereo/second_chance.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <unordered_set>

#include <opencv2/core/utility.hpp>

#include "common/point_grid.h"
#include "common/timing.h"
#include "host/decode.h"
#include "host/hopfield_network.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {
namespace {

std::int64_t PixelKey(const Eigen::Vector2f& point) {
  return (static_cast<std::int64_t>(std::lround(point.y())) << 32) +
         static_cast<std::int64_t>(std::lround(point.x()));
}

int RoundedDisparity(const StereoMatch& match) {
  return static_cast<int>(std::lround(match.left.x() - match.right.x()));
}

// The second network's rows: the retried features (their indices in the left features, and the
// matched neighbours backing each), then the matched features that support them.
struct SecondNetworkRows {
  std::vector<int> retried;                // index into the left features
  std::vector<std::vector<int>> backing;   // per retried feature: indices into the matches
  std::vector<int> support;                // indices into the matches, ascending
};

SecondNetworkRows ChooseRows(const std::vector<Eigen::Vector2f>& left_features,
                             const std::vector<StereoMatch>& matches,
                             const SecondChanceOptions& options, int* unmatched) {
  std::unordered_set<std::int64_t> matched_pixels;
  std::vector<Eigen::Vector2f> matched_points(matches.size());
  for (std::size_t m = 0; m < matches.size(); ++m) {
    matched_pixels.insert(PixelKey(matches[m].left));
    matched_points[m] = matches[m].left;
  }
  const hnn::PointGrid grid(matched_points, options.support_radius_px);
  const auto r = static_cast<float>(options.support_radius_px);
  SecondNetworkRows rows;
  std::vector<unsigned char> supports(matches.size(), 0);
  std::vector<int> near;
  *unmatched = 0;
  for (std::size_t i = 0; i < left_features.size(); ++i) {
    const Eigen::Vector2f& p = left_features[i];
    if (matched_pixels.count(PixelKey(p)) != 0) continue;
    ++*unmatched;
    near.clear();
    if (!matches.empty()) {
      for (int cy = grid.CellY(p.y() - r); cy <= grid.CellY(p.y() + r); ++cy) {
        for (std::size_t k = grid.RowBegin(cy, grid.CellX(p.x() - r));
             k < grid.RowEnd(cy, grid.CellX(p.x() + r)); ++k) {
          const int m = grid.items[k];
          if ((matched_points[static_cast<std::size_t>(m)] - p).squaredNorm() <= r * r) {
            near.push_back(m);
          }
        }
      }
    }
    if (static_cast<int>(near.size()) < options.min_support) continue;
    rows.retried.push_back(static_cast<int>(i));
    rows.backing.push_back(near);
    for (int m : near) supports[static_cast<std::size_t>(m)] = 1;
  }
  for (std::size_t m = 0; m < matches.size(); ++m) {
    if (supports[m]) rows.support.push_back(static_cast<int>(m));
  }
  return rows;
}

// One retried feature's candidates: the levels within band_margin of its backing neighbours'
// rounded disparities (inside [d_min, d_max], right window inside the image), the top_k most
// similar, in column order. Returns the band of levels it searched (empty when none).
DisparityBand AppendRetriedCandidates(int row, const Eigen::Vector2f& left_point,
                                      const std::vector<int>& backing,
                                      const std::vector<StereoMatch>& matches,
                                      const ZnccMatcher& similarity,
                                      const SecondChanceOptions& options, int d_min, int d_max,
                                      std::vector<hnn::Candidate>* candidates) {
  std::vector<int> levels;
  for (int m : backing) {
    const int d = RoundedDisparity(matches[static_cast<std::size_t>(m)]);
    for (int level = std::max(d_min, d - options.band_margin);
         level <= std::min(d_max, d + options.band_margin); ++level) {
      levels.push_back(level);
    }
  }
  std::sort(levels.begin(), levels.end());
  levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
  if (levels.empty()) return {};
  const DisparityBand band{levels.front(), levels.back()};
  std::vector<float> profile(static_cast<std::size_t>(band.hi - band.lo + 1));
  similarity.RowProfile(left_point, band.lo, band.hi, profile.data());
  std::vector<hnn::Candidate> row_candidates;
  for (int level : levels) {
    const Eigen::Vector2f right(left_point.x() - static_cast<float>(level), left_point.y());
    if (!similarity.RightWindowInside(right)) continue;
    row_candidates.push_back(
        {row, level - d_min, right, 0.0f, profile[static_cast<std::size_t>(level - band.lo)]});
  }
  if (options.top_k > 0 && static_cast<int>(row_candidates.size()) > options.top_k) {
    std::partial_sort(row_candidates.begin(), row_candidates.begin() + options.top_k,
                      row_candidates.end(), [](const hnn::Candidate& a, const hnn::Candidate& b) {
                        return a.correlation > b.correlation;
                      });
    row_candidates.resize(static_cast<std::size_t>(options.top_k));
    std::sort(row_candidates.begin(), row_candidates.end(),
              [](const hnn::Candidate& a, const hnn::Candidate& b) { return a.column < b.column; });
  }
  candidates->insert(candidates->end(), row_candidates.begin(), row_candidates.end());
  return band;
}

}  // namespace

std::string SecondChanceOptions::Check() const {
  if (!(support_radius_px > 0.0 && std::isfinite(support_radius_px))) {
    return "second-chance support_radius_px must be > 0 (got " + std::to_string(support_radius_px) +
           ")";
  }
  if (min_support < 1) return "second-chance min_support must be >= 1";
  if (band_margin < 0) return "second-chance band_margin must be >= 0";
  if (top_k < 0) return "second-chance top_k must be >= 0";
  if (cpu_below_neurons < 0) return "second-chance cpu_below_neurons must be >= 0";
  if (!(min_model_confidence >= 0.0 && min_model_confidence <= 1.0)) {
    return "second-chance min_model_confidence must be in [0, 1] (got " +
           std::to_string(min_model_confidence) + ")";
  }
  if (!(confidence_scale >= 0.0 && confidence_scale <= 1.0)) {
    return "second-chance confidence_scale must be in [0, 1] (got " +
           std::to_string(confidence_scale) + ")";
  }
  return {};
}

void RetryUnmatchedFeatures(const ZnccMatcher& similarity,
                            const std::vector<Eigen::Vector2f>& left_features,
                            const std::vector<StereoMatch>& matches, const MatcherOptions& matcher,
                            const SecondChanceOptions& options, ocl::Runtime* runtime,
                            std::vector<StereoMatch>* retried_matches,
                            std::vector<DisparityBand>* check_bands, SecondChanceReport* report) {
  const auto start = std::chrono::steady_clock::now();
  retried_matches->clear();
  check_bands->assign(left_features.size(), DisparityBand{});
  *report = SecondChanceReport{};
  report->applied = true;
  const SecondNetworkRows rows = ChooseRows(left_features, matches, options, &report->unmatched);
  report->retried = static_cast<int>(rows.retried.size());
  report->support = static_cast<int>(rows.support.size());
  const int d_min = static_cast<int>(std::ceil(matcher.candidates.min_disparity));
  const int d_max = static_cast<int>(std::floor(matcher.candidates.max_disparity));
  hnn::MatchingProblem problem;
  problem.kind = hnn::NetworkKind::kFeatureVsDisparity;
  problem.n_columns = std::max(0, d_max - d_min + 1);
  // Each retried feature's candidates on OpenCV's thread pool (a row's similarity profile is
  // independent of the others'), then in row order.
  const int n_retried = static_cast<int>(rows.retried.size());
  std::vector<std::vector<hnn::Candidate>> row_candidates(rows.retried.size());
  cv::parallel_for_(cv::Range(0, n_retried), [&](const cv::Range& range) {
    for (int row = range.start; row < range.end; ++row) {
      const auto r = static_cast<std::size_t>(row);
      const auto i = static_cast<std::size_t>(rows.retried[r]);
      (*check_bands)[i] =
          AppendRetriedCandidates(row, left_features[i], rows.backing[r], matches, similarity,
                                  options, d_min, d_max, &row_candidates[r]);
    }
  });
  for (std::size_t row = 0; row < rows.retried.size(); ++row) {
    problem.left_points.push_back(left_features[static_cast<std::size_t>(rows.retried[row])]);
    problem.candidates.insert(problem.candidates.end(), row_candidates[row].begin(),
                              row_candidates[row].end());
  }
  // The support rows: one neuron each, at the match's own (sub-pixel) right point. Alone in its
  // row it has no rival, so it stays on and lends the retried neurons the compatibility of its
  // disparity (eq. 6.11), as the first network's winners lent it to each other.
  for (int m : rows.support) {
    const StereoMatch& match = matches[static_cast<std::size_t>(m)];
    const int row = problem.n_left();
    problem.left_points.push_back(match.left);
    problem.candidates.push_back({row, std::clamp(RoundedDisparity(match), d_min, d_max) - d_min,
                                  match.right, 0.0f, match.correlation});
  }
  report->neurons = problem.n_neurons();
  if (rows.retried.empty() || problem.candidates.empty()) {
    report->ms = common::MillisecondsSince(start);
    return;
  }
  std::string engine_notice;
  hnn::SolveReport solve;
  MatcherOptions solver = matcher;
  if (solver.engine == hnn::EngineKind::kOpenCL &&
      (runtime == nullptr || problem.n_neurons() < options.cpu_below_neurons)) {
    solver.engine = hnn::EngineKind::kCpu;
  }
  report->engine = std::string(EngineName(solver.engine));
  try {
    solve = SolveMatchingNetwork(problem, solver, runtime, &engine_notice);
  } catch (const hnn::MemoryBudgetExceeded&) {
    report->over_memory_budget = true;
    report->ms = common::MillisecondsSince(start);
    return;
  }
  const std::vector<hnn::DecodedMatch> decoded =
      hnn::Decode(problem, solve.activation, matcher.decode, &solve.potential);
  for (StereoMatch& match :
       MatchesWithMargins(problem, decoded, solve.potential, matcher.energy.B)) {
    if (match.left_index >= static_cast<int>(rows.retried.size())) continue;  // a support row
    match.left_index = rows.retried[static_cast<std::size_t>(match.left_index)];
    match.second_chance = true;
    retried_matches->push_back(match);
  }
  report->ms = common::MillisecondsSince(start);
}

int AddSecondChanceMatches(std::vector<StereoMatch> retried, const ConfidenceOptions& confidence,
                           const SecondChanceOptions& options, float scale,
                           std::vector<StereoMatch>* matches) {
  const std::size_t first = matches->size();
  std::vector<StereoMatch> all = *matches;
  all.insert(all.end(), retried.begin(), retried.end());
  CountAgreeingNeighbours(all, scale);
  for (std::size_t k = first; k < all.size(); ++k) {
    StereoMatch& match = all[k];
    const float model = MatchConfidence(match, confidence);
    if (model < options.min_model_confidence) continue;
    match.confidence = static_cast<float>(options.confidence_scale) * model;
    matches->push_back(match);
  }
  return static_cast<int>(matches->size() - first);
}

}  // namespace hnnstereo::vision
