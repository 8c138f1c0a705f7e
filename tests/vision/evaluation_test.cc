// Scoring, baselines and refinements on seeded synthetic pairs with known disparity.
#include "vision/eval/evaluation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <random>

#include <opencv2/imgproc.hpp>

#include "vision/eval/eval_plot.h"
#include "vision/stereo/matcher_presets.h"

namespace hnnstereo::vision {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// A textured left image and its right view at a constant disparity (x_r = x_l - d), blurred so
// that ZNCC varies smoothly (sub-pixel fits need that).
struct SyntheticPair {
  cv::Mat left, right, disparity, nonoccluded;
};

SyntheticPair MakePair(double disparity, unsigned seed, int width = 160, int height = 120) {
  std::mt19937 random(seed);
  cv::Mat noise(height, width + 64, CV_8U);
  cv::theRNG().state = seed;
  cv::randu(noise, 0, 256);
  cv::Mat texture;
  cv::GaussianBlur(noise, texture, cv::Size(0, 0), 1.2);
  cv::normalize(texture, texture, 0, 255, cv::NORM_MINMAX);
  SyntheticPair pair;
  pair.left = texture(cv::Rect(32, 0, width, height)).clone();
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, -disparity - 32, 0, 1, 0);
  cv::warpAffine(texture, pair.right, shift, cv::Size(width, height), cv::INTER_CUBIC);
  pair.disparity = cv::Mat(height, width, CV_32F, cv::Scalar(static_cast<float>(disparity)));
  pair.nonoccluded = cv::Mat(height, width, CV_8U, cv::Scalar(255));
  return pair;
}

TruthView ViewOf(const SyntheticPair& pair) {
  TruthView truth;
  truth.disparity = &pair.disparity;
  truth.nonoccluded = &pair.nonoccluded;
  return truth;
}

TEST(ScoreMatches, CountsEachCaseOnce) {
  cv::Mat disparity(10, 20, CV_32F, cv::Scalar(4.0f));
  disparity.at<float>(0, 0) = kNaN;  // no truth
  cv::Mat visible(10, 20, CV_8U, cv::Scalar(255));
  visible.at<std::uint8_t>(1, 10) = 0;  // occluded
  TruthView truth{&disparity, &visible};
  MethodMatches m;
  m.method = "test";
  m.left = {{0, 0}, {10, 2}, {10, 3}, {10, 4}, {10, 5}, {10, 1}};
  m.right = {{0, 0}, {6, 2}, {7.5f, 3}, {3, 4}, {kNaN, kNaN}, {6, 1}};
  const MethodScore s = ScoreMatches(m, truth, 10);
  EXPECT_EQ(s.n_matches, 6);
  EXPECT_EQ(s.n_with_truth, 5);
  EXPECT_EQ(s.n_occluded, 1);
  EXPECT_EQ(s.n_nonoccluded, 4);
  EXPECT_EQ(s.correct_1px, 1);  // (6,2) exact; (7.5,3) 1.5 px; (3,4) 3 px; invalid
  EXPECT_EQ(s.correct_2px, 2);
  EXPECT_EQ(s.n_invalid, 1);
  EXPECT_EQ(s.occluded_correct_1px, 1);
  EXPECT_DOUBLE_EQ(s.precision_1px(), 0.25);
  EXPECT_DOUBLE_EQ(s.density(), 0.5);
  EXPECT_NEAR(s.mean_error_px(), (0.0 + 1.5 + 3.0) / 3.0, 1e-9);
  m.right.pop_back();
  EXPECT_THROW(ScoreMatches(m, truth, 10), std::invalid_argument);
}

TEST(ScoreMatches, MapsWarpedRightPointsBackWithH) {
  cv::Mat disparity(50, 50, CV_32F, cv::Scalar(3.0f));
  cv::Mat visible(50, 50, CV_8U, cv::Scalar(255));
  TruthView truth{&disparity, &visible};
  truth.right_from_rectified = EvaluationOptions::DefaultWarp();
  MethodMatches m;
  for (int i = 10; i < 40; i += 5) {
    const Eigen::Vector2f left(static_cast<float>(i), static_cast<float>(i / 2));
    const Eigen::Vector3d warped =
        truth.right_from_rectified * Eigen::Vector3d(left.x() - 3.0, left.y(), 1.0);
    m.left.push_back(left);
    m.right.push_back(warped.hnormalized().cast<float>());
  }
  const MethodScore s = ScoreMatches(m, truth, 6);
  EXPECT_EQ(s.correct_1px, 6);
  EXPECT_LT(s.mean_error_px(), 1e-3);
}

TEST(PrecisionDensityCurve, MostConfidentFirstAndEndsAtTheWhole) {
  cv::Mat disparity(10, 100, CV_32F, cv::Scalar(2.0f));
  cv::Mat visible(10, 100, CV_8U, cv::Scalar(255));
  TruthView truth{&disparity, &visible};
  MethodMatches m;
  for (int i = 0; i < 40; ++i) {
    const bool good = i < 20;
    m.left.emplace_back(static_cast<float>(10 + i), 5.0f);
    m.right.emplace_back(static_cast<float>(10 + i - (good ? 2 : 9)), 5.0f);
    m.confidence.push_back(good ? 1.0f - 0.01f * static_cast<float>(i) : 0.1f);
  }
  const auto curve = PrecisionDensityCurve(m, truth, 80, 4);
  ASSERT_GE(curve.size(), 4u);
  EXPECT_DOUBLE_EQ(curve.front().precision_1px, 1.0);
  EXPECT_DOUBLE_EQ(curve.back().precision_1px, 0.5);
  EXPECT_DOUBLE_EQ(curve.back().density, 0.5);
  for (std::size_t i = 1; i < curve.size(); ++i) EXPECT_GE(curve[i].density, curve[i - 1].density);
}

std::vector<Eigen::Vector2f> GridPoints(int width, int height, int margin, int step) {
  std::vector<Eigen::Vector2f> points;
  for (int y = margin; y < height - margin; y += step)
    for (int x = margin + 24; x < width - margin; x += step)
      points.emplace_back(static_cast<float>(x), static_cast<float>(y));
  return points;
}

TEST(Baselines, WinnerTakeAllZnccFindsAConstantShift) {
  const SyntheticPair pair = MakePair(7.0, 11);
  const auto points = GridPoints(pair.left.cols, pair.left.rows, 8, 7);
  const MethodMatches wta = WinnerTakeAllZncc(pair.left, pair.right, points, 7, 0, 16);
  const MethodScore s = ScoreMatches(wta, ViewOf(pair), static_cast<int>(points.size()));
  EXPECT_EQ(s.n_nonoccluded, static_cast<int>(points.size()));
  EXPECT_GT(s.precision_1px(), 0.97);
}

TEST(Baselines, StereoSgbmAndBmFindAConstantShiftAndInvalidCountsWrong) {
  const SyntheticPair pair = MakePair(5.0, 12);
  const auto points = GridPoints(pair.left.cols, pair.left.rows, 8, 7);
  for (bool semi_global : {false, true}) {
    const MethodMatches dense = OpenCvBlockMatching(pair.left, pair.right, points, semi_global, 0, 16);
    const MethodScore s = ScoreMatches(dense, ViewOf(pair), static_cast<int>(points.size()));
    EXPECT_GT(s.precision_1px(), 0.9) << dense.method;
    EXPECT_EQ(s.n_nonoccluded - s.correct_2px >= s.n_invalid, true) << dense.method;
  }
  // Pixels left of numDisparities have no output: NaN, scored as wrong.
  const MethodMatches edge =
      OpenCvBlockMatching(pair.left, pair.right, {{2.0f, 60.0f}}, true, 0, 16);
  EXPECT_FALSE(edge.right.front().allFinite());
  EXPECT_EQ(ScoreMatches(edge, ViewOf(pair), 1).n_invalid, 1);
}

TEST(Refinement, SubpixelParabolaReducesTheErrorOfAFractionalShift) {
  const SyntheticPair pair = MakePair(6.4, 13);
  MatchReport report;
  for (const Eigen::Vector2f& p : GridPoints(pair.left.cols, pair.left.rows, 10, 6)) {
    report.matches.push_back({p, Eigen::Vector2f(p.x() - 6.0f, p.y()), 1.0f, 0, 0});
  }
  auto mean_error = [&](const MatchReport& r) {
    double sum = 0.0;
    for (const StereoMatch& m : r.matches) sum += std::abs(m.right.x() - (m.left.x() - 6.4));
    return sum / static_cast<double>(r.matches.size());
  };
  const double before = mean_error(report);
  MatcherOptions matcher;
  matcher.candidates.rectified = true;
  RefinementOptions refinement;
  refinement.subpixel = true;
  RefineMatches(pair.left, pair.right, nullptr, matcher, refinement, &report);
  EXPECT_NEAR(before, 0.4, 1e-4);
  EXPECT_LT(mean_error(report), 0.2);
}

// The floor of the sub-pixel fit (hnn-default: 0.1 px): a match moves by at least the floor or
// not at all, so on a whole-pixel shift some keep their integer disparity exactly (where the
// parabola through three samples of a peak leans less than 0.1 px) and none ends far off; a
// shift of 6.4 px still moves most; for both data terms.
TEST(Refinement, SubpixelFloorKeepsWholePixelMatchesAndMovesFractionalOnes) {
  for (const bool census : {false, true}) {
    MatcherOptions matcher;
    matcher.candidates.rectified = true;
    if (census) matcher.data_term.kind = DataTermOptions::Kind::kCensus;
    RefinementOptions refinement;
    refinement.subpixel = true;
    refinement.subpixel_min_offset_px = 0.1;
    ASSERT_TRUE(refinement.Check().empty());
    const SyntheticPair whole = MakePair(6.0, 13);
    MatchReport report;
    for (const Eigen::Vector2f& p : GridPoints(whole.left.cols, whole.left.rows, 10, 6)) {
      report.matches.push_back({p, Eigen::Vector2f(p.x() - 6.0f, p.y()), 1.0f, 0, 0});
    }
    const MatchReport before = report;
    RefineMatches(whole.left, whole.right, nullptr, matcher, refinement, &report);
    ASSERT_EQ(report.matches.size(), before.matches.size());
    int kept = 0;
    for (std::size_t i = 0; i < report.matches.size(); ++i) {
      const float move = std::abs(report.matches[i].right.x() - before.matches[i].right.x());
      kept += move == 0.0f;
      EXPECT_TRUE(move == 0.0f || (move >= 0.1f - 1e-5f && move <= 0.5f))
          << "census " << census << " moved " << move;
    }
    EXPECT_GT(kept, 0) << "census " << census;
    const SyntheticPair fractional = MakePair(6.4, 13);
    int moved = 0;
    RefineMatches(fractional.left, fractional.right, nullptr, matcher, refinement, &report);
    for (std::size_t i = 0; i < report.matches.size(); ++i) {
      moved += report.matches[i].right.x() != before.matches[i].right.x();
    }
    EXPECT_GT(moved, static_cast<int>(report.matches.size()) / 2) << "census " << census;
  }
  RefinementOptions bad;
  bad.subpixel_min_offset_px = 0.7;
  EXPECT_FALSE(bad.Check().empty());
}

TEST(Refinement, EpipolarSnapAndSubpixelAlongTheLineOnAWarpedPair) {
  // Rectified pair at d = 6.4, right image then warped by H (3 deg rotation, a shift): the true
  // right point is H (x - 6.4, y) and F = H^-T F_rect with F_rect: y_r = y_l.
  const SyntheticPair pair = MakePair(6.4, 21, 200, 160);
  Eigen::Matrix3d H;
  const double a = 3.0 * M_PI / 180.0;
  H << std::cos(a), -std::sin(a), 6.0, std::sin(a), std::cos(a), -4.0, 0.0, 0.0, 1.0;
  cv::Mat H_cv(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) H_cv.at<double>(r, c) = H(r, c);
  cv::Mat right_warped;
  cv::warpPerspective(pair.right, right_warped, H_cv, pair.right.size(), cv::INTER_CUBIC);
  Eigen::Matrix3d F_rect;
  F_rect << 0, 0, 0, 0, 0, -1, 0, 1, 0;
  const Eigen::Matrix3d F = H.inverse().transpose() * F_rect;
  MatchReport report;
  std::vector<Eigen::Vector2f> truth;
  for (const Eigen::Vector2f& p : GridPoints(pair.left.cols, pair.left.rows, 24, 12)) {
    const Eigen::Vector3d t = H * Eigen::Vector3d(p.x() - 6.4, p.y(), 1.0);
    truth.emplace_back(static_cast<float>(t.x() / t.z()), static_cast<float>(t.y() / t.z()));
    // The matcher hands back a right edge pixel: the true point rounded to the pixel grid.
    report.matches.push_back({p, Eigen::Vector2f(std::round(truth.back().x()),
                                                 std::round(truth.back().y())), 1.0f, 0, 0});
  }
  auto errors = [&](const MatchReport& r) {
    double sum = 0.0, off_line = 0.0;
    for (std::size_t i = 0; i < r.matches.size(); ++i) {
      sum += (r.matches[i].right - truth[i]).norm();
      Eigen::Vector3d line = F * Eigen::Vector3d(r.matches[i].left.x(), r.matches[i].left.y(), 1);
      line /= line.head<2>().norm();
      off_line += std::abs(line.dot(Eigen::Vector3d(r.matches[i].right.x(), r.matches[i].right.y(), 1)));
    }
    const double n = static_cast<double>(r.matches.size());
    return std::make_pair(sum / n, off_line / n);
  };
  calib::StereoCalibration calibration;
  calibration.F = F;
  MatcherOptions matcher;
  matcher.candidates.rectified = false;
  RefinementOptions snap;
  snap.epipolar_snap = true;
  MatchReport snapped = report;
  RefineMatches(pair.left, right_warped, &calibration, matcher, snap, &snapped);
  const auto [before, before_off_line] = errors(report);
  const auto [after_snap, snap_off_line] = errors(snapped);
  EXPECT_GT(before, 0.3);
  EXPECT_GT(before_off_line, 0.15);
  EXPECT_LT(snap_off_line, 1e-4) << "on the epipolar line";
  EXPECT_LT(after_snap, before);
  RefinementOptions subpixel = snap;
  subpixel.epipolar_subpixel = true;
  MatchReport refined = report;
  RefineMatches(pair.left, right_warped, &calibration, matcher, subpixel, &refined);
  const auto [after_subpixel, subpixel_off_line] = errors(refined);
  EXPECT_LT(subpixel_off_line, 1e-4);
  EXPECT_LT(after_subpixel, 0.6 * after_snap) << "the parabola along the line";
}

TEST(Refinement, LeftRightCheckDropsInconsistentMatches) {
  const SyntheticPair pair = MakePair(5.0, 14);
  MatchReport report;
  const auto points = GridPoints(pair.left.cols, pair.left.rows, 10, 9);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const float wrong = (i % 2 == 0) ? 0.0f : 9.0f;  // every other match is 9 px off
    report.matches.push_back({points[i], Eigen::Vector2f(points[i].x() - 5.0f - wrong, points[i].y()),
                              1.0f, 0, 0});
  }
  MatcherOptions matcher;
  matcher.candidates.rectified = true;
  matcher.candidates.max_disparity = 20;
  RefinementOptions refinement;
  refinement.left_right_check = true;
  RefineMatches(pair.left, pair.right, nullptr, matcher, refinement, &report);
  const std::size_t expected_kept = (points.size() + 1) / 2;
  EXPECT_NEAR(static_cast<double>(report.matches.size()), static_cast<double>(expected_kept),
              0.1 * static_cast<double>(expected_kept));
  for (const StereoMatch& m : report.matches) EXPECT_NEAR(m.left.x() - m.right.x(), 5.0f, 1.0f);
  refinement.left_right_tolerance_px = -1.0;
  EXPECT_THROW(RefineMatches(pair.left, pair.right, nullptr, matcher, refinement, &report),
               std::invalid_argument);
}

TEST(Presets, ThesisIsTheInClassDefaultsAndBothAreValid) {
  const MatcherPreset thesis = ThesisPreset();
  EXPECT_EQ(thesis.matcher.energy.objective, hnn::Objective::kThesis);
  EXPECT_EQ(thesis.matcher.decode.method, hnn::DecodeMethod::kThesisPruning);
  EXPECT_FALSE(thesis.refinement.left_right_check);
  EXPECT_EQ(thesis.matcher.energy.W1, hnn::EnergyOptions{}.W1);
  EXPECT_TRUE(thesis.Check().empty());
  EXPECT_TRUE(AccurateDefaultPreset().Check().empty());
  EXPECT_TRUE(FindPreset("hnn-default").has_value());
  EXPECT_FALSE(FindPreset("nope").has_value());
}

TEST(EvaluatePair, SyntheticPairEndToEndOnTheCpuEngine) {
  const SyntheticPair synthetic = MakePair(6.0, 15, 200, 120);
  MiddleburyPair pair;
  pair.name = "synthetic";
  pair.left_grey = synthetic.left;
  pair.right_grey = synthetic.right;
  pair.disparity = synthetic.disparity;
  pair.nonoccluded = synthetic.nonoccluded;
  pair.max_disparity = 16;
  EvaluationOptions options;
  for (MatcherPreset& preset : options.presets) {
    preset.matcher.engine = hnn::EngineKind::kCpu;
    preset.matcher.features.max_features = 600;
    preset.matcher.features.canny_low = 20;
    preset.matcher.features.canny_high = 60;
  }
  options.warped = true;
  const PairEvaluation evaluation = EvaluatePair(pair, options, nullptr);
  ASSERT_EQ(evaluation.scores.size(), 2u + 3u + 2u + 1u) << ::testing::PrintToString(evaluation.notices);
  EXPECT_GT(evaluation.n_edges_with_truth, 600);
  const MethodScore& hnn = evaluation.scores[0];
  EXPECT_GT(hnn.n_matches, 200);
  EXPECT_GT(hnn.precision_1px(), 0.9);
  // The baselines are read at exactly the HNN's pixels.
  EXPECT_EQ(evaluation.scores[2].n_matches, hnn.n_matches);
  EXPECT_EQ(evaluation.scores[4].method, "opencv-sgbm");
  // The warped run matches from the calibration alone and is scored back through H.
  const MethodScore& warped = evaluation.scores[5];
  EXPECT_EQ(warped.method, "hnn-default (warped)");
  EXPECT_GT(warped.n_matches, 100);
  EXPECT_GT(warped.precision_1px(), 0.8);

  // Ranked by confidence over all edge pixels: the presets, WTA by its margin, the two sweeps.
  ASSERT_EQ(evaluation.ranked.size(), 2u + 3u);
  EXPECT_EQ(evaluation.ranked[0].method, "hnn-default");
  EXPECT_EQ(evaluation.ranked[2].method, "wta-zncc (margin)");
  EXPECT_EQ(evaluation.ranked[3].method, "opencv-sgbm (sweep)");
  EXPECT_EQ(evaluation.ranked[4].method, "opencv-bm (sweep)");
  EXPECT_EQ(evaluation.ranked[3].sweep.size(), std::size(kUniquenessSweep));
  EXPECT_NEAR(evaluation.ranked[0].Full().kept, hnn.n_with_truth, 1e-9);
  EXPECT_GT(evaluation.ranked[2].Full().density(), 0.9) << "WTA answers at every edge pixel";
  // The synthetic pair has no occlusion mask: the evaluation says so.
  EXPECT_NE(::testing::PrintToString(evaluation.notices).find("no occlusion mask"), std::string::npos);

  EvaluationReport report;
  report.pairs = {evaluation, evaluation};
  const nlohmann::json json = EvaluationJson(report);
  EXPECT_EQ(json["pairs"].size(), 2u);
  EXPECT_NE(EvaluationMarkdown(report).find("| synthetic | hnn-default |"), std::string::npos);
  EXPECT_NE(EvaluationMarkdown(report).find("| **overall** | opencv-sgbm (sweep) |"), std::string::npos);
  const cv::Mat ranked_plot = DrawRankedPlot(evaluation);
  EXPECT_EQ(ranked_plot.type(), CV_8UC3);
  EXPECT_GE(ranked_plot.cols, 800);
  const cv::Mat plot = DrawPrecisionDensityPlot(report);
  EXPECT_EQ(plot.type(), CV_8UC3);
  EXPECT_GT(plot.cols, 400);
}

// ---- Ranked by confidence ---------------------------------------------------------------

// 400 matches at d = 3 on a 10x100 truth, every third one 5 px off; `confidence` per match.
MethodMatches RankedFixture(const std::function<float(int, bool)>& confidence) {
  MethodMatches m;
  m.method = "fixture";
  for (int i = 0; i < 400; ++i) {
    const bool good = i % 3 != 0;
    const float x = static_cast<float>(10 + i % 80), y = static_cast<float>(i / 80);
    m.left.emplace_back(x, y);
    m.right.emplace_back(x - (good ? 3.0f : 8.0f), y);
    m.confidence.push_back(confidence(i, good));
  }
  return m;
}

struct RankedTruth {
  cv::Mat disparity = cv::Mat(10, 100, CV_32F, cv::Scalar(3.0f));
  cv::Mat visible = cv::Mat(10, 100, CV_8U, cv::Scalar(255));
  TruthView view() const { return TruthView{&disparity, &visible}; }
};

TEST(RankedMatches, ThePerfectRankingPassesTheCheckRandomAndConstantOnesDoNot) {
  const RankedTruth truth;
  std::mt19937 random(7);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  const RankedMatches perfect = RankMatches(
      RankedFixture([](int, bool good) { return good ? 1.0f : 0.0f; }), truth.view(), 800);
  const RankedMatches shuffled =
      RankMatches(RankedFixture([&](int, bool) { return uniform(random); }), truth.view(), 800);
  const RankedMatches constant =
      RankMatches(RankedFixture([](int, bool) { return 1.0f; }), truth.view(), 800);
  for (const RankedMatches* r : {&perfect, &shuffled, &constant}) {
    EXPECT_EQ(r->entries.size(), 400u);
    EXPECT_NEAR(r->Full().error(), 134.0 / 400.0, 1e-9);
    EXPECT_NEAR(r->Full().density(), 0.5, 1e-12);
  }
  // Acceptance form: error(top 25 %) <= 0.5 x error(all).
  auto ratio = [](const RankedMatches& r) { return r.TopShare(0.25).error() / r.Full().error(); };
  EXPECT_DOUBLE_EQ(ratio(perfect), 0.0);
  EXPECT_GT(ratio(shuffled), 0.6);
  // Equal confidences are never ordered by chance: a cut through them keeps their average.
  EXPECT_NEAR(ratio(constant), 1.0, 1e-9);
  EXPECT_NEAR(constant.TopShare(0.25).kept, 100.0, 1e-9);
  // An inverted ranking is worse than none.
  const RankedMatches inverted = RankMatches(
      RankedFixture([](int, bool good) { return good ? 0.0f : 1.0f; }), truth.view(), 800);
  EXPECT_GT(ratio(inverted), 2.0);
}

TEST(RankedMatches, CutsAtADensityAndSaysWhenItIsNotReached) {
  const RankedTruth truth;
  // Confidence falls with i: the first 200 (density 25 % of 800) hold 66 wrong ones (i % 3 == 0).
  MethodMatches m = RankedFixture([](int i, bool) { return 1.0f - 0.001f * static_cast<float>(i); });
  m.left.emplace_back(500.0f, 5.0f);  // outside the truth: ignored
  m.right.emplace_back(497.0f, 5.0f);
  m.confidence.push_back(2.0f);
  m.left.emplace_back(50.0f, 5.0f);  // invalid output: not kept
  m.right.emplace_back(kNaN, kNaN);
  m.confidence.push_back(3.0f);
  const RankedMatches ranked = RankMatches(m, truth.view(), 800);
  ASSERT_EQ(ranked.entries.size(), 400u);
  const OperatingPoint quarter = ranked.At(0.25);
  EXPECT_TRUE(quarter.reached);
  EXPECT_NEAR(quarter.kept, 200.0, 1e-9);
  EXPECT_NEAR(quarter.correct, 200.0 - 67.0, 1e-9);  // i = 0, 3, ..., 198: 67 wrong
  EXPECT_NEAR(quarter.density(), 0.25, 1e-12);
  EXPECT_TRUE(ranked.At(0.5).reached);
  EXPECT_FALSE(ranked.At(0.51).reached);
  const auto curve = ranked.Curve(10);
  ASSERT_EQ(curve.size(), 10u);
  EXPECT_NEAR(curve.back().density, 0.5, 1e-12);
  EXPECT_THROW(RankMatches(MethodMatches{"x", {{1, 1}}, {}, {}, 0.0}, truth.view(), 1),
               std::invalid_argument);
  // A method without a single match (e.g. a preset that failed) reaches nothing, not 100 % error.
  const RankedMatches none = RankMatches(MethodMatches{}, truth.view(), 800);
  EXPECT_FALSE(none.Full().reached);
  EXPECT_FALSE(none.At(0.25).reached);
  EXPECT_TRUE(none.Curve().empty());
}

SweepPoint Setting(int ratio, double density, double precision) {
  SweepPoint s;
  s.uniqueness_ratio = ratio;
  s.point.n_edges_with_truth = 1000;
  s.point.kept = 1000.0 * density;
  s.point.nonoccluded = s.point.kept;
  s.point.correct = precision * s.point.nonoccluded;
  s.point.reached = true;
  return s;
}

TEST(SweepLookup, TheBestSettingReachingADensityIsTheMostPreciseOfTheDenseEnoughOnes) {
  const std::vector<SweepPoint> sweep = {Setting(0, 0.90, 0.80), Setting(10, 0.70, 0.90),
                                         Setting(30, 0.50, 0.95), Setting(60, 0.20, 0.97)};
  EXPECT_EQ(BestSettingReaching(sweep, 0.25).setting, "uniqueness 30");
  EXPECT_NEAR(BestSettingReaching(sweep, 0.25).precision(), 0.95, 1e-12);
  EXPECT_NEAR(BestSettingReaching(sweep, 0.25).density(), 0.50, 1e-12) << "not cut down to D";
  EXPECT_EQ(BestSettingReaching(sweep, 0.10).setting, "uniqueness 60");
  EXPECT_EQ(BestSettingReaching(sweep, 0.50).setting, "uniqueness 30");
  EXPECT_EQ(BestSettingReaching(sweep, 0.51).setting, "uniqueness 10");
  EXPECT_EQ(BestSettingReaching(sweep, 0.75).setting, "uniqueness 0");
  EXPECT_FALSE(BestSettingReaching(sweep, 0.95).reached);
  EXPECT_EQ(DensestSetting(sweep).setting, "uniqueness 0");
  // Not monotone: a denser setting that is also more precise wins.
  const std::vector<SweepPoint> odd = {Setting(0, 0.90, 0.80), Setting(5, 0.80, 0.99),
                                       Setting(10, 0.70, 0.90)};
  EXPECT_EQ(BestSettingReaching(odd, 0.25).setting, "uniqueness 5");
  EXPECT_FALSE(BestSettingReaching({}, 0.25).reached);
}

TEST(SweepUniqueness, StereoSgbmAndBmLoseDensityAsTheUniquenessRatioGrows) {
  // Low contrast and independent noise in both views, so that many pixels are ambiguous.
  SyntheticPair pair = MakePair(6.0, 31, 200, 150);
  cv::theRNG().state = 99;
  for (cv::Mat* view : {&pair.left, &pair.right}) {
    cv::Mat noise(view->size(), CV_16S), noisy;
    cv::randn(noise, 0, 6);
    view->convertTo(noisy, CV_16S, 0.2, 100);
    noisy += noise;
    noisy.convertTo(*view, CV_8U);
  }
  const auto points = GridPoints(pair.left.cols, pair.left.rows, 6, 2);
  const int n = static_cast<int>(points.size());
  const std::vector<int> ratios(std::begin(kUniquenessSweep), std::end(kUniquenessSweep));
  for (const bool semi_global : {true, false}) {
    const auto sweep =
        SweepUniqueness(pair.left, pair.right, points, semi_global, 0, 32, ViewOf(pair), n, ratios);
    ASSERT_EQ(sweep.size(), ratios.size());
    for (std::size_t i = 1; i < sweep.size(); ++i) {
      EXPECT_EQ(sweep[i].uniqueness_ratio, ratios[i]);
      EXPECT_LE(sweep[i].point.density(), sweep[i - 1].point.density() + 0.01)
          << (semi_global ? "sgbm" : "bm") << " at uniqueness " << ratios[i];
    }
    EXPECT_GT(sweep.front().point.density(), sweep.back().point.density() + 0.05)
        << (semi_global ? "sgbm" : "bm");
    EXPECT_GT(sweep.front().point.precision(), 0.8) << (semi_global ? "sgbm" : "bm");
    // Stricter settings keep surer matches.
    EXPECT_GE(sweep.back().point.precision() + 0.01, sweep.front().point.precision());
  }
}

TEST(Baselines, WinnerTakeAllMarginIsSmallOnARepeatedPatternAndLargeOnTexture) {
  const SyntheticPair textured = MakePair(7.0, 41);
  cv::Mat stripes(120, 160, CV_8U);
  for (int y = 0; y < stripes.rows; ++y)
    for (int x = 0; x < stripes.cols; ++x)
      stripes.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(128 + 100 * std::sin(x * 2 * M_PI / 6.0));
  const auto points = GridPoints(160, 120, 12, 9);
  const MethodMatches on_texture = WinnerTakeAllZncc(textured.left, textured.right, points, 7, 0, 24);
  const MethodMatches on_stripes = WinnerTakeAllZncc(stripes, stripes, points, 7, 0, 24);
  double texture_margin = 0.0, stripe_margin = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_GE(on_texture.confidence[i], 0.0f);
    EXPECT_LE(on_texture.confidence[i], 2.0f);
    texture_margin += on_texture.confidence[i];
    stripe_margin += on_stripes.confidence[i];
  }
  texture_margin /= static_cast<double>(points.size());
  stripe_margin /= static_cast<double>(points.size());
  EXPECT_GT(texture_margin, 0.2);
  EXPECT_LT(stripe_margin, 0.05);
}

PairEvaluation HandMadePair(const std::string& name, const std::vector<SweepPoint>& sgbm,
                            const std::function<float(int, bool)>& hnn_confidence) {
  static const RankedTruth truth;
  PairEvaluation pair;
  pair.name = name;
  RankedMethod hnn;
  hnn.method = "hnn-default";
  hnn.ranked = RankMatches(RankedFixture(hnn_confidence), truth.view(), 800);
  RankedMethod sweep;
  sweep.method = "opencv-sgbm (sweep)";
  sweep.swept = true;
  sweep.sweep = sgbm;
  for (SweepPoint& s : sweep.sweep) {  // the same densities over this pair's 800 edge pixels
    s.point.n_edges_with_truth = 800;
    s.point.kept *= 0.8;
    s.point.nonoccluded *= 0.8;
    s.point.correct *= 0.8;
  }
  pair.ranked = {hnn, sweep};
  return pair;
}

TEST(SummarizeRanked, PoolsCountsOverPairsAndComparesAtTheSameDensity) {
  const std::vector<SweepPoint> sgbm = {Setting(0, 0.80, 0.80), Setting(30, 0.30, 0.90)};
  EvaluationReport report;
  report.pairs = {HandMadePair("a", sgbm, [](int, bool good) { return good ? 1.0f : 0.0f; }),
                  HandMadePair("b", {Setting(0, 0.40, 0.70)}, [](int, bool) { return 0.5f; })};
  const RankedSummary summary = SummarizeRanked(report);
  // 2 pairs x 2 methods + 2 overall rows.
  ASSERT_EQ(summary.rows.size(), 6u);
  const RankedSummary::Row& overall_hnn = summary.rows[4];
  EXPECT_EQ(overall_hnn.pair, "overall");
  EXPECT_EQ(overall_hnn.method, "hnn-default");
  EXPECT_EQ(overall_hnn.full.n_pairs, 2);
  EXPECT_NEAR(overall_hnn.full.kept, 800.0, 1e-9);
  EXPECT_NEAR(overall_hnn.full.density(), 0.5, 1e-12);
  // At 25 %: pair a perfect (0 wrong of 200), pair b constant (1/3 of 200 wrong).
  EXPECT_NEAR(overall_hnn.at[0].error(), (0.0 + 200.0 * 134.0 / 400.0) / 400.0, 1e-9);
  // SGBM: pair a's best setting at 25 % is uniqueness 30; pair b reaches only 40 %.
  const RankedSummary::Row& overall_sgbm = summary.rows[5];
  EXPECT_EQ(overall_sgbm.at[0].n_pairs, 2);
  EXPECT_EQ(overall_sgbm.at[0].setting, "per pair");
  EXPECT_EQ(overall_sgbm.at[1].n_pairs, 1);
  EXPECT_EQ(overall_sgbm.at[2].n_pairs, 1);
  ASSERT_EQ(summary.ratios.size(), 3u);
  EXPECT_NEAR(summary.ratios[0].ratio(0), 0.0, 1e-12);
  // At the HNN's full density (50 %), pair a's SGBM answer is uniqueness 0 (80 %, error 20 %).
  EXPECT_EQ(summary.ratios[0].sgbm[3].setting, "uniqueness 0");
  EXPECT_NEAR(summary.ratios[0].ratio(3), (134.0 / 400.0) / 0.2, 1e-9);
  EXPECT_FALSE(std::isfinite(summary.ratios[1].ratio(3))) << "pair b's SGBM never reaches 50 %";
  // Overall at full density pools only pair a.
  EXPECT_EQ(summary.ratios[2].hnn[3].n_pairs, 1);
  // Ranking check: perfect on a, none on b, pooled overall.
  ASSERT_EQ(summary.ranking.size(), 3u);
  EXPECT_DOUBLE_EQ(summary.ranking[0].ratio(), 0.0);
  EXPECT_NEAR(summary.ranking[1].ratio(), 1.0, 1e-9);
  EXPECT_EQ(summary.ranking[2].pair, "overall");
  EXPECT_NEAR(summary.ranking[2].ratio(), 0.5, 1e-9);

  const std::string markdown = RankedMarkdown(report);
  EXPECT_NE(markdown.find("| pair | method | 25 % | 50 % | 75 % | full: density % | full: error % |"),
            std::string::npos);
  EXPECT_NE(markdown.find("| a | opencv-sgbm (sweep) | 10.0 (u 30) | 20.0 (u 0) | 20.0 (u 0) | 80.0 | 20.0 (u 0) |"),
            std::string::npos) << markdown;
  EXPECT_NE(markdown.find("| b | hnn-default | 33.5 | 33.5 | n/a | 50.0 | 33.5 |"), std::string::npos)
      << markdown;
  EXPECT_NE(markdown.find("(1/2 pairs)"), std::string::npos) << markdown;
  const nlohmann::json json = EvaluationJson(report);
  ASSERT_TRUE(json.contains("ranked"));
  EXPECT_EQ(json["ranked"]["table"].size(), 6u);
  EXPECT_TRUE(json["ranked"]["table"][1]["at"]["0.75"].is_object());
  EXPECT_TRUE(json["ranked"]["table"][3]["at"]["0.75"].is_null());
  EXPECT_EQ(json["pairs"][0]["ranked"][1]["sweep"].size(), 2u);
  const cv::Mat plot = DrawRankedPlot(report.pairs[0]);
  EXPECT_GE(plot.cols, 800);
}

// A pair whose HNN preset kept `entries` (confidence, non-occluded, correct) as a probability.
PairEvaluation CalibrationPair(const std::string& name, const std::string& scene,
                               const std::vector<RankedMatches::Entry>& entries) {
  PairEvaluation pair;
  pair.name = name;
  pair.scene = scene;
  RankedMethod hnn;
  hnn.method = "hnn-default";
  hnn.probability = true;
  hnn.ranked.entries = entries;
  hnn.ranked.n_edges_with_truth = static_cast<int>(entries.size());
  RankedMethod wta;  // a margin, not a probability: never binned
  wta.method = "wta-zncc (margin)";
  wta.ranked.entries = {{1.5f, true, false}};
  pair.ranked = {hnn, wta};
  return pair;
}

TEST(ConfidenceCalibration, BinsNonOccludedMatchesPerPairPerSceneAndOverall) {
  EvaluationReport report;
  // Indoor pair: 4 matches at 0.995 (1 wrong), 2 at 0.6 (both wrong), 1 occluded (not binned).
  report.pairs.push_back(CalibrationPair("indoor_a", "indoor",
                                         {{0.995f, true, true},  {0.995f, true, true},
                                          {0.995f, true, true},  {0.995f, true, false},
                                          {0.6f, true, false},   {0.6f, true, false},
                                          {0.97f, false, false}}));
  // Outdoor pair: 2 at 0.995 (both wrong), 1 at exactly 0.5 (bin [0.5, 0.8)), 1 at 1.0 (last bin).
  report.pairs.push_back(CalibrationPair("eth3d_x", "outdoor",
                                         {{0.995f, true, false}, {0.995f, true, false},
                                          {0.5f, true, true},    {1.0f, true, true}}));
  const RankedSummary summary = SummarizeRanked(report);
  // hnn-default only: two pairs, indoor, outdoor, overall.
  ASSERT_EQ(summary.calibration.size(), 5u);
  const ConfidenceCalibration& a = summary.calibration[0];
  EXPECT_EQ(a.group, "indoor_a");
  EXPECT_EQ(a.method, "hnn-default");
  EXPECT_DOUBLE_EQ(a.matches[5], 4.0);
  EXPECT_DOUBLE_EQ(a.Error(5), 0.25);
  EXPECT_DOUBLE_EQ(a.matches[1], 2.0);
  EXPECT_DOUBLE_EQ(a.Error(1), 1.0);
  EXPECT_NEAR(a.MeanConfidence(1), 0.6, 1e-6);
  EXPECT_DOUBLE_EQ(a.matches[4], 0.0) << "the occluded match is not binned";
  EXPECT_TRUE(std::isnan(a.Error(0)));
  const ConfidenceCalibration& outdoor = summary.calibration[3];
  EXPECT_EQ(outdoor.group, "outdoor");
  EXPECT_EQ(outdoor.n_pairs, 1);
  EXPECT_DOUBLE_EQ(outdoor.matches[5], 3.0) << "1.0 falls in the last bin";
  EXPECT_NEAR(outdoor.Error(5), 2.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(outdoor.matches[1], 1.0) << "0.5 opens the second bin";
  const ConfidenceCalibration& overall = summary.calibration[4];
  EXPECT_EQ(overall.group, "overall");
  EXPECT_EQ(overall.n_pairs, 2);
  EXPECT_DOUBLE_EQ(overall.matches[5], 7.0);
  EXPECT_NEAR(overall.Error(5), 3.0 / 7.0, 1e-12);

  const std::string markdown = RankedMarkdown(report);
  EXPECT_NE(markdown.find("| **outdoor** (1) | hnn-default | - | 0.0 (1) | - | - | - | 66.7 (3) |"),
            std::string::npos)
      << markdown;
  const nlohmann::json json = EvaluationJson(report);
  ASSERT_EQ(json["ranked"]["confidence_calibration"].size(), 5u);
  EXPECT_TRUE(json["ranked"]["confidence_calibration"][0]["bins"][0]["error_1px"].is_null());
  EXPECT_EQ(json["pairs"][1]["scene"], "outdoor");
  const cv::Mat plot = DrawCalibrationPlot(report);
  EXPECT_EQ(plot.cols, 900);
  EXPECT_TRUE(DrawCalibrationPlot(EvaluationReport{}).empty());
}

TEST(Middlebury, TheVendoredTeddyGivesTheSameOcclusionsAsTheSharedOne) {
  const std::string shared = std::string(HNNSTEREO_SHARED_DIR) + "/datasets/middlebury2003_teddy";
  if (!std::filesystem::exists(shared)) GTEST_SKIP() << shared << " is absent";
  const MiddleburyPair vendored =
      LoadMiddlebury(std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy");
  const MiddleburyPair original = LoadMiddlebury(shared);
  EXPECT_EQ(vendored.occlusion_source, original.occlusion_source);
  EXPECT_EQ(cv::countNonZero(vendored.nonoccluded != original.nonoccluded), 0);
  EXPECT_EQ(vendored.max_disparity, original.max_disparity);
}

TEST(EvaluationOptions, RejectsBadSettings) {
  EvaluationOptions options;
  EXPECT_TRUE(options.Check().empty());
  options.wta_zncc_window = 4;
  EXPECT_FALSE(options.Check().empty());
  options = {};
  options.presets.clear();
  EXPECT_FALSE(options.Check().empty());
  options = {};
  options.warp.setZero();
  EXPECT_FALSE(options.Check().empty());
}

}  // namespace
}  // namespace hnnstereo::vision
