#pragma once
// Named matcher settings: the thesis-faithful settings, the measured default and the ablations
// (docs/matching.md lists them; docs/accuracy.md gives their figures), plus the refinements that
// run after the network: a left-right consistency check and a parabola sub-pixel fit of the
// data term's similarity.

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "host/opencl_runtime.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

/// Steps after the decoded network (they need the images, so they are not decoding options).
struct RefinementOptions {
  /// Left-right consistency: from each match's right point, search the left image along the
  /// epipolar line (rectified: the row, same disparity range) for the best ZNCC; keep the match
  /// only when that lands within `left_right_tolerance_px` of its left point.
  bool left_right_check = false;
  double left_right_tolerance_px = 1.0;  ///< px
  /// Sub-pixel: fit a parabola to the similarity (the data term's) at the right point and its two
  /// neighbours along the row (rectified pairs only) and move the right point to the vertex (at
  /// most 0.5 px).
  bool subpixel = false;
  /// ... unless the vertex lies less than this (px) from the whole pixel: then the match keeps
  /// its integer disparity (a parabola through three samples does not resolve such a lean).
  double subpixel_min_offset_px = 0.0;
  /// Unrectified pairs: move the right point to the foot of its perpendicular on the left
  /// point's epipolar line F x (a right edge pixel lies up to 0.7 px off the line it belongs to).
  bool epipolar_snap = false;
  /// Unrectified pairs, after the snap: the parabola fit of `subpixel` along the epipolar line,
  /// with bilinearly interpolated right windows.
  bool epipolar_subpixel = false;
  /// Rectified pairs, feature-vs-disparity network, after the check and the fit: a second
  /// network over the features left unmatched (vision/stereo/second_chance.h); its matches pass
  /// the left-right check over the levels they searched and the sub-pixel fit.
  SecondChanceOptions second_chance;
  std::string Check() const;
};

struct MatcherPreset {
  std::string name;
  MatcherOptions matcher;
  RefinementOptions refinement;
  std::string Check() const;
};

/// Thesis-faithful settings (THESIS.md section 3): eq. 6.7 additive compatibility, W1 = 0.3,
/// W2 = 0.7, A = 2, B = C = D = 1, T = 1.5, ZNCC 7x7, continuous activation, all neurons off at
/// the start, thesis pruning (row max, column max, threshold 0.5), feature-vs-feature network,
/// top-8 candidates, 8 px support, the energy stop rule.
MatcherPreset ThesisPreset();

/// hnn-default (docs/matching.md): the feature-vs-disparity network with candidates at the
/// K = 3 best peaks of the census similarity along the row, 14 px support, geometric consistency
/// times similarity, the left-right check and the parabola sub-pixel fit (0.1 px floor), stopped
/// by the decisions rule. Unrectified pairs fall back to the feature network of hnn-geometry-lr
/// (ZNCC) with the epipolar snap and sub-pixel fit along the line.
MatcherPreset AccurateDefaultPreset();

/// All named presets; `name` lookup for --preset.
std::vector<MatcherPreset> AllPresets();
std::optional<MatcherPreset> FindPreset(const std::string& name);

/// MatchStereo, then the preset's refinements. The report's matches are the refined ones;
/// `timing_ms.total` includes the refinement time.
MatchReport MatchWithPreset(const cv::Mat& left_grey, const cv::Mat& right_grey,
                            const calib::StereoCalibration* calibration, const MatcherPreset& preset,
                            ocl::Runtime* runtime);

/// Unrectified pairs: moves match->right onto the left point's epipolar line F x_l (the foot of
/// the perpendicular) and, with `subpixel`, by a parabola fit of ZNCC along that line (at most
/// 0.5 px; right windows bilinearly interpolated).
void RefineAlongEpipolarLine(const cv::Mat& left_grey, const cv::Mat& right_grey,
                             const Eigen::Matrix3d& F, int window, bool subpixel,
                             StereoMatch* match);

/// The refinements alone, on a finished report (with a calibration the left-right check
/// searches the epipolar line F^T x_r and the snap / sub-pixel work along F x_l). The report
/// must come from MatchStereo on this same pair: its `similarity` tables are reused (when they
/// are the data term asked for) and released. `runtime`: the second chance's network runs on
/// it (opencl engine; null: the cpu engine).
void RefineMatches(const cv::Mat& left_grey, const cv::Mat& right_grey,
                   const calib::StereoCalibration* calibration, const MatcherOptions& matcher,
                   const RefinementOptions& refinement, MatchReport* report,
                   ocl::Runtime* runtime = nullptr);

}  // namespace hnnstereo::vision
