#pragma once
// Accuracy of the matcher on data with ground truth (issue 6): the Hopfield matcher and honest
// baselines scored at the SAME left pixels in the same run.
//
// Scores (per pair and overall):
// - precision within 1 px / 2 px: share of the matches at non-occluded pixels with ground truth
//   whose right point lies within 1 (2) px of the true one, (x - d, y); occluded pixels (mask or
//   left-right check of the ground truth) are counted and scored apart;
// - density: matches at pixels with ground truth / Canny edge pixels (of the left image, same
//   detector options as the matcher) with ground truth;
// - time of each method.
// Baselines at the HNN's matched left pixels: winner-take-all ZNCC along the epipolar line (the
// thesis's local search, "selective point matching"), OpenCV StereoBM and StereoSGBM (invalid
// output counts as wrong), and the thesis-faithful HNN.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "host/opencl_runtime.h"
#include "vision/matcher_presets.h"
#include "vision/middlebury.h"

namespace hnnstereo::vision {

/// Matches of one method at left pixels: right point NaN = no valid output (counts as wrong).
struct MethodMatches {
  std::string method;
  std::vector<Eigen::Vector2f> left;
  std::vector<Eigen::Vector2f> right;
  std::vector<float> confidence;  ///< higher = surer (activation, ZNCC...); ranks the curve
  double time_ms = 0.0;
};

/// One method's scores on one pair (or summed over pairs).
struct MethodScore {
  std::string method;
  int n_matches = 0;             ///< all matches (left pixels) handed in
  int n_with_truth = 0;          ///< at pixels with ground truth
  int n_nonoccluded = 0;         ///< ... and visible in the right image
  int n_occluded = 0;            ///< ... with ground truth but occluded
  int n_invalid = 0;             ///< no output at the pixel (counted wrong)
  int correct_1px = 0, correct_2px = 0;  ///< non-occluded matches within 1 / 2 px
  int occluded_correct_1px = 0;          ///< occluded matches within 1 px of the truth
  int n_edges_with_truth = 0;    ///< denominator of density
  double sum_error_px = 0.0;     ///< non-occluded, valid matches: sum of endpoint errors
  int n_error = 0;
  double time_ms = 0.0;

  double precision_1px() const { return n_nonoccluded ? double(correct_1px) / n_nonoccluded : 0.0; }
  double precision_2px() const { return n_nonoccluded ? double(correct_2px) / n_nonoccluded : 0.0; }
  double occluded_precision_1px() const {
    return n_occluded ? double(occluded_correct_1px) / n_occluded : 0.0;
  }
  double density() const { return n_edges_with_truth ? double(n_with_truth) / n_edges_with_truth : 0.0; }
  double mean_error_px() const { return n_error ? sum_error_px / n_error : 0.0; }
  void Add(const MethodScore& other);  ///< sums counts and times (overall figures)
};

/// Ground truth of a pair in the frame the matches are given in. `right_from_rectified` maps
/// (x - d, y) of the rectified right image into the right image the matcher saw (identity for
/// rectified evaluation, H for the warped one).
struct TruthView {
  const cv::Mat* disparity = nullptr;    ///< CV_32F, NaN unknown
  const cv::Mat* nonoccluded = nullptr;  ///< CV_8U, 255 visible
  Eigen::Matrix3d right_from_rectified = Eigen::Matrix3d::Identity();
};

/// Scores matches against the ground truth: the error of a match is the distance between its
/// right point, mapped back by right_from_rectified^-1, and the true (x - d, y), where d is the
/// ground truth at the left pixel rounded to the nearest pixel.
MethodScore ScoreMatches(const MethodMatches& matches, const TruthView& truth,
                         int n_edges_with_truth);

/// Precision within 1 px against density when only the most confident matches are kept
/// (density steps of `step`).
struct CurvePoint {
  double density = 0.0;
  double precision_1px = 0.0;
};
std::vector<CurvePoint> PrecisionDensityCurve(const MethodMatches& matches, const TruthView& truth,
                                              int n_edges_with_truth, int steps = 20);

/// Winner-take-all ZNCC at each left pixel over disparities [min, max] along its row (rectified):
/// the best-scoring right pixel, or NaN when no window is valid. Confidence = the best ZNCC.
MethodMatches WinnerTakeAllZncc(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                const std::vector<Eigen::Vector2f>& left_points, int window,
                                int min_disparity, int max_disparity);

/// The same for an unrectified pair, from its calibration alone: the left pixel's ray between
/// `min_depth` and `max_depth` (mm, world frame of P1) projected by P2 into the right image,
/// one sample per right pixel along that epipolar segment.
MethodMatches WinnerTakeAllZnccAlongRay(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                        const calib::StereoCalibration& calibration,
                                        const std::vector<Eigen::Vector2f>& left_points, int window,
                                        double min_depth, double max_depth);

/// Dense OpenCV disparity (StereoBM or StereoSGBM) read at the left pixels; invalid -> NaN.
/// num_disparities is rounded up to a multiple of 16.
MethodMatches OpenCvBlockMatching(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                  const std::vector<Eigen::Vector2f>& left_points, bool semi_global,
                                  int min_disparity, int num_disparities);

struct EvaluationOptions {
  /// The matchers compared, first = "the default" (the baselines use its matched pixels).
  std::vector<MatcherPreset> presets = {AccurateDefaultPreset(), ThesisPreset()};
  bool baselines = true;          ///< WTA ZNCC, StereoBM, StereoSGBM at the same pixels
  int wta_zncc_window = 7;        ///< thesis: 7
  bool warped = false;            ///< also evaluate the unrectified version (right warped by H)
  /// Homography of the warped evaluation: a small rotation, shear and vertical shift.
  Eigen::Matrix3d warp = DefaultWarp();
  std::string Check() const;
  static Eigen::Matrix3d DefaultWarp();
};

struct PairEvaluation {
  std::string name, layout, occlusion_source;
  int width = 0, height = 0;
  double min_disparity = 0.0, max_disparity = 0.0;
  int n_edges = 0, n_edges_with_truth = 0;
  std::vector<MethodScore> scores;  ///< presets then baselines
  std::vector<std::pair<std::string, std::vector<CurvePoint>>> curves;
  std::vector<std::string> notices;
};

struct EvaluationReport {
  std::vector<PairEvaluation> pairs;
  std::vector<MethodScore> overall;  ///< summed over pairs, same order as each pair's scores
  double time_ms = 0.0;
};

/// Evaluates one pair: each preset, then (options.baselines) the baselines at the left pixels
/// the first preset matched. `runtime` may be null (the opencl engine then falls back to cpu).
PairEvaluation EvaluatePair(const MiddleburyPair& pair, const EvaluationOptions& options,
                            ocl::Runtime* runtime);

/// Evaluates every pair and sums the overall figures.
EvaluationReport Evaluate(const std::vector<MiddleburyPair>& pairs, const EvaluationOptions& options,
                          ocl::Runtime* runtime);

nlohmann::json EvaluationJson(const EvaluationReport& report);
/// A Markdown table: one row per pair and method, then the overall rows.
std::string EvaluationMarkdown(const EvaluationReport& report);

}  // namespace hnnstereo::vision
