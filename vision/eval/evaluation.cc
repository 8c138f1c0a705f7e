#include "vision/eval/evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/stereo/correlation.h"
#include "vision/features/features.h"
#include "common/timing.h"
#include "common/format.h"

namespace hnnstereo::vision {
namespace {

using Clock = std::chrono::steady_clock;
using common::MillisecondsSince;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// The ground truth at a left point: nullopt when unknown or outside the image.
std::optional<std::pair<float, bool>> TruthAt(const TruthView& truth, const Eigen::Vector2f& left) {
  const int x = static_cast<int>(std::lround(left.x()));
  const int y = static_cast<int>(std::lround(left.y()));
  if (x < 0 || y < 0 || x >= truth.disparity->cols || y >= truth.disparity->rows) return std::nullopt;
  const float d = truth.disparity->at<float>(y, x);
  if (!std::isfinite(d)) return std::nullopt;
  return std::make_pair(d, truth.nonoccluded->at<std::uint8_t>(y, x) != 0);
}

// Endpoint error of one match in the rectified frame; +inf for an invalid output.
double MatchError(const Eigen::Matrix3d& rectified_from_right,
                  const Eigen::Vector2f& left, const Eigen::Vector2f& right, float disparity) {
  if (!right.allFinite()) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d mapped = rectified_from_right * Eigen::Vector3d(right.x(), right.y(), 1.0);
  if (!(std::abs(mapped.z()) > 1e-12)) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d right_rectified = mapped.hnormalized();
  const Eigen::Vector2d expected(static_cast<double>(left.x()) - disparity, left.y());
  return (right_rectified - expected).norm();
}

MethodMatches FromReport(const std::string& method, const MatchReport& report) {
  MethodMatches matches;
  matches.method = method;
  for (const StereoMatch& m : report.matches) {
    matches.left.push_back(m.left);
    matches.right.push_back(m.right);
    matches.confidence.push_back(m.confidence);  // ranks the HNN's curves (not the activation)
  }
  matches.time_ms = report.timing_ms.total;
  return matches;
}

// A rectified calibration for sets that ship none (f = width, baseline 100 mm, same K twice):
// it reproduces the rectified geometry, x_r = x_l - d with d = f b / Z.
calib::StereoCalibration SyntheticRectifiedCalibration(int width, int height) {
  Eigen::Matrix3d K;
  K << width, 0, 0.5 * (width - 1), 0, width, 0.5 * (height - 1), 0, 0, 1;
  calib::StereoCalibration calibration;
  calibration.P1.leftCols<3>() = K;
  calibration.P1.col(3).setZero();
  calibration.P2.leftCols<3>() = K;
  calibration.P2.col(3) = K * Eigen::Vector3d(-100.0, 0.0, 0.0);
  calibration.image_width = width;
  calibration.image_height = height;
  calibration.rectified = true;
  calibration.DeriveFromProjections();
  return calibration;
}

MethodScore ScoreAndCurve(const MethodMatches& matches, const TruthView& truth, int n_edges_with_truth,
                          PairEvaluation* evaluation) {
  MethodScore score = ScoreMatches(matches, truth, n_edges_with_truth);
  evaluation->curves.emplace_back(matches.method,
                                  PrecisionDensityCurve(matches, truth, n_edges_with_truth));
  return score;
}

// Everything of the matcher options that changes the network's result.
std::string MatcherKey(const MatcherOptions& o) {
  const hnn::EnergyOptions& e = o.energy;
  const hnn::DynamicsOptions& d = o.dynamics;
  std::ostringstream key;
  key << static_cast<int>(o.features.detector) << ',' << o.features.canny_low << ','
      << o.features.canny_high << ',' << o.features.canny_aperture << ',' << o.features.max_features
      << ',' << o.features.border_px << ',' << o.features.susan_brightness_threshold << ','
      << o.features.moravec_window << ',' << o.features.moravec_threshold << ','
      << o.features.sobel_threshold << '|' << o.candidates.rectified << ','
      << o.candidates.max_epipolar_distance_px << ',' << o.candidates.min_disparity << ','
      << o.candidates.max_disparity << ',' << o.candidates.top_k << ','
      << o.candidates.min_correlation << ',' << o.candidates.dense << ','
      << static_cast<int>(o.candidates.kind) << ',' << o.candidates.zncc_peaks << ','
      << o.candidates.subpixel_peaks << '|' << o.zncc_window << ','
      << static_cast<int>(o.data_term.kind) << ',' << o.data_term.census_window << ','
      << o.data_term.aggregation_window << ',' << o.data_term.support_gamma << '|' << e.A << ','
      << e.B << ',' << e.C << ',' << e.D << ',' << e.W1 << ',' << e.W2 << ',' << e.T << ','
      << e.lambda << ',' << e.theta << ',' << static_cast<int>(e.objective) << ','
      << static_cast<int>(e.compatibility) << ',' << e.support_radius_px << ','
      << e.distance_attenuation << ',' << e.attenuation_centre_px << ',' << e.attenuation_slope
      << ',' << e.weight_offset << '|' << static_cast<int>(d.activation) << ',' << d.alpha << ','
      << static_cast<int>(d.initial_state) << ',' << d.initial_value << ',' << d.initial_noise
      << ',' << d.seed << ',' << d.time_step << ',' << d.tau << ',' << d.max_steps << ','
      << d.energy_interval << ',' << d.energy_tolerance << ',' << d.stable_checks << ','
      << d.max_updates << ',' << d.stable_updates << ',' << d.update_tolerance << '|'
      << static_cast<int>(o.decode.method) << ',' << o.decode.threshold << '|'
      << static_cast<int>(o.engine) << ',' << o.memory_budget_bytes;
  return key.str();
}

std::string Percent(double share) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", 100.0 * share);
  return text;
}

}  // namespace

void MethodScore::Add(const MethodScore& other) {
  n_matches += other.n_matches;
  n_with_truth += other.n_with_truth;
  n_nonoccluded += other.n_nonoccluded;
  n_occluded += other.n_occluded;
  n_invalid += other.n_invalid;
  correct_1px += other.correct_1px;
  correct_2px += other.correct_2px;
  occluded_correct_1px += other.occluded_correct_1px;
  n_edges_with_truth += other.n_edges_with_truth;
  sum_error_px += other.sum_error_px;
  n_error += other.n_error;
  time_ms += other.time_ms;
}

MethodScore ScoreMatches(const MethodMatches& matches, const TruthView& truth,
                         int n_edges_with_truth) {
  if (truth.disparity == nullptr || truth.nonoccluded == nullptr) {
    throw std::invalid_argument("ScoreMatches: the truth view has no disparity or mask");
  }
  if (matches.left.size() != matches.right.size()) {
    throw std::invalid_argument("ScoreMatches: " + std::to_string(matches.left.size()) +
                                " left and " + std::to_string(matches.right.size()) + " right points");
  }
  const Eigen::Matrix3d rectified_from_right = truth.right_from_rectified.inverse();
  MethodScore score;
  score.method = matches.method;
  score.n_matches = static_cast<int>(matches.left.size());
  score.n_edges_with_truth = n_edges_with_truth;
  score.time_ms = matches.time_ms;
  for (std::size_t i = 0; i < matches.left.size(); ++i) {
    const auto known = TruthAt(truth, matches.left[i]);
    if (!known) continue;
    ++score.n_with_truth;
    const double error = MatchError(rectified_from_right, matches.left[i], matches.right[i],
                                    known->first);
    if (!std::isfinite(error)) ++score.n_invalid;
    if (known->second) {
      ++score.n_nonoccluded;
      if (error <= 1.0) ++score.correct_1px;
      if (error <= 2.0) ++score.correct_2px;
      if (std::isfinite(error)) score.sum_error_px += error, ++score.n_error;
    } else {
      ++score.n_occluded;
      if (error <= 1.0) ++score.occluded_correct_1px;
    }
  }
  return score;
}

std::vector<CurvePoint> PrecisionDensityCurve(const MethodMatches& matches, const TruthView& truth,
                                              int n_edges_with_truth, int steps) {
  std::vector<CurvePoint> curve;
  if (matches.left.empty() || n_edges_with_truth <= 0 || steps <= 0) return curve;
  std::vector<std::size_t> order(matches.left.size());
  std::iota(order.begin(), order.end(), 0);
  const bool ranked = matches.confidence.size() == matches.left.size();
  if (ranked) {
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return matches.confidence[a] > matches.confidence[b];
    });
  }
  const Eigen::Matrix3d rectified_from_right = truth.right_from_rectified.inverse();
  int with_truth = 0, nonoccluded = 0, correct = 0;
  const std::size_t n = order.size();
  std::size_t next = ranked ? std::max<std::size_t>(1, n / static_cast<std::size_t>(steps)) : n;
  for (std::size_t rank = 0; rank < n; ++rank) {
    const std::size_t i = order[rank];
    if (const auto known = TruthAt(truth, matches.left[i])) {
      ++with_truth;
      if (known->second) {
        ++nonoccluded;
        if (MatchError(rectified_from_right, matches.left[i], matches.right[i], known->first) <= 1.0) {
          ++correct;
        }
      }
    }
    if (rank + 1 == next || rank + 1 == n) {
      if (nonoccluded > 0) {
        curve.push_back({double(with_truth) / n_edges_with_truth, double(correct) / nonoccluded});
      }
      next = std::min(n, next + std::max<std::size_t>(1, n / static_cast<std::size_t>(steps)));
    }
  }
  return curve;
}

// ---- Ranked by confidence ---------------------------------------------------------------

void OperatingPoint::Add(const OperatingPoint& other) {
  kept += other.kept;
  nonoccluded += other.nonoccluded;
  correct += other.correct;
  n_edges_with_truth += other.n_edges_with_truth;
  n_pairs += std::max(1, other.n_pairs);
}

namespace {

// The first `count` entries (fractional): a group of equal confidence that the cut splits
// counts with the share kept.
OperatingPoint CutRanked(const std::vector<RankedMatches::Entry>& entries, double count,
                         int n_edges_with_truth) {
  OperatingPoint point;
  point.n_edges_with_truth = n_edges_with_truth;
  point.n_pairs = 0;
  const double n = static_cast<double>(entries.size());
  point.reached = !entries.empty() && count <= n + 1e-9;  // no match at all: nothing reached
  if (!point.reached) return point;
  count = std::min(count, n);
  std::size_t begin = 0;
  while (begin < entries.size() && point.kept < count - 1e-12) {
    std::size_t end = begin + 1;
    while (end < entries.size() && entries[end].confidence == entries[begin].confidence) ++end;
    double nonoccluded = 0.0, correct = 0.0;
    for (std::size_t i = begin; i < end; ++i) {
      nonoccluded += entries[i].nonoccluded ? 1.0 : 0.0;
      correct += entries[i].correct ? 1.0 : 0.0;
    }
    const double size = static_cast<double>(end - begin);
    const double share = std::min(1.0, (count - point.kept) / size);
    point.kept += share * size;
    point.nonoccluded += share * nonoccluded;
    point.correct += share * correct;
    begin = end;
  }
  return point;
}

}  // namespace

OperatingPoint RankedMatches::At(double density) const {
  return CutRanked(entries, density * n_edges_with_truth, n_edges_with_truth);
}

OperatingPoint RankedMatches::TopShare(double share) const {
  return CutRanked(entries, share * static_cast<double>(entries.size()), n_edges_with_truth);
}

OperatingPoint RankedMatches::Full() const {
  return CutRanked(entries, static_cast<double>(entries.size()), n_edges_with_truth);
}

std::vector<CurvePoint> RankedMatches::Curve(int steps) const {
  std::vector<CurvePoint> curve;
  if (entries.empty() || n_edges_with_truth <= 0 || steps <= 0) return curve;
  const double n = static_cast<double>(entries.size());
  for (int s = 1; s <= steps; ++s) {
    const OperatingPoint point = CutRanked(entries, n * s / steps, n_edges_with_truth);
    if (point.nonoccluded > 0.0) curve.push_back({point.density(), point.precision()});
  }
  return curve;
}

RankedMatches RankMatches(const MethodMatches& matches, const TruthView& truth,
                          int n_edges_with_truth) {
  if (truth.disparity == nullptr || truth.nonoccluded == nullptr) {
    throw std::invalid_argument("RankMatches: the truth view has no disparity or mask");
  }
  if (matches.left.size() != matches.right.size()) {
    throw std::invalid_argument("RankMatches: " + std::to_string(matches.left.size()) +
                                " left and " + std::to_string(matches.right.size()) + " right points");
  }
  const bool has_confidence = matches.confidence.size() == matches.left.size();
  const Eigen::Matrix3d rectified_from_right = truth.right_from_rectified.inverse();
  RankedMatches ranked;
  ranked.n_edges_with_truth = n_edges_with_truth;
  for (std::size_t i = 0; i < matches.left.size(); ++i) {
    const auto known = TruthAt(truth, matches.left[i]);
    if (!known) continue;
    const double error = MatchError(rectified_from_right, matches.left[i], matches.right[i],
                                    known->first);
    if (!std::isfinite(error)) continue;  // no output: not kept
    float confidence = has_confidence ? matches.confidence[i] : 0.0f;
    if (std::isnan(confidence)) confidence = -std::numeric_limits<float>::infinity();
    ranked.entries.push_back({confidence, known->second, known->second && error <= 1.0});
  }
  std::stable_sort(ranked.entries.begin(), ranked.entries.end(),
                   [](const RankedMatches::Entry& a, const RankedMatches::Entry& b) {
                     return a.confidence > b.confidence;
                   });
  return ranked;
}

OperatingPoint BestSettingReaching(const std::vector<SweepPoint>& sweep, double density) {
  const SweepPoint* best = nullptr;
  for (const SweepPoint& s : sweep) {
    if (s.point.density() < density - 1e-12) continue;
    if (best == nullptr || s.point.precision() > best->point.precision() ||
        (s.point.precision() == best->point.precision() &&
         s.point.density() > best->point.density())) {
      best = &s;
    }
  }
  OperatingPoint point;
  if (best == nullptr) {
    if (!sweep.empty()) point.n_edges_with_truth = sweep.front().point.n_edges_with_truth;
    return point;
  }
  point = best->point;
  point.reached = true;
  point.setting = "uniqueness " + std::to_string(best->uniqueness_ratio);
  return point;
}

OperatingPoint DensestSetting(const std::vector<SweepPoint>& sweep) {
  const SweepPoint* densest = nullptr;
  for (const SweepPoint& s : sweep) {
    if (densest == nullptr || s.point.kept > densest->point.kept) densest = &s;
  }
  if (densest == nullptr) return {};
  OperatingPoint point = densest->point;
  point.reached = true;
  point.setting = "uniqueness " + std::to_string(densest->uniqueness_ratio);
  return point;
}

std::vector<SweepPoint> SweepUniqueness(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                        const std::vector<Eigen::Vector2f>& edges, bool semi_global,
                                        int min_disparity, int num_disparities,
                                        const TruthView& truth, int n_edges_with_truth,
                                        const std::vector<int>& uniqueness_ratios) {
  // OpenCV does not expose SGBM's cost volume, so each setting reruns the whole matcher.
  std::vector<SweepPoint> sweep;
  for (const int ratio : uniqueness_ratios) {
    const MethodMatches matches = OpenCvBlockMatching(left_grey, right_grey, edges, semi_global,
                                                      min_disparity, num_disparities, ratio);
    SweepPoint point;
    point.uniqueness_ratio = ratio;
    point.point = RankMatches(matches, truth, n_edges_with_truth).Full();
    point.point.setting = "uniqueness " + std::to_string(ratio);
    sweep.push_back(point);
  }
  return sweep;
}

OperatingPoint RankedMethod::At(double density) const {
  return swept ? BestSettingReaching(sweep, density) : ranked.At(density);
}

OperatingPoint RankedMethod::Full() const { return swept ? DensestSetting(sweep) : ranked.Full(); }

std::vector<CurvePoint> RankedMethod::Curve() const {
  if (!swept) return ranked.Curve();
  std::vector<CurvePoint> points;
  for (const SweepPoint& s : sweep) points.push_back({s.point.density(), s.point.precision()});
  return points;
}

// Winner-take-all ZNCC over the right pixels `search(left, visit)` visits for each left pixel
// (the thesis's local search); a left pixel with no candidate gets a NaN partner.
template <typename Search>
MethodMatches WinnerTakeAllOver(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                const std::vector<Eigen::Vector2f>& left_points, int window,
                                const Search& search) {
  const auto start = Clock::now();
  MethodMatches result;
  result.method = "wta-zncc";
  const ZnccMatcher zncc(left_grey, right_grey, window);
  std::vector<float> scores;
  for (const Eigen::Vector2f& point : left_points) {
    const Eigen::Vector2f left(std::round(point.x()), std::round(point.y()));
    float best = -std::numeric_limits<float>::infinity();
    std::size_t best_step = 0;
    Eigen::Vector2f best_right(kNaN, kNaN);
    scores.clear();
    search(left, [&](const Eigen::Vector2f& right) {
      const float score = zncc(left, right);
      if (score > best) best = score, best_right = right, best_step = scores.size();
      scores.push_back(score);
    });
    // Margin: the winner over the best score more than one search step (1 px) away from it.
    float runner_up = -1.0f;
    for (std::size_t s = 0; s < scores.size(); ++s) {
      if (s + 1 < best_step || s > best_step + 1) runner_up = std::max(runner_up, scores[s]);
    }
    result.left.push_back(point);
    result.right.push_back(best_right);
    result.confidence.push_back(std::isfinite(best) ? best - runner_up : -2.0f);
  }
  result.time_ms = MillisecondsSince(start);
  return result;
}

MethodMatches WinnerTakeAllZncc(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                const std::vector<Eigen::Vector2f>& left_points, int window,
                                int min_disparity, int max_disparity) {
  return WinnerTakeAllOver(left_grey, right_grey, left_points, window,
                           [&](const Eigen::Vector2f& left, const auto& visit) {
                             for (int d = min_disparity; d <= max_disparity; ++d) {
                               const Eigen::Vector2f right(left.x() - static_cast<float>(d), left.y());
                               if (right.x() < 0.0f) break;
                               visit(right);
                             }
                           });
}

MethodMatches WinnerTakeAllZnccAlongRay(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                        const calib::StereoCalibration& calibration,
                                        const std::vector<Eigen::Vector2f>& left_points, int window,
                                        double min_depth, double max_depth) {
  const Eigen::Matrix3d M1_inverse = calibration.P1.leftCols<3>().inverse();
  const Eigen::Vector3d C1 = calibration.C1;
  return WinnerTakeAllOver(
      left_grey, right_grey, left_points, window,
      [&](const Eigen::Vector2f& left, const auto& visit) {
        // Points of the left pixel's ray, projected into the right image (one per right pixel).
        const Eigen::Vector3d direction = M1_inverse * Eigen::Vector3d(left.x(), left.y(), 1.0);
        auto project = [&](double depth) {
          const Eigen::Vector3d world = C1 + depth * direction / direction.z();
          return Eigen::Vector2d((calibration.P2 * world.homogeneous()).hnormalized());
        };
        const Eigen::Vector2d near = project(min_depth), far = project(max_depth);
        const int samples = std::max(2, static_cast<int>(std::ceil((near - far).norm())) + 1);
        for (int s = 0; s < samples; ++s) {
          const Eigen::Vector2d right = far + (near - far) * (double(s) / (samples - 1));
          const Eigen::Vector2f pixel(static_cast<float>(std::round(right.x())),
                                      static_cast<float>(std::round(right.y())));
          if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() > static_cast<float>(right_grey.cols - 1) ||
              pixel.y() > static_cast<float>(right_grey.rows - 1)) {
            continue;
          }
          visit(pixel);
        }
      });
}

MethodMatches OpenCvBlockMatching(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                  const std::vector<Eigen::Vector2f>& left_points, bool semi_global,
                                  int min_disparity, int num_disparities, int uniqueness_ratio) {
  const auto start = Clock::now();
  num_disparities = std::max(16, 16 * ((num_disparities + 15) / 16));
  cv::Mat disparity_fixed;  // CV_16S, 16 x disparity; below min_disparity * 16 = invalid
  if (semi_global) {
    // Hirschmueller, "Stereo processing by semiglobal matching and mutual information", PAMI 2008.
    // OpenCV's recommended smoothness penalties for a 5x5 block on one channel; full 8 paths.
    const int block = 5;
    auto sgbm = cv::StereoSGBM::create(min_disparity, num_disparities, block, 8 * block * block,
                                       32 * block * block, 1, 63, uniqueness_ratio, 100, 2,
                                       cv::StereoSGBM::MODE_HH);
    sgbm->compute(left_grey, right_grey, disparity_fixed);
  } else {
    auto bm = cv::StereoBM::create(num_disparities, 15);
    bm->setMinDisparity(min_disparity);
    bm->setDisp12MaxDiff(1);
    bm->setUniquenessRatio(uniqueness_ratio);
    bm->compute(left_grey, right_grey, disparity_fixed);
  }
  MethodMatches result;
  result.method = semi_global ? "opencv-sgbm" : "opencv-bm";
  for (const Eigen::Vector2f& point : left_points) {
    const int x = static_cast<int>(std::lround(point.x()));
    const int y = static_cast<int>(std::lround(point.y()));
    Eigen::Vector2f right(kNaN, kNaN);
    if (x >= 0 && y >= 0 && x < disparity_fixed.cols && y < disparity_fixed.rows) {
      const short fixed = disparity_fixed.at<short>(y, x);
      if (fixed >= min_disparity * 16) right = Eigen::Vector2f(static_cast<float>(x) - fixed / 16.0f, static_cast<float>(y));
    }
    result.left.push_back(point);
    result.right.push_back(right);
  }
  result.time_ms = MillisecondsSince(start);
  return result;
}

Eigen::Matrix3d EvaluationOptions::DefaultWarp() {
  // A 3 degree rotation about the image centre region, 2 % shear and a 6 px vertical shift:
  // rows are no longer epipolar lines.
  const double angle = 3.0 * 3.14159265358979323846 / 180.0;
  Eigen::Matrix3d H;
  H << std::cos(angle), -std::sin(angle) + 0.02, 12.0, std::sin(angle), std::cos(angle), -6.0, 0.0,
      0.0, 1.0;
  return H;
}

std::string EvaluationOptions::Check() const {
  if (presets.empty()) return "evaluation needs at least one matcher preset";
  for (const MatcherPreset& preset : presets) {
    if (auto error = preset.Check(); !error.empty()) return preset.name + ": " + error;
  }
  if (wta_zncc_window < 3 || wta_zncc_window > 15 || wta_zncc_window % 2 == 0) {
    return "wta_zncc_window must be odd, 3..15 (got " + std::to_string(wta_zncc_window) + ")";
  }
  if (!warp.allFinite() || std::abs(warp.determinant()) < 1e-9) return "the warp homography is singular";
  return {};
}

namespace {

// The pair's description in the evaluation and its notices on how occlusion is known: from a
// mask, from a 1 px left-right check of the two ground-truth maps, or not at all.
void DescribePair(const MiddleburyPair& pair, const EvaluationOptions& options,
                  PairEvaluation* evaluation) {
  evaluation->name = pair.name;
  evaluation->layout = std::string(MiddleburyLayoutName(pair.layout));
  evaluation->occlusion_source = pair.occlusion_source;
  evaluation->width = pair.left_grey.cols;
  evaluation->height = pair.left_grey.rows;
  evaluation->min_disparity = pair.min_disparity;
  evaluation->max_disparity = pair.max_disparity;
  const bool outdoor = std::any_of(options.outdoor_names.begin(), options.outdoor_names.end(),
                                   [&](const std::string& key) {
                                     return !key.empty() && pair.name.find(key) != std::string::npos;
                                   });
  evaluation->scene = outdoor ? "outdoor" : "indoor";
  if (pair.occlusion_source == "left-right check") {
    evaluation->notices.push_back(
        "no occlusion mask: occluded pixels are those failing a 1 px left-right check of the left "
        "and right ground-truth maps");
  } else if (pair.occlusion_source != "mask") {
    evaluation->notices.push_back(
        "no occlusion mask and no right-view ground truth: every pixel with ground truth counts "
        "as non-occluded, so occluded matches are scored as visible ones (figures differ from the "
        "same pair read with its right-view ground truth)");
  }
}

// The matches of each preset on the rectified pair, scored and ranked into `evaluation`.
// Presets that differ only in their refinements share one network run. Returns the first
// preset's left pixels (the baselines are scored at them).
std::vector<Eigen::Vector2f> EvaluatePresets(const MiddleburyPair& pair, const EvaluationOptions& options,
                                             const TruthView& truth, int n_edges, ocl::Runtime* runtime,
                                             PairEvaluation* evaluation) {
  std::vector<Eigen::Vector2f> default_pixels;
  std::vector<std::pair<std::string, MatchReport>> networks;
  for (std::size_t p = 0; p < options.presets.size(); ++p) {
    MatcherPreset preset = options.presets[p];
    preset.matcher.candidates.rectified = true;
    preset.matcher.candidates.min_disparity = pair.min_disparity;
    preset.matcher.candidates.max_disparity = pair.max_disparity;
    MethodMatches matches;
    matches.method = preset.name;
    try {
      const std::string key = MatcherKey(preset.matcher);
      auto cached = std::find_if(networks.begin(), networks.end(),
                                 [&](const auto& entry) { return entry.first == key; });
      if (cached == networks.end()) {
        networks.emplace_back(key, MatchStereo(pair.left_grey, pair.right_grey, nullptr,
                                               preset.matcher, runtime));
        cached = networks.end() - 1;
      }
      MatchReport report = cached->second;
      const auto refine_start = Clock::now();
      RefineMatches(pair.left_grey, pair.right_grey, nullptr, preset.matcher, preset.refinement, &report,
                    runtime);
      report.timing_ms.total += MillisecondsSince(refine_start);
      if (!report.engine_notice.empty()) evaluation->notices.push_back(report.engine_notice);
      matches = FromReport(preset.name, report);
    } catch (const std::exception& error) {
      evaluation->notices.push_back(preset.name + ": " + error.what());
    }
    if (p == 0) default_pixels = matches.left;
    evaluation->scores.push_back(ScoreAndCurve(matches, truth, n_edges, evaluation));
    RankedMethod ranked;
    ranked.method = preset.name;
    ranked.ranked = RankMatches(matches, truth, n_edges);
    ranked.time_ms = matches.time_ms;
    ranked.probability = true;
    evaluation->ranked.push_back(std::move(ranked));
  }
  return default_pixels;
}

// The baselines: winner-take-all ZNCC, StereoBM and StereoSGBM scored at the first preset's
// pixels; WTA ZNCC over every edge pixel (curve, and ranked by its margin) to compare precision
// at equal density; BM and SGBM ranked by sweeping their uniqueness ratio.
void EvaluateBaselines(const MiddleburyPair& pair, const EvaluationOptions& options,
                       const std::vector<Eigen::Vector2f>& edge_points,
                       const std::vector<Eigen::Vector2f>& default_pixels, const TruthView& truth,
                       int n_edges, PairEvaluation* evaluation) {
  const int d_min = static_cast<int>(pair.min_disparity);
  const int d_max = static_cast<int>(pair.max_disparity);
  evaluation->scores.push_back(ScoreAndCurve(
      WinnerTakeAllZncc(pair.left_grey, pair.right_grey, default_pixels, options.wta_zncc_window,
                        d_min, d_max),
      truth, n_edges, evaluation));
  evaluation->scores.push_back(ScoreAndCurve(
      OpenCvBlockMatching(pair.left_grey, pair.right_grey, default_pixels, false, d_min, d_max - d_min),
      truth, n_edges, evaluation));
  evaluation->scores.push_back(ScoreAndCurve(
      OpenCvBlockMatching(pair.left_grey, pair.right_grey, default_pixels, true, d_min, d_max - d_min),
      truth, n_edges, evaluation));
  MethodMatches all_edges = WinnerTakeAllZncc(pair.left_grey, pair.right_grey, edge_points,
                                              options.wta_zncc_window, d_min, d_max);
  all_edges.method = "wta-zncc (all edges)";
  evaluation->curves.emplace_back(all_edges.method, PrecisionDensityCurve(all_edges, truth, n_edges));
  RankedMethod wta;
  wta.method = "wta-zncc (margin)";
  wta.ranked = RankMatches(all_edges, truth, n_edges);
  wta.time_ms = all_edges.time_ms;
  evaluation->ranked.push_back(std::move(wta));
  const std::vector<int> ratios(std::begin(kUniquenessSweep), std::end(kUniquenessSweep));
  for (const bool semi_global : {true, false}) {
    RankedMethod sweep;
    sweep.method = semi_global ? "opencv-sgbm (sweep)" : "opencv-bm (sweep)";
    sweep.swept = true;
    const auto sweep_start = Clock::now();
    sweep.sweep = SweepUniqueness(pair.left_grey, pair.right_grey, edge_points, semi_global, d_min,
                                  d_max - d_min, truth, n_edges, ratios);
    sweep.time_ms = MillisecondsSince(sweep_start);
    evaluation->ranked.push_back(std::move(sweep));
  }
}

// A preset for the warped (unrectified) pair: gated by F and a depth range; the disparity
// network, which needs rectified rows, becomes the feature-vs-feature network with the
// preset's other settings (ZNCC data term), with a notice.
MatcherPreset UnrectifiedPreset(MatcherPreset preset, double min_depth, double max_depth,
                                PairEvaluation* evaluation) {
  preset.name += " (warped)";
  preset.matcher.candidates.rectified = false;
  preset.matcher.candidates.z_range_mm = std::make_pair(min_depth, max_depth);
  if (preset.matcher.candidates.kind == hnn::NetworkKind::kFeatureVsDisparity) {
    preset.matcher.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
    preset.matcher.candidates.zncc_peaks = false;
    preset.matcher.candidates.subpixel_peaks = false;
    preset.matcher.data_term = DataTermOptions{};  // the feature network's ZNCC
    preset.matcher.confidence = ConfidenceOptionsFor(preset.matcher.data_term);
    evaluation->notices.push_back(preset.name +
                                  ": the disparity network needs rectified rows; the warped "
                                  "run uses the feature-vs-feature network (ZNCC data term)");
  }
  return preset;
}

// The unrectified version (EvaluationOptions::warped): the right image warped by H, P2 replaced
// by H P2; the matcher sees only the calibration (epipolar gating from F, depth range from the
// disparity range with a 100 mm baseline), scored after mapping back with H.
void EvaluateWarped(const MiddleburyPair& pair, const EvaluationOptions& options,
                    const TruthView& truth, int n_edges, ocl::Runtime* runtime,
                    PairEvaluation* evaluation) {
  cv::Mat H_cv(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) H_cv.at<double>(r, c) = options.warp(r, c);
  cv::Mat right_warped;
  cv::warpPerspective(pair.right_grey, right_warped, H_cv, pair.right_grey.size(), cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT, cv::Scalar(0));
  calib::StereoCalibration calibration =
      SyntheticRectifiedCalibration(pair.left_grey.cols, pair.left_grey.rows);
  calibration.P2 = options.warp * calibration.P2;
  calibration.rectified = false;
  calibration.DeriveFromProjections();
  const double focal_baseline = calibration.P1(0, 0) * 100.0;
  const double min_depth = focal_baseline / std::max(1.0, pair.max_disparity);
  const double max_depth = focal_baseline / std::max(0.5, pair.min_disparity);
  TruthView warped_truth = truth;
  warped_truth.right_from_rectified = options.warp;
  std::vector<Eigen::Vector2f> warped_pixels;
  for (std::size_t p = 0; p < options.presets.size(); ++p) {
    const MatcherPreset preset = UnrectifiedPreset(options.presets[p], min_depth, max_depth, evaluation);
    MethodMatches matches;
    matches.method = preset.name;
    try {
      const MatchReport report =
          MatchWithPreset(pair.left_grey, right_warped, &calibration, preset, runtime);
      matches = FromReport(preset.name, report);
    } catch (const std::exception& error) {
      evaluation->notices.push_back(preset.name + ": " + error.what());
    }
    if (p == 0) warped_pixels = matches.left;
    evaluation->scores.push_back(ScoreAndCurve(matches, warped_truth, n_edges, evaluation));
  }
  if (options.baselines) {
    MethodMatches wta = WinnerTakeAllZnccAlongRay(pair.left_grey, right_warped, calibration,
                                                  warped_pixels, options.wta_zncc_window,
                                                  min_depth, max_depth);
    wta.method = "wta-zncc (warped)";
    evaluation->scores.push_back(ScoreAndCurve(wta, warped_truth, n_edges, evaluation));
  }
}

}  // namespace

PairEvaluation EvaluatePair(const MiddleburyPair& pair, const EvaluationOptions& options,
                            ocl::Runtime* runtime) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  PairEvaluation evaluation;
  // Density's denominator: every Canny edge pixel of the left image (no cap) with ground truth.
  FeatureOptions edge_options = options.presets.front().matcher.features;
  edge_options.max_features = 0;
  const FeatureReport edges = DetectFeatures(pair.left_grey, edge_options);
  evaluation.n_edges = static_cast<int>(edges.points.size());
  TruthView truth;
  truth.disparity = &pair.disparity;
  truth.nonoccluded = &pair.nonoccluded;
  for (const Eigen::Vector2f& p : edges.points) {
    if (TruthAt(truth, p)) ++evaluation.n_edges_with_truth;
  }
  const int n_edges = evaluation.n_edges_with_truth;
  DescribePair(pair, options, &evaluation);
  const std::vector<Eigen::Vector2f> default_pixels =
      EvaluatePresets(pair, options, truth, n_edges, runtime, &evaluation);
  if (options.baselines) {
    EvaluateBaselines(pair, options, edges.points, default_pixels, truth, n_edges, &evaluation);
  }
  if (options.warped) EvaluateWarped(pair, options, truth, n_edges, runtime, &evaluation);
  return evaluation;
}

EvaluationReport Evaluate(const std::vector<MiddleburyPair>& pairs, const EvaluationOptions& options,
                          ocl::Runtime* runtime) {
  const auto start = Clock::now();
  EvaluationReport report;
  for (const MiddleburyPair& pair : pairs) {
    report.pairs.push_back(EvaluatePair(pair, options, runtime));
    const PairEvaluation& evaluation = report.pairs.back();
    for (const MethodScore& score : evaluation.scores) {
      auto it = std::find_if(report.overall.begin(), report.overall.end(),
                             [&](const MethodScore& s) { return s.method == score.method; });
      if (it == report.overall.end()) {
        report.overall.push_back(score);
      } else {
        it->Add(score);
      }
    }
  }
  report.time_ms = MillisecondsSince(start);
  return report;
}

// ---- Ranked summary ---------------------------------------------------------------------

double RankedSummary::Ratio::ratio(int i) const {
  if (!hnn[i].reached || !sgbm[i].reached || !(sgbm[i].error() > 0.0)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return hnn[i].error() / sgbm[i].error();
}

namespace {

constexpr const char* kSgbmSweep = "opencv-sgbm (sweep)";

const RankedMethod* FindRanked(const PairEvaluation& pair, const std::string& method) {
  for (const RankedMethod& m : pair.ranked) {
    if (m.method == method) return &m;
  }
  return nullptr;
}

// Pools `point` into `pooled` when reached; the pooled point is reached once any pair is.
void Pool(OperatingPoint* pooled, const OperatingPoint& point) {
  if (!point.reached) return;
  pooled->Add(point);
  pooled->reached = true;
  if (pooled->n_pairs > 1 && pooled->setting != point.setting) {
    pooled->setting = "per pair";
  } else {
    pooled->setting = point.setting;
  }
}

}  // namespace

void ConfidenceCalibration::Add(const RankedMatches& ranked) {
  for (const RankedMatches::Entry& entry : ranked.entries) {
    if (!entry.nonoccluded) continue;
    const auto upper = std::upper_bound(kConfidenceBinEdges.begin() + 1, kConfidenceBinEdges.end() - 1,
                                        static_cast<double>(entry.confidence));
    const std::size_t bin = static_cast<std::size_t>(upper - kConfidenceBinEdges.begin()) - 1;
    matches[bin] += 1.0;
    wrong[bin] += entry.correct ? 0.0 : 1.0;
    confidence_sum[bin] += entry.confidence;
  }
}

void ConfidenceCalibration::Add(const ConfidenceCalibration& other) {
  for (std::size_t b = 0; b < kBins; ++b) {
    matches[b] += other.matches[b];
    wrong[b] += other.wrong[b];
    confidence_sum[b] += other.confidence_sum[b];
  }
  n_pairs += other.n_pairs;
}

double ConfidenceCalibration::Error(std::size_t bin) const {
  return matches[bin] > 0.0 ? wrong[bin] / matches[bin] : std::numeric_limits<double>::quiet_NaN();
}

double ConfidenceCalibration::MeanConfidence(std::size_t bin) const {
  return matches[bin] > 0.0 ? confidence_sum[bin] / matches[bin] : std::numeric_limits<double>::quiet_NaN();
}

namespace {

// Per probability-ranked method: each pair's calibration, then the pairs pooled per scene type
// (in the order the types first appear), then all pairs.
std::vector<ConfidenceCalibration> CalibrationTables(const EvaluationReport& report) {
  std::vector<std::string> methods, scenes;
  for (const PairEvaluation& pair : report.pairs) {
    if (std::find(scenes.begin(), scenes.end(), pair.scene) == scenes.end()) scenes.push_back(pair.scene);
    for (const RankedMethod& m : pair.ranked) {
      if (m.probability && std::find(methods.begin(), methods.end(), m.method) == methods.end()) {
        methods.push_back(m.method);
      }
    }
  }
  std::vector<ConfidenceCalibration> tables;
  for (const std::string& method : methods) {
    std::vector<ConfidenceCalibration> per_scene(scenes.size());
    ConfidenceCalibration overall;
    overall.group = "overall";
    overall.method = method;
    for (const PairEvaluation& pair : report.pairs) {
      const RankedMethod* m = FindRanked(pair, method);
      if (m == nullptr || !m->probability) continue;
      ConfidenceCalibration table;
      table.group = pair.name;
      table.method = method;
      table.n_pairs = 1;
      table.Add(m->ranked);
      tables.push_back(table);
      const std::size_t s = static_cast<std::size_t>(
          std::find(scenes.begin(), scenes.end(), pair.scene) - scenes.begin());
      per_scene[s].Add(table);
      overall.Add(table);
    }
    for (std::size_t s = 0; s < scenes.size(); ++s) {
      if (per_scene[s].n_pairs == 0) continue;
      per_scene[s].group = scenes[s];
      per_scene[s].method = method;
      tables.push_back(per_scene[s]);
    }
    tables.push_back(overall);
  }
  return tables;
}

}  // namespace

RankedSummary SummarizeRanked(const EvaluationReport& report) {
  RankedSummary summary;
  summary.calibration = CalibrationTables(report);
  std::vector<std::string> methods;
  for (const PairEvaluation& pair : report.pairs) {
    for (const RankedMethod& m : pair.ranked) {
      if (std::find(methods.begin(), methods.end(), m.method) == methods.end()) {
        methods.push_back(m.method);
      }
      RankedSummary::Row row;
      row.pair = pair.name;
      row.method = m.method;
      for (int i = 0; i < 3; ++i) row.at[i] = m.At(kTableDensities[i]);
      row.full = m.Full();
      row.full.n_pairs = 1;
      summary.rows.push_back(row);
      if (!m.swept && !m.ranked.entries.empty()) {
        RankedSummary::RankingCheck check;
        check.pair = pair.name;
        check.method = m.method;
        check.top = m.ranked.TopShare(0.25);
        check.all = m.ranked.Full();
        summary.ranking.push_back(check);
      }
    }
    // The HNN under test (first preset) against StereoSGBM's best setting at the same density.
    const RankedMethod* sgbm = FindRanked(pair, kSgbmSweep);
    if (!pair.ranked.empty() && sgbm != nullptr) {
      const RankedMethod& hnn = pair.ranked.front();
      RankedSummary::Ratio ratio;
      ratio.pair = pair.name;
      for (int i = 0; i < 3; ++i) {
        ratio.hnn[i] = hnn.At(kTableDensities[i]);
        ratio.sgbm[i] = sgbm->At(kTableDensities[i]);
      }
      ratio.hnn[3] = hnn.Full();
      ratio.sgbm[3] = sgbm->At(ratio.hnn[3].density());
      summary.ratios.push_back(ratio);
    }
    // At the first preset's own pixels: StereoSGBM at uniqueness 10 (invalid counts wrong).
    const auto sgbm_score = std::find_if(pair.scores.begin(), pair.scores.end(),
                                         [](const MethodScore& s) { return s.method == "opencv-sgbm"; });
    if (!pair.scores.empty() && sgbm_score != pair.scores.end()) {
      summary.same_pixels.push_back({pair.name, pair.scores.front().density(),
                                     1.0 - pair.scores.front().precision_1px(),
                                     1.0 - sgbm_score->precision_1px(),
                                     pair.scores.front().n_nonoccluded});
    }
  }
  const std::size_t n_pair_rows = summary.rows.size();
  for (const std::string& method : methods) {
    RankedSummary::Row overall;
    overall.pair = "overall";
    overall.method = method;
    for (std::size_t r = 0; r < n_pair_rows; ++r) {
      const RankedSummary::Row& row = summary.rows[r];
      if (row.method != method) continue;
      for (int i = 0; i < 3; ++i) Pool(&overall.at[i], row.at[i]);
      Pool(&overall.full, row.full);
    }
    summary.rows.push_back(overall);
    RankedSummary::RankingCheck check;
    check.pair = "overall";
    check.method = method;
    bool any = false;
    for (const RankedSummary::RankingCheck& c : summary.ranking) {
      if (c.method != method || c.pair == "overall") continue;
      Pool(&check.top, c.top);
      Pool(&check.all, c.all);
      any = true;
    }
    if (any) summary.ranking.push_back(check);
  }
  if (!summary.ratios.empty()) {
    // Pooled over the pairs where both reach the density.
    RankedSummary::Ratio overall;
    overall.pair = "overall";
    for (const RankedSummary::Ratio& r : summary.ratios) {
      for (int i = 0; i < 4; ++i) {
        if (!r.hnn[i].reached || !r.sgbm[i].reached) continue;
        Pool(&overall.hnn[i], r.hnn[i]);
        Pool(&overall.sgbm[i], r.sgbm[i]);
      }
    }
    summary.ratios.push_back(overall);
  }
  if (!summary.same_pixels.empty()) {
    const auto sgbm_score = std::find_if(report.overall.begin(), report.overall.end(),
                                         [](const MethodScore& s) { return s.method == "opencv-sgbm"; });
    if (!report.overall.empty() && sgbm_score != report.overall.end()) {
      summary.same_pixels.push_back({"overall", report.overall.front().density(),
                                     1.0 - report.overall.front().precision_1px(),
                                     1.0 - sgbm_score->precision_1px(),
                                     report.overall.front().n_nonoccluded});
    }
  }
  return summary;
}

namespace {

nlohmann::json PointJson(const OperatingPoint& p) {
  if (!p.reached) return nullptr;  // n/a: not reached
  nlohmann::json json{{"density", p.density()},   {"precision_1px", p.precision()},
                      {"error_1px", p.error()},   {"kept", p.kept},
                      {"nonoccluded", p.nonoccluded}, {"correct_1px", p.correct},
                      {"n_edges_with_truth", p.n_edges_with_truth}};
  if (!p.setting.empty()) json["setting"] = p.setting;
  if (p.n_pairs > 0) json["n_pairs"] = p.n_pairs;
  return json;
}

std::string DensityKey(double density) {
  char text[16];
  std::snprintf(text, sizeof text, "%.2f", density);
  return text;
}

nlohmann::json RankedJson(const EvaluationReport& report) {
  const RankedSummary summary = SummarizeRanked(report);
  nlohmann::json json;
  json["definitions"] = {
      {"density", "kept matches at left Canny edge pixels with ground truth / those edge pixels; "
                  "an invalid output (no disparity) is not kept"},
      {"precision_1px", "kept non-occluded matches within 1 px of the true right point / kept "
                        "non-occluded matches; error_1px = 1 - precision_1px"},
      {"ranked", "a ranked method keeps its most confident matches down to the density (matches "
                 "of equal confidence that the cut splits count with the share kept); HNN presets "
                 "by StereoMatch::confidence, wta-zncc (margin) over all edge pixels by best ZNCC "
                 "minus the best ZNCC more than 1 px from the winner"},
      {"swept", "opencv-sgbm (5x5, MODE_HH 8 paths, P1 8*25, P2 32*25, disp12MaxDiff 1, speckle "
                "100/2) and opencv-bm (15x15, disp12MaxDiff 1) at each uniqueness ratio; at density "
                "D: the setting with the highest precision among those whose density >= D, that "
                "setting's full point (not cut down to D); full: the densest setting"},
      {"overall", "counts summed over the pairs that reach the density (n_pairs), i.e. "
                  "edge-weighted; swept methods take each pair's best setting"},
      {"hnn_vs_sgbm", "error of the first preset / error of opencv-sgbm's best setting reaching "
                      "the same density (25/50/75 % and the preset's full density); overall pools "
                      "the pairs where both reach it"},
      {"ranking_check", "error of the top 25 % of a ranked method's kept matches (at pixels with "
                        "ground truth) by confidence / error of all of them"},
      {"same_pixels", "at the first preset's matched pixels: its error vs opencv-sgbm at "
                      "uniqueness 10 with the left-right check, an invalid output counted wrong"},
      {"confidence_calibration", "an HNN preset's non-occluded matches at pixels with ground truth "
                                 "binned by confidence [low, high): their count, error_1px and mean "
                                 "confidence (calibrated: error_1px near 1 - mean_confidence); per "
                                 "pair, per scene type (indoor, outdoor) and overall"}};
  nlohmann::json rows = nlohmann::json::array();
  for (const RankedSummary::Row& row : summary.rows) {
    nlohmann::json at = nlohmann::json::object();
    for (int i = 0; i < 3; ++i) at[DensityKey(kTableDensities[i])] = PointJson(row.at[i]);
    rows.push_back({{"pair", row.pair}, {"method", row.method}, {"at", at}, {"full", PointJson(row.full)}});
  }
  json["table"] = rows;
  nlohmann::json ratios = nlohmann::json::array();
  auto number = [](double value) -> nlohmann::json {
    return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
  };
  for (const RankedSummary::Ratio& r : summary.ratios) {
    nlohmann::json entry{{"pair", r.pair}};
    for (int i = 0; i < 4; ++i) {
      const std::string key = i < 3 ? DensityKey(kTableDensities[i]) : "hnn_full";
      entry[key] = {{"hnn", PointJson(r.hnn[i])}, {"sgbm", PointJson(r.sgbm[i])},
                    {"ratio", number(r.ratio(i))}};
    }
    ratios.push_back(entry);
  }
  json["hnn_vs_sgbm"] = ratios;
  nlohmann::json checks = nlohmann::json::array();
  for (const RankedSummary::RankingCheck& c : summary.ranking) {
    checks.push_back({{"pair", c.pair}, {"method", c.method}, {"top_25", PointJson(c.top)},
                      {"all", PointJson(c.all)}, {"ratio", c.ratio()}});
  }
  json["ranking_check"] = checks;
  nlohmann::json same = nlohmann::json::array();
  for (const RankedSummary::SamePixels& s : summary.same_pixels) {
    same.push_back({{"pair", s.pair}, {"density", s.density}, {"hnn_error_1px", s.hnn_error},
                    {"sgbm_error_1px", s.sgbm_error}, {"n_nonoccluded", s.n}, {"ratio", s.ratio()}});
  }
  json["same_pixels"] = same;
  nlohmann::json calibration = nlohmann::json::array();
  for (const ConfidenceCalibration& c : summary.calibration) {
    nlohmann::json bins = nlohmann::json::array();
    for (std::size_t b = 0; b < ConfidenceCalibration::kBins; ++b) {
      bins.push_back({{"low", kConfidenceBinEdges[b]}, {"high", kConfidenceBinEdges[b + 1]},
                      {"matches", c.matches[b]}, {"error_1px", number(c.Error(b))},
                      {"mean_confidence", number(c.MeanConfidence(b))}});
    }
    calibration.push_back({{"group", c.group}, {"method", c.method}, {"n_pairs", c.n_pairs}, {"bins", bins}});
  }
  json["confidence_calibration"] = calibration;
  return json;
}

nlohmann::json PairRankedJson(const PairEvaluation& pair) {
  nlohmann::json methods = nlohmann::json::array();
  for (const RankedMethod& m : pair.ranked) {
    nlohmann::json entry{{"method", m.method}, {"swept", m.swept}, {"time_ms", m.time_ms},
                         {"full", PointJson(m.Full())}};
    nlohmann::json curve = nlohmann::json::array();
    for (const CurvePoint& c : m.Curve()) curve.push_back({c.density, c.precision_1px});
    entry["curve"] = curve;
    if (m.swept) {
      nlohmann::json sweep = nlohmann::json::array();
      for (const SweepPoint& s : m.sweep) {
        nlohmann::json point = PointJson(s.point);
        point["uniqueness_ratio"] = s.uniqueness_ratio;
        sweep.push_back(point);
      }
      entry["sweep"] = sweep;
    }
    methods.push_back(entry);
  }
  return methods;
}

}  // namespace

nlohmann::json EvaluationJson(const EvaluationReport& report) {
  auto score_json = [](const MethodScore& s) {
    return nlohmann::json{{"method", s.method},
                          {"n_matches", s.n_matches},
                          {"n_with_truth", s.n_with_truth},
                          {"n_nonoccluded", s.n_nonoccluded},
                          {"n_occluded", s.n_occluded},
                          {"n_invalid", s.n_invalid},
                          {"n_edges_with_truth", s.n_edges_with_truth},
                          {"precision_1px", s.precision_1px()},
                          {"precision_2px", s.precision_2px()},
                          {"occluded_precision_1px", s.occluded_precision_1px()},
                          {"density", s.density()},
                          {"mean_error_px", s.mean_error_px()},
                          {"time_ms", s.time_ms}};
  };
  nlohmann::json json;
  json["definitions"] = {
      {"precision_1px", "non-occluded matches with ground truth within 1 px of the true right point"},
      {"precision_2px", "the same within 2 px"},
      {"occluded_precision_1px", "matches at occluded pixels (mask or left-right check) within 1 px"},
      {"density", "matches at pixels with ground truth / left Canny edge pixels with ground truth"},
      {"baselines", "wta-zncc, opencv-bm and opencv-sgbm are read at the left pixels the first "
                    "method matched; an invalid output counts as wrong"}};
  json["pairs"] = nlohmann::json::array();
  for (const PairEvaluation& pair : report.pairs) {
    nlohmann::json p{{"name", pair.name},
                     {"layout", pair.layout},
                     {"scene", pair.scene},
                     {"occlusion_source", pair.occlusion_source},
                     {"width", pair.width},
                     {"height", pair.height},
                     {"min_disparity", pair.min_disparity},
                     {"max_disparity", pair.max_disparity},
                     {"n_edges", pair.n_edges},
                     {"n_edges_with_truth", pair.n_edges_with_truth},
                     {"notices", pair.notices}};
    p["methods"] = nlohmann::json::array();
    for (const MethodScore& s : pair.scores) p["methods"].push_back(score_json(s));
    if (!pair.ranked.empty()) p["ranked"] = PairRankedJson(pair);
    p["curves"] = nlohmann::json::object();
    for (const auto& [method, curve] : pair.curves) {
      nlohmann::json points = nlohmann::json::array();
      for (const CurvePoint& c : curve) points.push_back({c.density, c.precision_1px});
      p["curves"][method] = points;
    }
    json["pairs"].push_back(p);
  }
  json["overall"] = nlohmann::json::array();
  for (const MethodScore& s : report.overall) json["overall"].push_back(score_json(s));
  const bool ranked = std::any_of(report.pairs.begin(), report.pairs.end(),
                                  [](const PairEvaluation& p) { return !p.ranked.empty(); });
  if (ranked) json["ranked"] = RankedJson(report);
  json["time_ms"] = report.time_ms;
  return json;
}

std::string EvaluationMarkdown(const EvaluationReport& report) {
  std::string text =
      "| pair | method | matches | density % | precision 1 px % | precision 2 px % | occluded "
      "(1 px %) | invalid | time ms |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
  auto row = [&](const std::string& pair, const MethodScore& s) {
    char line[512];
    std::snprintf(line, sizeof line, "| %s | %s | %d | %s | %s | %s | %d (%s) | %d | %.0f |\n",
                  pair.c_str(), s.method.c_str(), s.n_matches, Percent(s.density()).c_str(),
                  Percent(s.precision_1px()).c_str(), Percent(s.precision_2px()).c_str(), s.n_occluded,
                  Percent(s.occluded_precision_1px()).c_str(), s.n_invalid, s.time_ms);
    text += line;
  };
  for (const PairEvaluation& pair : report.pairs) {
    for (const MethodScore& s : pair.scores) row(pair.name, s);
  }
  for (const MethodScore& s : report.overall) row("**overall**", s);
  const bool ranked = std::any_of(report.pairs.begin(), report.pairs.end(),
                                  [](const PairEvaluation& p) { return !p.ranked.empty(); });
  if (ranked) text += "\n" + RankedMarkdown(report);
  return text;
}

namespace {

using common::Fixed;

std::string PairLabel(const std::string& pair) { return pair == "overall" ? "**overall**" : pair; }

// "4.2", "4.2 (u 30)" for a swept method, "4.2 (4/5 pairs)" for a pooled point short of pairs,
// "n/a" when not reached.
std::string ErrorCell(const OperatingPoint& p, int n_pairs_total) {
  if (!p.reached) return "n/a";
  std::string cell = Percent(p.error());
  std::string note;
  if (p.setting.rfind("uniqueness ", 0) == 0) note = "u " + p.setting.substr(11);
  if (p.setting == "per pair") note = "u per pair";
  if (n_pairs_total > 0 && p.n_pairs > 0 && p.n_pairs < n_pairs_total) {
    note += std::string(note.empty() ? "" : ", ") + std::to_string(p.n_pairs) + "/" +
            std::to_string(n_pairs_total) + " pairs";
  }
  return note.empty() ? cell : cell + " (" + note + ")";
}

std::string RatioCell(const RankedSummary::Ratio& r, int i, int n_pairs_total) {
  const double ratio = r.ratio(i);
  if (!std::isfinite(ratio)) return "n/a";
  std::string cell = Fixed(ratio, 2);
  if (n_pairs_total > 0 && r.hnn[i].n_pairs > 0 && r.hnn[i].n_pairs < n_pairs_total) {
    cell += " (" + std::to_string(r.hnn[i].n_pairs) + "/" + std::to_string(n_pairs_total) + " pairs)";
  }
  return cell;
}

}  // namespace

std::string RankedMarkdown(const EvaluationReport& report) {
  const RankedSummary summary = SummarizeRanked(report);
  const int n_pairs = static_cast<int>(report.pairs.size());
  std::string text =
      "Ranked by confidence: error rate % (kept non-occluded matches more than 1 px off) when each "
      "method keeps its most confident matches down to a density (share of left Canny edge pixels "
      "with ground truth). Swept methods: the best uniqueness setting reaching that density "
      "(u = its ratio). n/a = the method does not reach it.\n\n"
      "| pair | method | 25 % | 50 % | 75 % | full: density % | full: error % |\n"
      "|---|---|---:|---:|---:|---:|---:|\n";
  for (const RankedSummary::Row& row : summary.rows) {
    const int total = row.pair == "overall" ? n_pairs : 0;
    text += "| " + PairLabel(row.pair) + " | " + row.method + " | " + ErrorCell(row.at[0], total) +
            " | " + ErrorCell(row.at[1], total) + " | " + ErrorCell(row.at[2], total) + " | " +
            (row.full.reached ? Percent(row.full.density()) : "n/a") + " | " +
            ErrorCell(row.full, total) + " |\n";
  }
  if (!summary.ratios.empty()) {
    const std::string hnn = report.pairs.front().ranked.front().method;
    text += "\nError of " + hnn +
            " / error of opencv-sgbm's best uniqueness setting reaching the same density "
            "(below 1: the HNN is better):\n\n"
            "| pair | 25 % | 50 % | 75 % | at the HNN's full density | HNN full density % |\n"
            "|---|---:|---:|---:|---:|---:|\n";
    for (const RankedSummary::Ratio& r : summary.ratios) {
      const int total = r.pair == "overall" ? n_pairs : 0;
      text += "| " + PairLabel(r.pair) + " | " + RatioCell(r, 0, total) + " | " + RatioCell(r, 1, total) +
              " | " + RatioCell(r, 2, total) + " | " + RatioCell(r, 3, total) + " | " +
              (r.hnn[3].reached ? Percent(r.hnn[3].density()) : "n/a") + " |\n";
    }
  }
  if (!summary.ranking.empty()) {
    text += "\nRanking check: error % of the top 25 % of a method's matches by confidence against "
            "all of them (the confidence ranks when top / all is well below 1):\n\n"
            "| pair | method | matches with truth | error all % | error top 25 % | top / all |\n"
            "|---|---|---:|---:|---:|---:|\n";
    for (const RankedSummary::RankingCheck& c : summary.ranking) {
      text += "| " + PairLabel(c.pair) + " | " + c.method + " | " +
              std::to_string(static_cast<long long>(std::llround(c.all.kept))) + " | " +
              Percent(c.all.error()) + " | " + Percent(c.top.error()) + " | " +
              Fixed(c.ratio(), 2) + " |\n";
    }
  }
  if (!summary.same_pixels.empty()) {
    const std::string hnn = report.pairs.front().scores.front().method;
    text += "\nAt " + hnn + "'s own pixels (its full density): its error % against opencv-sgbm "
            "(uniqueness 10, left-right check) at the same pixels, invalid output counted wrong:\n\n"
            "| pair | density % | HNN error % | SGBM error % | HNN / SGBM |\n"
            "|---|---:|---:|---:|---:|\n";
    for (const RankedSummary::SamePixels& s : summary.same_pixels) {
      text += "| " + PairLabel(s.pair) + " | " + Percent(s.density) + " | " + Percent(s.hnn_error) +
              " | " + Percent(s.sgbm_error) + " | " + Fixed(s.ratio(), 2) + " |\n";
    }
  }
  if (!summary.calibration.empty()) {
    text += "\nConfidence calibration: error % of the non-occluded matches in each confidence bin "
            "(matches in brackets); a confidence that holds has about 1 - c of them wrong, on "
            "every scene type:\n\n| pair or scene | method |";
    std::string rule = "|---|---|";
    for (std::size_t b = 0; b < ConfidenceCalibration::kBins; ++b) {
      text += " " + Fixed(kConfidenceBinEdges[b], 2) + "-" + Fixed(kConfidenceBinEdges[b + 1], 2) + " |";
      rule += "---:|";
    }
    text += "\n" + rule + "\n";
    for (const ConfidenceCalibration& c : summary.calibration) {
      const bool pooled = c.group == "overall" || c.group == "indoor" || c.group == "outdoor";
      text += "| " + (pooled ? "**" + c.group + "** (" + std::to_string(c.n_pairs) + ")" : c.group) +
              " | " + c.method + " |";
      for (std::size_t b = 0; b < ConfidenceCalibration::kBins; ++b) {
        text += c.matches[b] > 0.0 ? " " + Percent(c.Error(b)) + " (" +
                                         std::to_string(static_cast<long long>(c.matches[b])) + ") |"
                                   : " - |";
      }
      text += "\n";
    }
  }
  return text;
}

}  // namespace hnnstereo::vision
