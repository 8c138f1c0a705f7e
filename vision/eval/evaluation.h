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
//
// Ranked by confidence (docs/accuracy.md, "Ranked by confidence"): every method over ALL left
// Canny edge pixels with ground truth, each ranked by its own confidence - the HNN presets by
// StereoMatch::confidence, winner-take-all ZNCC by its margin, StereoSGBM / StereoBM swept over
// their uniqueness ratio (one point per setting). An invalid output is simply not kept there.

#include <Eigen/Core>
#include <array>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "host/opencl_runtime.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/eval/middlebury.h"

namespace hnnstereo::vision {

/// Matches of one method at left pixels: right point NaN = no valid output (counts as wrong).
struct MethodMatches {
  std::string method;
  std::vector<Eigen::Vector2f> left;
  std::vector<Eigen::Vector2f> right;
  std::vector<float> confidence;  ///< higher = surer (HNN confidence, WTA margin); ranks curves
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
/// the best-scoring right pixel, or NaN when no window is valid. Confidence = the margin: the
/// best ZNCC minus the best ZNCC more than 1 px (one search step) away from the winner (-1 when
/// there is none), in [0, 2].
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
/// num_disparities is rounded up to a multiple of 16. StereoSGBM: 5x5 block, MODE_HH (full 8
/// paths), P1 = 8*25, P2 = 32*25 (one channel), disp12MaxDiff = 1 (the left-right check),
/// speckle window 100 / range 2. StereoBM: 15x15, disp12MaxDiff = 1. Both at `uniqueness_ratio`.
MethodMatches OpenCvBlockMatching(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                  const std::vector<Eigen::Vector2f>& left_points, bool semi_global,
                                  int min_disparity, int num_disparities, int uniqueness_ratio = 10);

// ---- Ranked by confidence ---------------------------------------------------------------

/// The densities of the ranked table (share of left Canny edge pixels with ground truth).
inline constexpr double kTableDensities[] = {0.25, 0.50, 0.75};
/// The uniqueness ratios StereoSGBM and StereoBM are swept over.
inline constexpr int kUniquenessSweep[] = {0, 5, 10, 15, 20, 25, 30, 40, 50, 60};

/// Counts of one method kept down to one density (fractional where the cut splits matches of
/// equal confidence: each of them counts with the share kept, so ties are never ordered by
/// chance). Precision and error are over the kept non-occluded matches, as in MethodScore.
struct OperatingPoint {
  bool reached = false;      ///< the method keeps at least that density
  double kept = 0.0;         ///< kept matches at pixels with ground truth
  double nonoccluded = 0.0;  ///< ... non-occluded
  double correct = 0.0;      ///< ... within 1 px
  int n_edges_with_truth = 0;
  std::string setting;       ///< swept methods: the setting, e.g. "uniqueness 10"
  int n_pairs = 0;           ///< pooled points: pairs summed (reached ones)
  double density() const { return n_edges_with_truth ? kept / n_edges_with_truth : 0.0; }
  double precision() const { return nonoccluded > 0.0 ? correct / nonoccluded : 0.0; }
  double error() const { return 1.0 - precision(); }
  void Add(const OperatingPoint& other);  ///< pools counts (setting and reached are left alone)
};

/// One method over all edge pixels with ground truth: the kept matches sorted by confidence.
struct RankedMatches {
  struct Entry {
    float confidence;
    bool nonoccluded, correct;
  };
  std::vector<Entry> entries;  ///< valid matches at pixels with ground truth, most confident first
  int n_edges_with_truth = 0;
  /// The most confident matches down to `density` (n/a = not reached).
  OperatingPoint At(double density) const;
  /// The most confident `share` of the kept matches (ranking check: share 0.25).
  OperatingPoint TopShare(double share) const;
  OperatingPoint Full() const;
  /// Precision against density, `steps` evenly spaced densities up to the full one.
  std::vector<CurvePoint> Curve(int steps = 50) const;
};

/// Scores matches (right NaN = not kept) against the truth and ranks them by confidence.
RankedMatches RankMatches(const MethodMatches& matches, const TruthView& truth,
                          int n_edges_with_truth);

/// One setting of a swept method (StereoSGBM / StereoBM at one uniqueness ratio).
struct SweepPoint {
  int uniqueness_ratio = 0;
  OperatingPoint point;  ///< all valid outputs at the edge pixels
};

/// "Best setting reaching density D": among the settings whose density >= D, the one with the
/// highest precision (ties: the denser); that setting's full point, not cut down to D.
/// Not reached when no setting is that dense.
OperatingPoint BestSettingReaching(const std::vector<SweepPoint>& sweep, double density);

/// The densest setting (full density of a swept method).
OperatingPoint DensestSetting(const std::vector<SweepPoint>& sweep);

/// StereoSGBM (semi_global) or StereoBM over `uniqueness_ratios`, read at `edges`, scored.
std::vector<SweepPoint> SweepUniqueness(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                        const std::vector<Eigen::Vector2f>& edges, bool semi_global,
                                        int min_disparity, int num_disparities,
                                        const TruthView& truth, int n_edges_with_truth,
                                        const std::vector<int>& uniqueness_ratios);

/// One method of the ranked comparison on one pair.
struct RankedMethod {
  std::string method;        ///< "hnn-default", "wta-zncc (margin)", "opencv-sgbm (sweep)"...
  bool swept = false;        ///< true: `sweep` is set; false: `ranked` is set
  RankedMatches ranked;
  std::vector<SweepPoint> sweep;
  double time_ms = 0.0;
  /// The confidence is a probability of being within 1 px (the HNN presets' fitted model,
  /// ConfidenceOptions): it is binned in the confidence calibration.
  bool probability = false;
  OperatingPoint At(double density) const;  ///< ranked cut, or the best setting reaching it
  OperatingPoint Full() const;               ///< all matches, or the densest setting
  std::vector<CurvePoint> Curve() const;     ///< ranked curve, or one point per setting
};

/// The memory budget of `eval`'s networks (bytes): three times the matcher's default
/// (hnn::kDefaultMemoryBudgetBytes), since the ablation presets on textured full-size sets
/// (top-8 over every disparity level) build networks of about 2.4 GB.
inline constexpr std::size_t kEvaluationMemoryBudgetBytes = 3 * hnn::kDefaultMemoryBudgetBytes;

struct EvaluationOptions {
  /// The matchers compared, first = "the default" (the baselines use its matched pixels).
  std::vector<MatcherPreset> presets = {AccurateDefaultPreset(), ThesisPreset()};
  bool baselines = true;          ///< WTA ZNCC, StereoBM, StereoSGBM at the same pixels
  int wta_zncc_window = 7;        ///< thesis: 7
  bool warped = false;            ///< also evaluate the unrectified version (right warped by H)
  /// A pair whose name contains one of these is an outdoor scene, any other an indoor one (the
  /// Middlebury sets): the confidence calibration is also pooled per scene type.
  std::vector<std::string> outdoor_names = {"eth3d", "kitti", "outdoor"};
  /// Homography of the warped evaluation: a small rotation, shear and vertical shift.
  Eigen::Matrix3d warp = DefaultWarp();
  std::string Check() const;
  static Eigen::Matrix3d DefaultWarp();
};

struct PairEvaluation {
  std::string name, layout, occlusion_source;
  std::string scene = "indoor";  ///< or "outdoor" (EvaluationOptions::outdoor_names)
  int width = 0, height = 0;
  double min_disparity = 0.0, max_disparity = 0.0;
  int n_edges = 0, n_edges_with_truth = 0;
  std::vector<MethodScore> scores;  ///< presets then baselines
  std::vector<std::pair<std::string, std::vector<CurvePoint>>> curves;
  /// Ranked by confidence over all edge pixels: each HNN preset (rectified), then (baselines)
  /// "wta-zncc (margin)", "opencv-sgbm (sweep)", "opencv-bm (sweep)".
  std::vector<RankedMethod> ranked;
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

/// Edges of the confidence bins of the calibration table: [0, 0.5), [0.5, 0.8), [0.8, 0.9),
/// [0.9, 0.95), [0.95, 0.99), [0.99, 1].
inline constexpr std::array<double, 7> kConfidenceBinEdges = {0.0, 0.5, 0.8, 0.9, 0.95, 0.99, 1.0};

/// Error rate against confidence, a reliability table (Niculescu-Mizil and Caruana, "Predicting
/// good probabilities with supervised learning", ICML 2005): a method's non-occluded matches at
/// pixels with ground truth, binned by confidence. A confidence that holds across scenes has about
/// 1 - (mean confidence) of a bin's matches wrong, in every bin and on every scene type.
struct ConfidenceCalibration {
  static constexpr std::size_t kBins = kConfidenceBinEdges.size() - 1;
  std::string group;  ///< a pair's name, a scene type ("indoor", "outdoor") or "overall"
  std::string method;
  int n_pairs = 0;
  std::array<double, kBins> matches{}, wrong{}, confidence_sum{};
  void Add(const RankedMatches& ranked);        ///< bins one pair's matches
  void Add(const ConfidenceCalibration& other);  ///< pools counts (group and method kept)
  double Error(std::size_t bin) const;           ///< NaN for an empty bin
  double MeanConfidence(std::size_t bin) const;  ///< NaN for an empty bin
};

/// The ranked comparison's figures, per pair and pooled over pairs (counts summed: edge-weighted).
struct RankedSummary {
  struct Row {
    std::string pair;    ///< pair name, or "overall"
    std::string method;
    OperatingPoint at[3];  ///< at kTableDensities
    OperatingPoint full;
  };
  struct Ratio {  ///< first HNN preset's error / StereoSGBM best setting's error, same density
    std::string pair;
    OperatingPoint hnn[4], sgbm[4];  ///< at kTableDensities, then at the HNN's full density
    double ratio(int i) const;       ///< NaN when either does not reach
  };
  struct RankingCheck {  ///< error of the top 25 % by confidence vs all, per HNN preset
    std::string pair, method;
    OperatingPoint top, all;
    double ratio() const { return all.error() > 0.0 ? top.error() / all.error() : 0.0; }
  };
  struct SamePixels {  ///< at the first preset's matched pixels: HNN vs SGBM (uniqueness 10)
    std::string pair;
    double density = 0.0, hnn_error = 0.0, sgbm_error = 0.0;
    int n = 0;
    double ratio() const { return sgbm_error > 0.0 ? hnn_error / sgbm_error : 0.0; }
  };
  std::vector<Row> rows;  ///< per pair (in order), then overall
  std::vector<Ratio> ratios;
  std::vector<RankingCheck> ranking;
  std::vector<SamePixels> same_pixels;
  /// Per probability-ranked method: per pair, then per scene type, then overall.
  std::vector<ConfidenceCalibration> calibration;
};
RankedSummary SummarizeRanked(const EvaluationReport& report);

nlohmann::json EvaluationJson(const EvaluationReport& report);
/// A Markdown table: one row per pair and method, then the overall rows; then the ranked
/// comparison (RankedMarkdown) when the report has one.
std::string EvaluationMarkdown(const EvaluationReport& report);
/// The "Ranked by confidence" tables: error rates at 25 / 50 / 75 % and full density, the HNN /
/// StereoSGBM ratio, the ranking check, the comparison at the HNN's pixels.
std::string RankedMarkdown(const EvaluationReport& report);

}  // namespace hnnstereo::vision
