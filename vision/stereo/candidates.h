#pragma once
// Candidate gating: which (left feature, right feature) pairs become neurons (ARCHITECTURE.md,
// the HNN engine). Epipolar distance (from F, or rows when rectified), disparity range
// (rectified), world-height range (calibrated), optional top-K by correlation, or the thesis's
// all-pairs network.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "host/hopfield_problem.h"
#include "vision/stereo/correlation.h"

namespace hnnstereo::vision {

struct CandidateOptions {
  bool rectified = false;                 ///< rows are epipolar lines; tau = |y_l - y_r|
  double max_epipolar_distance_px = 1.5;  ///< gate on tau (eq. 6.14), pixels
  double min_disparity = 0.0;             ///< rectified: d = x_l - x_r >= this (px)
  double max_disparity = 64.0;            ///< rectified: d <= this (px)
  /// Calibrated: keep a candidate only when its triangulated point has zmin <= Z <= zmax (mm).
  std::optional<std::pair<double, double>> z_range_mm;
  int top_k = 8;                          ///< keep the K best-correlated per left feature; 0 = all
  double min_correlation = -1.0;          ///< drop candidates whose ZNCC is below this
  bool dense = false;                     ///< the thesis's all-pairs network (no gating at all)
  hnn::NetworkKind kind = hnn::NetworkKind::kFeatureVsFeature;
  /// Feature-vs-disparity only: keep only the local maxima of ZNCC along the row (a disparity
  /// whose ZNCC is >= both neighbours'), so top-K picks K distinct peaks instead of the
  /// shoulders of the best one. Off: every disparity level competes (the thesis code).
  bool zncc_peaks = false;
  /// Feature-vs-disparity only: move each candidate's right point to the vertex of the parabola
  /// through ZNCC at d - 1, d, d + 1 (at most 0.5 px), so the disparity-gradient compatibility
  /// sees sub-pixel disparities. The column stays the integer level.
  bool subpixel_peaks = false;
  std::string Check() const;
};

/// The disparity levels one left feature searches (feature-vs-disparity network), lo..hi
/// inclusive: a band around a coarser level's answer (vision/stereo/coarse_to_fine.h).
struct DisparityBand {
  int lo = 0, hi = -1;  ///< an empty band (lo > hi) gives the feature no candidate
};

struct CandidateReport {
  hnn::MatchingProblem problem;
  std::vector<Eigen::Vector2f> right_points;  ///< right features (feature-vs-feature)
  std::int64_t pairs_tested = 0;
  double time_ms = 0.0;
};

/// Builds the matching problem. `calibration` is required unless options.rectified; its F gives
/// tau and its P1, P2 the height gate. `bands` (feature-vs-disparity network only): empty, or
/// one per left feature - that feature searches only its band (clipped to the options' range;
/// the columns stay the levels of the whole range). Throws std::invalid_argument on bad options.
CandidateReport BuildCandidates(const std::vector<Eigen::Vector2f>& left_points,
                                const std::vector<Eigen::Vector2f>& right_points,
                                const ZnccMatcher& zncc,
                                const calib::StereoCalibration* calibration,
                                const CandidateOptions& options,
                                const std::vector<DisparityBand>& bands = {});

}  // namespace hnnstereo::vision
