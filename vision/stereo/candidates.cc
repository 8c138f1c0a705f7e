#include "vision/stereo/candidates.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <unordered_map>

#include "calib/epipolar.h"
#include "common/point_grid.h"
#include <opencv2/core/utility.hpp>
#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace hnnstereo::vision {
namespace {

struct Scored {
  int column;
  Eigen::Vector2f right_point;
  float tau;
  float correlation;
};

// Keeps the K best-correlated (ties: smaller tau), then restores column order.
void KeepTopK(std::vector<Scored>* scored, int top_k) {
  if (top_k > 0 && static_cast<int>(scored->size()) > top_k) {
    std::partial_sort(scored->begin(), scored->begin() + top_k, scored->end(),
                      [](const Scored& a, const Scored& b) {
                        return a.correlation != b.correlation ? a.correlation > b.correlation
                                                              : a.tau < b.tau;
                      });
    scored->resize(static_cast<std::size_t>(top_k));
  }
  std::sort(scored->begin(), scored->end(),
            [](const Scored& a, const Scored& b) { return a.column < b.column; });
}

// The signed distance (px) of right point r from the epipolar line of left point l (eq. 6.14;
// `line` normalised so that a x + b y + c is that distance): |y_l - y_r| on a rectified pair,
// infinite where the line is undefined.
float EpipolarDistance(const Eigen::Vector3d& line, const Eigen::Vector2f& l,
                       const Eigen::Vector2f& r, bool rectified) {
  if (rectified) return std::abs(l.y() - r.y());
  if (line.isZero()) return std::numeric_limits<float>::infinity();
  return static_cast<float>(std::abs(line.x() * r.x() + line.y() * r.y() + line.z()));
}

// Whether the pair (l, r), triangulated, lies in front of both cameras within z_range_mm (true
// without a z range). Inhomogeneous linear triangulation (H&Z 12.2 with X_4 = 1) by normal
// equations: the gate runs for every candidate on the epipolar band, so it avoids a 4x4 SVD
// per pair.
bool HeightInRange(const calib::StereoCalibration* calibration, const CandidateOptions& options,
                   const Eigen::Vector2f& l, const Eigen::Vector2f& r) {
  if (!options.z_range_mm || calibration == nullptr) return true;
  const auto& P1 = calibration->P1;
  const auto& P2 = calibration->P2;
  Eigen::Matrix<double, 4, 4> A;
  A.row(0) = l.x() * P1.row(2) - P1.row(0);
  A.row(1) = l.y() * P1.row(2) - P1.row(1);
  A.row(2) = r.x() * P2.row(2) - P2.row(0);
  A.row(3) = r.y() * P2.row(2) - P2.row(1);
  const Eigen::Matrix<double, 4, 3> M = A.leftCols<3>();
  const Eigen::Vector3d X = (M.transpose() * M).ldlt().solve(-M.transpose() * A.col(3));
  if (!X.allFinite()) return false;
  const double depth1 = (P1 * X.homogeneous()).z(), depth2 = (P2 * X.homogeneous()).z();
  if (depth1 * P1.leftCols<3>().determinant() <= 0 || depth2 * P2.leftCols<3>().determinant() <= 0) {
    return false;  // behind a camera
  }
  return X.z() >= options.z_range_mm->first && X.z() <= options.z_range_mm->second;
}

// The right features (indices, sorted) in the cells of `grid` that the band of `line`
// (|a x + b y + c| <= max_distance_px) crosses: per cell column (or row, along the axis the
// line is closer to), the band's extent. A superset of the features within the band, so the
// candidates are those of testing every right feature.
void RightFeaturesInBand(const hnn::PointGrid& grid, const Eigen::Vector3d& line,
                         double max_distance_px, std::vector<int>& found) {
  found.clear();
  const double a = line.x(), b = line.y(), c = line.z();
  if (!(std::abs(a) > 0.0 || std::abs(b) > 0.0) || !line.allFinite()) return;
  const bool by_column = std::abs(b) >= std::abs(a);
  const double along = by_column ? b : a, across = by_column ? a : b;
  const double half = max_distance_px / std::abs(along) + 1e-3;
  const int n_slices = by_column ? grid.nx : grid.ny, n_other = by_column ? grid.ny : grid.nx;
  const double origin = by_column ? grid.x0 : grid.y0, other_origin = by_column ? grid.y0 : grid.x0;
  for (int s = 0; s < n_slices; ++s) {
    const double u0 = origin + s * grid.cell, u1 = u0 + grid.cell;
    const double v0 = -(across * u0 + c) / along, v1 = -(across * u1 + c) / along;
    const double low = (std::min(v0, v1) - half - other_origin) / grid.cell;
    const double high = (std::max(v0, v1) + half - other_origin) / grid.cell;
    if (high < 0.0 || low > n_other - 1.0 + 1.0) continue;
    const int first = std::max(0, static_cast<int>(std::floor(low)));
    const int last = std::min(n_other - 1, static_cast<int>(std::floor(high)));
    if (by_column) {
      for (int o = first; o <= last; ++o) {
        found.insert(found.end(), grid.items.begin() + static_cast<std::ptrdiff_t>(grid.RowBegin(o, s)),
                     grid.items.begin() + static_cast<std::ptrdiff_t>(grid.RowEnd(o, s)));
      }
    } else {  // cells first..last of row s: one range
      found.insert(found.end(), grid.items.begin() + static_cast<std::ptrdiff_t>(grid.RowBegin(s, first)),
                   grid.items.begin() + static_cast<std::ptrdiff_t>(grid.RowEnd(s, last)));
    }
  }
  std::sort(found.begin(), found.end());
}

// Per-thread scratch space of the candidate sources.
struct Scratch {
  std::vector<Scored> scored;
  std::vector<float> profile;
};

// The feature-vs-disparity network's candidates (thesis code, operation mode 3): columns are
// disparity levels d_min..d_max along the left feature's row; every level above
// min_correlation, or only the ZNCC profile's peaks (zncc_peaks), optionally at the sub-pixel
// vertex of the parabola through the peak and its neighbours (subpixel_peaks).
struct DisparityCandidates {
  const std::vector<Eigen::Vector2f>& left_points;
  const ZnccMatcher& zncc;
  const CandidateOptions& options;
  int d_min, d_max;
  const std::vector<DisparityBand>& bands;  // empty, or one per left feature

  int n_columns() const { return std::max(0, d_max - d_min + 1); }

  // Appends left feature i's candidates to `out` (sorted by column).
  void Append(int i, Scratch& scratch, std::vector<hnn::Candidate>& out,
              std::int64_t& pairs_tested) const {
    const Eigen::Vector2f& l = left_points[static_cast<std::size_t>(i)];
    // The levels searched (lo..hi) and profiled (first..last: one more each side inside the
    // range, so a band's end is a peak only when it beats the level beyond).
    int lo = d_min, hi = d_max;
    if (!bands.empty()) {
      lo = std::max(lo, bands[static_cast<std::size_t>(i)].lo);
      hi = std::min(hi, bands[static_cast<std::size_t>(i)].hi);
      if (lo > hi) return;
    }
    const Levels levels{lo, hi, std::max(d_min, lo - 1), std::min(d_max, hi + 1)};
    std::vector<Scored>& scored = scratch.scored;
    scored.clear();
    // The similarity profile along the row (all disparities at once, vision/correlation.h).
    scratch.profile.resize(static_cast<std::size_t>(levels.last - levels.first + 1));
    zncc.RowProfile(l, levels.first, levels.last, scratch.profile.data());
    pairs_tested += levels.last - levels.first + 1;
    if (!options.zncc_peaks && !options.subpixel_peaks) {
      ScoreAllLevels(l, levels, scratch.profile, &scored);
    } else {
      ScorePeaks(l, levels, &scratch.profile, &scored);
    }
    KeepTopK(&scored, options.top_k);
    for (const Scored& s : scored) out.push_back({i, s.column, s.right_point, s.tau, s.correlation});
  }

 private:
  struct Levels {
    int lo, hi;       // candidates come from these levels
    int first, last;  // the profile's levels (profile[0] is level `first`)
  };

  // Every level whose right window lies in the image and whose ZNCC reaches min_correlation.
  void ScoreAllLevels(const Eigen::Vector2f& l, const Levels& levels,
                      const std::vector<float>& profile, std::vector<Scored>* scored) const {
    for (int d = levels.lo; d <= levels.hi; ++d) {
      const Eigen::Vector2f r(l.x() - static_cast<float>(d), l.y());
      if (!zncc.RightWindowInside(r)) continue;  // no such pixel in the right image
      const float m = profile[static_cast<std::size_t>(d - levels.first)];
      if (m < options.min_correlation) continue;
      scored->push_back({d - d_min, r, 0.0f, m});
    }
  }

  // The profile's peaks (and/or sub-pixel vertices). -2 marks a level whose right window
  // leaves the image: never a candidate. The right x falls as d rises, so the levels inside
  // are one run: only the levels outside it at either end are tested one by one.
  void ScorePeaks(const Eigen::Vector2f& l, const Levels& levels, std::vector<float>* profile_out,
                  std::vector<Scored>* scored) const {
    std::vector<float>& profile = *profile_out;
    auto outside = [&](int d) {
      return !zncc.RightWindowInside(Eigen::Vector2f(l.x() - static_cast<float>(d), l.y()));
    };
    int inside_first = levels.first, inside_last = levels.last;
    while (inside_first <= levels.last && outside(inside_first)) {
      profile[static_cast<std::size_t>(inside_first++ - levels.first)] = -2.0f;
    }
    while (inside_last >= inside_first && outside(inside_last)) {
      profile[static_cast<std::size_t>(inside_last-- - levels.first)] = -2.0f;
    }
    const int n = levels.last - levels.first + 1;
    for (int c = levels.lo - levels.first; c <= levels.hi - levels.first; ++c) {
      const float m = profile[static_cast<std::size_t>(c)];
      if (m < -1.0f || m < options.min_correlation) continue;
      const float before = c > 0 ? profile[static_cast<std::size_t>(c - 1)] : -2.0f;
      const float after = c + 1 < n ? profile[static_cast<std::size_t>(c + 1)] : -2.0f;
      if (options.zncc_peaks && !(m >= before && m >= after)) continue;
      float d = static_cast<float>(c + levels.first);
      if (options.subpixel_peaks && c > 0 && c + 1 < n) {
        // Vertex of the parabola through (d-1, before), (d, m), (d+1, after), in disparity.
        const float curvature = before - 2.0f * m + after;
        if (curvature < 0.0f) d += std::clamp(0.5f * (before - after) / curvature, -0.5f, 0.5f);
      }
      scored->push_back({c + levels.first - d_min, Eigen::Vector2f(l.x() - d, l.y()), 0.0f, m});
    }
  }
};

// The feature-vs-feature network's candidates: columns are right features. A sparse network
// keeps the pairs within max_epipolar_distance_px of the epipolar line (on a rectified pair:
// rows within it and disparities in range), in the z range, with ZNCC at least
// min_correlation, the top_k best; a dense one keeps every pair. The right features a left
// feature tests: rectified, those of its rows (`rows`); unrectified, those of the grid cells
// its epipolar band crosses (`grid`, when band_search; 10-50x fewer pairs than all); else all.
struct FeatureCandidates {
  const std::vector<Eigen::Vector2f>& left_points;
  const std::vector<Eigen::Vector2f>& right_points;
  const ZnccMatcher& zncc;
  const calib::StereoCalibration* calibration;
  const CandidateOptions& options;
  const std::unordered_map<int, std::vector<int>>& rows;  // right features by rounded row
  const hnn::PointGrid& grid;
  bool band_search;
  int row_reach;  // rows within max_epipolar_distance_px of a left feature's

  // Appends left feature i's candidates to `out` (sorted by column).
  void Append(int i, Scratch& scratch, std::vector<hnn::Candidate>& out,
              std::int64_t& pairs_tested) const {
    const Eigen::Vector2f& l = left_points[static_cast<std::size_t>(i)];
    const Eigen::Vector3d line = options.rectified
                                     ? Eigen::Vector3d::Zero().eval()
                                     : calib::EpipolarLineInRight(calibration->F, l.cast<double>());
    std::vector<Scored>& scored = scratch.scored;
    scored.clear();
    if (options.rectified && !options.dense) {
      const int y = static_cast<int>(std::lround(l.y()));
      for (int row = y - row_reach; row <= y + row_reach; ++row) {
        const auto it = rows.find(row);
        if (it == rows.end()) continue;
        for (int k : it->second) Consider(l, line, k, &scored, &pairs_tested);
      }
    } else if (band_search) {
      thread_local std::vector<int> in_band;
      RightFeaturesInBand(grid, line, options.max_epipolar_distance_px, in_band);
      for (int k : in_band) Consider(l, line, k, &scored, &pairs_tested);
    } else {
      for (int k = 0; k < static_cast<int>(right_points.size()); ++k) {
        Consider(l, line, k, &scored, &pairs_tested);
      }
    }
    if (!options.dense) KeepTopK(&scored, options.top_k);
    std::sort(scored.begin(), scored.end(),
              [](const Scored& a, const Scored& b) { return a.column < b.column; });
    for (const Scored& s : scored) out.push_back({i, s.column, s.right_point, s.tau, s.correlation});
  }

 private:
  // Tests the pair (left point l, right feature k) and scores it when it passes the gates.
  void Consider(const Eigen::Vector2f& l, const Eigen::Vector3d& line, int k,
                std::vector<Scored>* scored, std::int64_t* pairs_tested) const {
    const Eigen::Vector2f& r = right_points[static_cast<std::size_t>(k)];
    ++*pairs_tested;
    const float tau = EpipolarDistance(line, l, r, options.rectified);
    if (!options.dense) {
      if (!(tau <= options.max_epipolar_distance_px)) return;
      if (options.rectified) {
        const double d = l.x() - r.x();
        if (d < options.min_disparity || d > options.max_disparity) return;
      }
      if (!HeightInRange(calibration, options, l, r)) return;
    }
    const float m = zncc(l, r);
    if (!options.dense && m < options.min_correlation) return;
    scored->push_back({k, r, std::isfinite(tau) ? tau : 1e6f, m});
  }
};

// Runs `source.Append` for every left feature. Each left feature's candidates depend on that
// feature alone (ZNCC reads the images only): chunks of features run in parallel on OpenCV's
// thread pool, each into its own list, joined in feature order, so the problem is the same
// (sorted by (left, column)) for any thread count.
template <typename Source>
void CollectCandidates(int n_left, const Source& source, CandidateReport* report) {
  const int n_chunks = std::max(1, std::min(n_left, 8 * std::max(1, cv::getNumThreads())));
  std::vector<std::vector<hnn::Candidate>> chunk_candidates(static_cast<std::size_t>(n_chunks));
  std::vector<std::int64_t> chunk_pairs(static_cast<std::size_t>(n_chunks), 0);
  cv::parallel_for_(cv::Range(0, n_chunks), [&](const cv::Range& range) {
    Scratch scratch;
    for (int c = range.start; c < range.end; ++c) {
      const auto uc = static_cast<std::size_t>(c);
      const int first = static_cast<int>(static_cast<std::int64_t>(n_left) * c / n_chunks);
      const int last = static_cast<int>(static_cast<std::int64_t>(n_left) * (c + 1) / n_chunks);
      for (int i = first; i < last; ++i) source.Append(i, scratch, chunk_candidates[uc], chunk_pairs[uc]);
    }
  });
  std::size_t total = 0;
  for (const auto& chunk : chunk_candidates) total += chunk.size();
  report->problem.candidates.reserve(total);
  for (std::size_t c = 0; c < chunk_candidates.size(); ++c) {
    report->problem.candidates.insert(report->problem.candidates.end(), chunk_candidates[c].begin(),
                                      chunk_candidates[c].end());
    report->pairs_tested += chunk_pairs[c];
  }
}

// The feature-vs-disparity network's levels: refuses a range beyond the image width (a level
// there can never hold a candidate) before allocating for it.
DisparityCandidates DisparityLevels(const std::vector<Eigen::Vector2f>& left_points,
                                    const ZnccMatcher& zncc, const CandidateOptions& options,
                                    const std::vector<DisparityBand>& bands) {
  const double width_limit = std::max(0, zncc.right_width() - 1);
  if (options.max_disparity > width_limit || options.min_disparity < -width_limit) {
    throw std::invalid_argument(
        "disparity range [" + std::to_string(options.min_disparity) + ", " +
        std::to_string(options.max_disparity) + "] is beyond the image width (" +
        std::to_string(zncc.right_width()) + " px: |disparity| <= " +
        std::to_string(static_cast<int>(width_limit)) + ")");
  }
  return {left_points, zncc, options, static_cast<int>(std::ceil(options.min_disparity)),
          static_cast<int>(std::floor(options.max_disparity)), bands};
}

// The feature-vs-feature network's candidates: right features bucketed by row (rectified,
// sparse) or in a uniform grid of cells of at least 16 px and 4 band widths (unrectified,
// sparse), then collected.
void CollectFeatureCandidates(const std::vector<Eigen::Vector2f>& left_points,
                              const std::vector<Eigen::Vector2f>& right_points,
                              const ZnccMatcher& zncc, const calib::StereoCalibration* calibration,
                              const CandidateOptions& options, CandidateReport* report) {
  std::unordered_map<int, std::vector<int>> rows;
  if (options.rectified && !options.dense) {
    for (int k = 0; k < static_cast<int>(right_points.size()); ++k) {
      rows[static_cast<int>(std::lround(right_points[static_cast<std::size_t>(k)].y()))].push_back(k);
    }
  }
  const bool band_search = !options.rectified && !options.dense && !right_points.empty();
  const hnn::PointGrid grid(band_search ? right_points : std::vector<Eigen::Vector2f>{},
                            std::max(16.0, 4.0 * options.max_epipolar_distance_px));
  const int row_reach = static_cast<int>(std::ceil(options.max_epipolar_distance_px));
  CollectCandidates(static_cast<int>(left_points.size()),
                    FeatureCandidates{left_points, right_points, zncc, calibration, options, rows,
                                      grid, band_search, row_reach},
                    report);
}

}  // namespace

std::string CandidateOptions::Check() const {
  if (!(max_epipolar_distance_px >= 0.0)) {
    return "max_epipolar_distance_px must be >= 0 (got " + std::to_string(max_epipolar_distance_px) + ")";
  }
  if (!(min_disparity <= max_disparity) || !std::isfinite(min_disparity) ||
      !std::isfinite(max_disparity)) {
    return "need min_disparity <= max_disparity (got " + std::to_string(min_disparity) + ", " +
           std::to_string(max_disparity) + ")";
  }
  if (z_range_mm && !(z_range_mm->first < z_range_mm->second)) {
    return "z range needs ZMIN < ZMAX";
  }
  if (top_k < 0) return "top_k must be >= 0";
  if (kind == hnn::NetworkKind::kFeatureVsDisparity && !rectified) {
    return "the feature-vs-disparity network needs a rectified pair";
  }
  if ((zncc_peaks || subpixel_peaks) && kind != hnn::NetworkKind::kFeatureVsDisparity) {
    return "zncc_peaks / subpixel_peaks need the feature-vs-disparity network";
  }
  return {};
}

CandidateReport BuildCandidates(const std::vector<Eigen::Vector2f>& left_points,
                                const std::vector<Eigen::Vector2f>& right_points,
                                const ZnccMatcher& zncc,
                                const calib::StereoCalibration* calibration,
                                const CandidateOptions& options,
                                const std::vector<DisparityBand>& bands) {
  const auto start = std::chrono::steady_clock::now();
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  if (!options.rectified && calibration == nullptr) {
    throw std::invalid_argument("candidate gating needs a calibration (F) or a rectified pair");
  }
  CandidateReport report;
  hnn::MatchingProblem& problem = report.problem;
  problem.left_points = left_points;
  problem.kind = options.kind;
  problem.dense = options.dense;
  report.right_points = right_points;
  if (options.kind == hnn::NetworkKind::kFeatureVsDisparity) {
    if (!bands.empty() && bands.size() != left_points.size()) {
      throw std::invalid_argument("BuildCandidates: one disparity band per left feature");
    }
    const DisparityCandidates levels = DisparityLevels(left_points, zncc, options, bands);
    problem.n_columns = levels.n_columns();
    CollectCandidates(static_cast<int>(left_points.size()), levels, &report);
  } else {
    problem.n_columns = static_cast<int>(right_points.size());
    CollectFeatureCandidates(left_points, right_points, zncc, calibration, options, &report);
  }
  report.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace hnnstereo::vision
