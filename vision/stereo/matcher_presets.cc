#include "vision/stereo/matcher_presets.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "common/timing.h"
#include "vision/stereo/correlation.h"

namespace hnnstereo::vision {
namespace {

// Pixel centres along the image line a x + b y + c = 0 inside a width x height image, one per
// pixel step along the line's longer axis.
std::vector<Eigen::Vector2f> PixelsOnLine(const Eigen::Vector3d& line, int width, int height) {
  std::vector<Eigen::Vector2f> pixels;
  const double a = line.x(), b = line.y(), c = line.z();
  if (std::abs(b) >= std::abs(a)) {  // mostly horizontal: step in x
    if (b == 0.0) return pixels;
    for (int x = 0; x < width; ++x) {
      const double y = -(a * x + c) / b;
      if (y >= 0.0 && y <= height - 1.0) pixels.emplace_back(static_cast<float>(x), static_cast<float>(y));
    }
  } else {
    for (int y = 0; y < height; ++y) {
      const double x = -(b * y + c) / a;
      if (x >= 0.0 && x <= width - 1.0) pixels.emplace_back(static_cast<float>(x), static_cast<float>(y));
    }
  }
  return pixels;
}

}  // namespace

std::string RefinementOptions::Check() const {
  if (!(left_right_tolerance_px >= 0.0)) {
    return "left_right_tolerance_px must be >= 0 (got " + std::to_string(left_right_tolerance_px) + ")";
  }
  if (!(subpixel_min_offset_px >= 0.0 && subpixel_min_offset_px <= 0.5)) {
    return "subpixel_min_offset_px must be in [0, 0.5] (got " +
           std::to_string(subpixel_min_offset_px) + ")";
  }
  return second_chance.Check();
}

std::string MatcherPreset::Check() const {
  if (auto error = matcher.Check(); !error.empty()) return error;
  return refinement.Check();
}

MatcherPreset ThesisPreset() {
  MatcherPreset preset;
  preset.name = "hnn-thesis";
  // The in-class defaults of MatcherOptions are the thesis's values (THESIS.md section 3).
  preset.matcher = MatcherOptions{};
  preset.matcher.energy.objective = hnn::Objective::kThesis;  // eq. 6.7, additive
  preset.matcher.decode.method = hnn::DecodeMethod::kThesisPruning;
  return preset;
}

namespace {

// The previous default (feature-vs-feature network, geometry x similarity, left-right check).
MatcherPreset FeatureNetworkPreset() {
  MatcherPreset preset;
  preset.name = "hnn-geometry-lr";
  preset.matcher = MatcherOptions{};
  // The pairwise term as geometric consistency times similarity (THESIS.md section 3 hint), not
  // eq. 6.7's additive mix (docs/accuracy.md).
  preset.matcher.energy.objective = hnn::Objective::kGeometrySimilarity;
  // The left-right check raises precision; no sub-pixel fit (Tsukuba's integer ground truth
  // loses with it).
  preset.refinement.left_right_check = true;
  return preset;
}

}  // namespace

MatcherPreset AccurateDefaultPreset() {
  MatcherPreset preset = FeatureNetworkPreset();
  preset.name = "hnn-default";
  // The feature-vs-disparity network (columns = disparity levels: a left edge pixel may take
  // any disparity, as winner-take-all does, not only the positions of right Canny pixels), with
  // candidates at the K best local maxima of the similarity along the row, at integer
  // disparities. Rectified pairs only (unrectified ones fall back to the feature network).
  preset.matcher.candidates.kind = hnn::NetworkKind::kFeatureVsDisparity;
  preset.matcher.candidates.rectified = true;
  preset.matcher.candidates.zncc_peaks = true;
  // K = 3 peaks and a 14 px support radius, measured with the census term below
  // (docs/accuracy.md).
  preset.matcher.candidates.top_k = 3;
  preset.matcher.energy.support_radius_px = 14.0;
  // The census data term (5 x 5 census, Hamming costs summed over 13 x 13 with adaptive
  // support weights, gamma 20) for the candidates' peaks, the biases, the similarity in the
  // compatibilities and the left-right check: fewer wrong matches at depth edges than ZNCC,
  // whose window is ruled by the occluding contour.
  preset.matcher.data_term.kind = DataTermOptions::Kind::kCensus;
  preset.matcher.data_term.census_window = 5;
  preset.matcher.data_term.aggregation_window = 13;
  preset.matcher.data_term.support_gamma = 20.0;
  preset.matcher.confidence = CensusConfidenceOptions();  // fitted for it (docs/accuracy.md)
  // Unrectified pairs (eval --warped, match/pick with a calibration): snap the right point onto
  // its epipolar line, then the parabola along the line (docs/accuracy.md, the warped pairs).
  preset.refinement.epipolar_snap = true;
  preset.refinement.epipolar_subpixel = true;
  // Rectified pairs: the parabola sub-pixel fit of the census similarity, leaving a match whose
  // vertex lies within 0.1 px of its whole pixel as it is (integer ground truth such as
  // Tsukuba's loses without that floor; docs/accuracy.md).
  preset.refinement.subpixel = true;
  preset.refinement.subpixel_min_offset_px = 0.1;
  // A second network over the features left unmatched, its candidates from the matched
  // neighbours' disparities (vision/stereo/second_chance.h; docs/matching.md).
  preset.refinement.second_chance.enabled = true;
  // The matches settle long before the energy does (docs/engine.md): the run stops when every
  // row's decision has settled (checked every 2 steps, twice in a row).
  preset.matcher.dynamics.stop_rule = hnn::DynamicsOptions::StopRule::kDecisions;
  preset.matcher.dynamics.energy_interval = 2;
  preset.matcher.dynamics.stable_checks = 2;
  return preset;
}

std::vector<MatcherPreset> AllPresets() {
  // Ablations, to measure each change on the same data (docs/accuracy.md).
  // Feature-vs-feature network: without refinement, and with the left-right check (the
  // previous default).
  MatcherPreset geometry_lr = FeatureNetworkPreset();
  MatcherPreset geometry = geometry_lr;
  geometry.name = "hnn-geometry";
  geometry.refinement = RefinementOptions{};
  // Feature-vs-disparity network with every disparity level competing for the top K.
  // (K = 8 and an 8 px support radius, as measured in docs/accuracy.md.)
  MatcherPreset disparity = AccurateDefaultPreset();
  disparity.name = "hnn-disparity";
  disparity.matcher.candidates.zncc_peaks = false;
  disparity.matcher.candidates.top_k = 8;
  disparity.matcher.energy.support_radius_px = 8.0;
  disparity.matcher.data_term = DataTermOptions{};  // ZNCC, as measured
  disparity.matcher.confidence = ConfidenceOptions{};
  disparity.refinement.subpixel = false;  // as measured
  disparity.refinement.subpixel_min_offset_px = 0.0;
  // ZNCC peaks with parabola sub-pixel candidate disparities (K = 8, 8 px, as measured).
  MatcherPreset subpixel = disparity;
  subpixel.name = "hnn-disparity-subpixel";
  subpixel.matcher.candidates.zncc_peaks = true;
  subpixel.matcher.candidates.subpixel_peaks = true;
  return {AccurateDefaultPreset(), ThesisPreset(), geometry, geometry_lr, disparity, subpixel};
}

std::optional<MatcherPreset> FindPreset(const std::string& name) {
  for (MatcherPreset& preset : AllPresets()) {
    if (preset.name == name) return preset;
  }
  return std::nullopt;
}

namespace {

// ZNCC of two equally sized CV_32F patches; 0 for a flat patch (no evidence either way).
double PatchZncc(const cv::Mat& a, const cv::Mat& b) {
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(a, mean_a, std_a);
  cv::meanStdDev(b, mean_b, std_b);
  if (std_a[0] <= 1e-6 || std_b[0] <= 1e-6) return 0.0;
  const cv::Mat da = a - mean_a[0], db = b - mean_b[0];
  return da.dot(db) / (static_cast<double>(a.total()) * std_a[0] * std_b[0]);
}

// The epipolar snap and sub-pixel fit (RefineAlongEpipolarLine) of every match: each match
// alone, in parallel, without the ZNCC tables.
void RefineAllAlongEpipolarLines(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                 const Eigen::Matrix3d& F, int zncc_window, bool subpixel,
                                 std::vector<StereoMatch>* matches_out) {
  std::vector<StereoMatch>& matches = *matches_out;
  cv::parallel_for_(cv::Range(0, static_cast<int>(matches.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      RefineAlongEpipolarLine(left_grey, right_grey, F, zncc_window, subpixel,
                              &matches[static_cast<std::size_t>(i)]);
    }
  });
}

// The left-right check and the row sub-pixel fit of one match, on the similarity tables.
struct TableRefiner {
  const cv::Mat& left_grey;
  const calib::StereoCalibration* calibration;
  const ZnccMatcher& zncc;
  const RefinementOptions& refinement;
  bool rectified;
  int d_min, d_max;  // the disparity levels searched on a rectified pair
  const std::vector<DisparityBand>& bands;  // check bands per left feature, or none

  // Whether the match is kept; refines its right x in place (`reverse_profile`: scratch).
  bool Refine(StereoMatch& match, std::vector<float>& reverse_profile) const {
    if (refinement.left_right_check && !PassesLeftRightCheck(match, reverse_profile)) return false;
    if (refinement.subpixel && rectified) SubpixelAlongRow(&match);
    return true;
  }

 private:
  // The reverse search: the best left point for this right point (winner-take-all ZNCC) lies
  // within left_right_tolerance_px of the match's (+ 0.5 px across the row).
  bool PassesLeftRightCheck(const StereoMatch& match, std::vector<float>& reverse_profile) const {
    float best = -std::numeric_limits<float>::infinity();
    Eigen::Vector2f best_left(std::numeric_limits<float>::quiet_NaN(), 0.0f);
    if (rectified) {
      // Every disparity's ZNCC at once (vision/correlation.h), then the same scan; over the
      // match's check band on a coarse-to-fine pair (MatchReport::check_bands).
      int lo = d_min, hi = d_max;
      if (!bands.empty() && match.left_index >= 0 &&
          static_cast<std::size_t>(match.left_index) < bands.size()) {
        lo = std::max(lo, bands[static_cast<std::size_t>(match.left_index)].lo);
        hi = std::min(hi, bands[static_cast<std::size_t>(match.left_index)].hi);
      }
      reverse_profile.resize(static_cast<std::size_t>(std::max(0, hi - lo + 1)));
      if (hi >= lo) zncc.ReverseRowProfile(match.right, lo, hi, reverse_profile.data());
      for (int d = lo; d <= hi; ++d) {
        const Eigen::Vector2f left(std::round(match.right.x()) + static_cast<float>(d),
                                   std::round(match.right.y()));
        if (left.x() > static_cast<float>(left_grey.cols - 1)) break;
        const float score = reverse_profile[static_cast<std::size_t>(d - lo)];
        if (score > best) best = score, best_left = left;
      }
    } else {
      const Eigen::Vector3d line =
          calibration->F.transpose() * Eigen::Vector3d(match.right.x(), match.right.y(), 1.0);
      for (const Eigen::Vector2f& left : PixelsOnLine(line, left_grey.cols, left_grey.rows)) {
        const float score = zncc.ReverseSimilarity(left, match.right);
        if (score > best) best = score, best_left = left;
      }
    }
    return std::abs(best_left.x() - match.left.x()) <= refinement.left_right_tolerance_px &&
           std::abs(best_left.y() - match.left.y()) <= refinement.left_right_tolerance_px + 0.5f;
  }

  // Parabola through the similarity at x - 1, x, x + 1: vertex offset
  // (c- - c+) / (2 (c- - 2 c0 + c+)), applied when at least subpixel_min_offset_px.
  void SubpixelAlongRow(StereoMatch* match) const {
    const Eigen::Vector2f step(1.0f, 0.0f);
    const Eigen::Vector2f right(std::round(match->right.x()), std::round(match->right.y()));
    double before = 0.0, centre = 0.0, after = 0.0;
    const float d = match->left.x() - right.x();
    if (right.y() == match->left.y() && d == std::round(d) && std::abs(d) < 1e6f) {
      // The three as one row profile (one set of support weights for the census term; the
      // same values as pair by pair, vision/correlation.h): disparities d + 1, d, d - 1.
      float three[3];
      const int level = static_cast<int>(d);
      zncc.RowProfile(match->left, level - 1, level + 1, three);
      before = three[2], centre = three[1], after = three[0];
    } else {
      before = zncc(match->left, right - step);
      centre = zncc(match->left, right);
      after = zncc(match->left, right + step);
    }
    const double curvature = before - 2.0 * centre + after;
    if (curvature < 0.0) {
      const double offset = std::clamp(0.5 * (before - after) / curvature, -0.5, 0.5);
      if (std::abs(offset) >= refinement.subpixel_min_offset_px) {
        match->right.x() = right.x() + static_cast<float>(offset);
      }
    }
  }
};

// Runs `refiner` on every match in parallel (its scratch per thread), then keeps the kept ones
// in their order.
void RefineOnTables(const TableRefiner& refiner, std::vector<StereoMatch>* matches_out) {
  std::vector<StereoMatch>& matches = *matches_out;
  std::vector<unsigned char> keep(matches.size(), 0);
  cv::parallel_for_(cv::Range(0, static_cast<int>(matches.size())), [&](const cv::Range& range) {
    std::vector<float> reverse_profile;
    for (int i = range.start; i < range.end; ++i) {
      const auto k = static_cast<std::size_t>(i);
      keep[k] = refiner.Refine(matches[k], reverse_profile) ? 1 : 0;
    }
  });
  std::vector<StereoMatch> kept;
  kept.reserve(matches.size());
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (keep[k]) kept.push_back(matches[k]);
  }
  matches = std::move(kept);
}


// The second chance (vision/stereo/second_chance.h) after `first_pass` checked and refined the
// network's matches: the retried features' winners pass the same check, over the levels each
// searched, and the same sub-pixel fit, then join the matches with their weaker confidence.
void GiveSecondChance(const TableRefiner& first_pass, const MatcherOptions& matcher,
                      const SecondChanceOptions& options, ocl::Runtime* runtime,
                      MatchReport* report) {
  std::vector<StereoMatch> retried;
  std::vector<DisparityBand> searched;
  RetryUnmatchedFeatures(first_pass.zncc, report->left_features, report->matches, matcher, options,
                         runtime, &retried, &searched, &report->second_chance);
  const TableRefiner second_pass{first_pass.left_grey, first_pass.calibration, first_pass.zncc,
                                 first_pass.refinement, first_pass.rectified, first_pass.d_min,
                                 first_pass.d_max, searched};
  RefineOnTables(second_pass, &retried);
  report->second_chance.matched =
      AddSecondChanceMatches(std::move(retried), matcher.confidence, options,
                             std::ldexp(1.0f, -report->coarse_to_fine.levels), &report->matches);
}

}  // namespace

void RefineAlongEpipolarLine(const cv::Mat& left_grey, const cv::Mat& right_grey,
                             const Eigen::Matrix3d& F, int window, bool subpixel,
                             StereoMatch* match) {
  Eigen::Vector3d line = F * Eigen::Vector3d(match->left.x(), match->left.y(), 1.0);
  const double norm = line.head<2>().norm();
  if (!(norm > 0.0) || !line.allFinite()) return;
  line /= norm;
  const Eigen::Vector2d right = match->right.cast<double>();
  const double distance = line.head<2>().dot(right) + line.z();
  Eigen::Vector2d foot = right - distance * line.head<2>();
  if (subpixel) {
    // Parabola through ZNCC at foot - u, foot, foot + u (u: unit step along the line), with the
    // right windows bilinearly interpolated (cv::getRectSubPix), the left window at its pixel.
    const Eigen::Vector2d along(-line.y(), line.x());
    const cv::Size size(window, window);
    cv::Mat left_patch;
    cv::getRectSubPix(left_grey, size, cv::Point2f(match->left.x(), match->left.y()), left_patch,
                      CV_32F);
    double score[3];
    for (int k = -1; k <= 1; ++k) {
      const Eigen::Vector2d at = foot + static_cast<double>(k) * along;
      cv::Mat right_patch;
      cv::getRectSubPix(right_grey, size, cv::Point2f(static_cast<float>(at.x()),
                                                      static_cast<float>(at.y())),
                        right_patch, CV_32F);
      score[k + 1] = PatchZncc(left_patch, right_patch);
    }
    const double curvature = score[0] - 2.0 * score[1] + score[2];
    if (curvature < 0.0) {
      foot += std::clamp(0.5 * (score[0] - score[2]) / curvature, -0.5, 0.5) * along;
    }
  }
  match->right = foot.cast<float>();
}

void RefineMatches(const cv::Mat& left_grey, const cv::Mat& right_grey,
                   const calib::StereoCalibration* calibration, const MatcherOptions& matcher,
                   const RefinementOptions& refinement, MatchReport* report,
                   ocl::Runtime* runtime) {
  if (auto error = refinement.Check(); !error.empty()) throw std::invalid_argument(error);
  // Taken out of the report: its tables are only needed here, and a kept report stays small.
  std::shared_ptr<const ZnccMatcher> similarity = std::move(report->similarity);
  const bool rectified = matcher.candidates.rectified || calibration == nullptr;
  // Not behind a memory-budget fit: the features it left out were never tried.
  const bool second_chance = refinement.second_chance.enabled && rectified &&
                             matcher.candidates.kind == hnn::NetworkKind::kFeatureVsDisparity &&
                             !matcher.candidates.dense && !report->memory_fit.applied;
  if (!refinement.left_right_check && !refinement.subpixel && !refinement.epipolar_snap &&
      !refinement.epipolar_subpixel && !second_chance) {
    return;
  }
  if (!rectified && calibration == nullptr) {
    throw std::invalid_argument("RefineMatches: an unrectified pair needs its calibration");
  }
  // The epipolar snap and sub-pixel fit run after the left-right check.
  const bool along_epipolar_lines =
      !rectified && (refinement.epipolar_snap || refinement.epipolar_subpixel);
  if (refinement.left_right_check || (refinement.subpixel && rectified) || second_chance) {
    // The matcher's own similarity tables when they are the ones asked for (MatchStereo's, on
    // the same pair), else built here.
    if (!similarity || similarity->window() != matcher.zncc_window ||
        !(similarity->data_term() == matcher.data_term) ||
        similarity->right_width() != right_grey.cols) {
      similarity = std::make_shared<const ZnccMatcher>(left_grey, right_grey, matcher.zncc_window,
                                                       matcher.data_term);
    }
    const TableRefiner refiner{left_grey, calibration, *similarity, refinement, rectified,
                               static_cast<int>(std::ceil(matcher.candidates.min_disparity)),
                               static_cast<int>(std::floor(matcher.candidates.max_disparity)),
                               report->check_bands};
    RefineOnTables(refiner, &report->matches);
    if (second_chance) {
      const auto start = std::chrono::steady_clock::now();
      GiveSecondChance(refiner, matcher, refinement.second_chance, runtime, report);
      report->timing_ms.second_chance = common::MillisecondsSince(start);
    }
  }
  if (along_epipolar_lines) {
    RefineAllAlongEpipolarLines(left_grey, right_grey, calibration->F, matcher.zncc_window,
                                refinement.epipolar_subpixel, &report->matches);
  }
}

MatchReport MatchWithPreset(const cv::Mat& left_grey, const cv::Mat& right_grey,
                            const calib::StereoCalibration* calibration, const MatcherPreset& preset,
                            ocl::Runtime* runtime) {
  if (auto error = preset.Check(); !error.empty()) throw std::invalid_argument(error);
  MatchReport report = MatchStereo(left_grey, right_grey, calibration, preset.matcher, runtime);
  const auto start = std::chrono::steady_clock::now();
  RefineMatches(left_grey, right_grey, calibration, preset.matcher, preset.refinement, &report,
                runtime);
  report.timing_ms.total +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace hnnstereo::vision
