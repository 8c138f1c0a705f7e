// The per-match confidence (vision/stereo_matcher.h, ConfidenceOptions): the neighbourhood
// counts it reads, the model's monotonicity, and that it ranks real matches (vendored Teddy).
#include <gtest/gtest.h>

#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "vision/stereo/matcher_presets.h"
#include "vision/eval/middlebury.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {
namespace {

StereoMatch MatchAt(float x, float y, float dx, float dy) {
  StereoMatch m{};
  m.left = {x, y};
  m.right = {x + dx, y + dy};
  return m;
}

// The definition, pair by pair: other matches within r px whose displacement agrees (within
// 1 px + slope * distance), and the distance of the displacement from the least-squares plane of
// the neighbours' within kSurfaceRadiusPx (Eigen's QR, not the normal equations).
void BruteForceCounts(const std::vector<StereoMatch>& matches, std::size_t i,
                      std::array<int, 4>* neighbours, std::array<int, 4>* agreeing,
                      double* residual) {
  *neighbours = {0, 0, 0, 0};
  *agreeing = {0, 0, 0, 0};
  const StereoMatch& a = matches[i];
  std::vector<Eigen::Vector3d> rows;
  std::vector<Eigen::Vector2d> shifts;
  for (std::size_t j = 0; j < matches.size(); ++j) {
    if (j == i) continue;
    const StereoMatch& b = matches[j];
    const double ex = b.left.x() - a.left.x(), ey = b.left.y() - a.left.y();
    const double distance = std::hypot(ex, ey);
    const Eigen::Vector2d shift_b = (b.right - b.left).cast<double>();
    const double f = (shift_b - (a.right - a.left).cast<double>()).norm();
    for (std::size_t r = 0; r < kAgreementRadiiPx.size(); ++r) {
      if (distance <= kAgreementRadiiPx[r]) {
        ++(*neighbours)[r];
        if (f <= 1.0 + kAgreementSlope[r] * distance) ++(*agreeing)[r];
      }
    }
    if (distance <= kSurfaceRadiusPx) {
      rows.emplace_back(1.0, ex, ey);
      shifts.push_back(shift_b);
    }
  }
  *residual = kSurfaceResidualCapPx;
  if (rows.size() >= 4) {
    Eigen::MatrixXd A(static_cast<Eigen::Index>(rows.size()), 3);
    Eigen::MatrixXd S(static_cast<Eigen::Index>(rows.size()), 2);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      A.row(static_cast<Eigen::Index>(k)) = rows[k].transpose();
      S.row(static_cast<Eigen::Index>(k)) = shifts[k].transpose();
    }
    const Eigen::MatrixXd plane = A.colPivHouseholderQr().solve(S);
    const Eigen::Vector2d at_self = plane.row(0).transpose();
    *residual = std::min<double>((at_self - (a.right - a.left).cast<double>()).norm(),
                                 kSurfaceResidualCapPx);
  }
}

TEST(CountAgreeingNeighbours, EqualsTheDefinitionOnScatteredMatches) {
  // Clusters on a few surfaces (shared displacement +- noise) plus uniform outliers, duplicates
  // and points on the image border, so every count and both outcomes of the 1 px test occur.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> x(0.0f, 300.0f), y(0.0f, 200.0f), jitter(-0.8f, 0.8f);
  std::uniform_real_distribution<float> wild(-40.0f, 0.0f);
  std::vector<StereoMatch> matches;
  for (int i = 0; i < 3000; ++i) {
    const float px = x(rng), py = y(rng);
    const float surface = px < 150.0f ? -10.0f : -25.0f;
    const bool outlier = i % 7 == 0;
    matches.push_back(MatchAt(px, py, outlier ? wild(rng) : surface + jitter(rng),
                              outlier ? jitter(rng) : 0.0f));
  }
  for (int i = 0; i < 50; ++i) matches.push_back(matches[static_cast<std::size_t>(i) * 13]);
  // A pair apart from the rest (negative coordinates too), exactly on each other's 3 px circle.
  matches.push_back(MatchAt(-100.0f, -50.0f, -3.0f, 0.0f));
  matches.push_back(MatchAt(-97.0f, -50.0f, -3.5f, 0.0f));
  const std::vector<StereoMatch> original = matches;
  CountAgreeingNeighbours(matches);
  ASSERT_EQ(matches.size(), original.size());
  int some_disagree = 0, off_surface = 0, residual_checked = 0, off_by_one = 0;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    std::array<int, 4> neighbours{}, agreeing{};
    double residual = 0.0;
    BruteForceCounts(original, i, &neighbours, &agreeing, &residual);
    for (std::size_t r = 0; r < 4; ++r) {
      // Float vs double distances may differ on a point exactly on a circle: a tolerance of one.
      ASSERT_NEAR(matches[i].neighbours[r], neighbours[r], 1) << "match " << i << " radius " << r;
      ASSERT_NEAR(matches[i].agreeing[r], agreeing[r], 1) << "match " << i << " radius " << r;
      off_by_one += (matches[i].neighbours[r] != neighbours[r]) + (matches[i].agreeing[r] != agreeing[r]);
    }
    // The ridge (1e-3 of the spread) moves the plane by far less than 0.05 px.
    ASSERT_NEAR(matches[i].surface_residual, residual, 0.05) << "match " << i;
    residual_checked += residual < kSurfaceResidualCapPx;
    EXPECT_EQ(matches[i].left, original[i].left);  // order and points untouched
    some_disagree += matches[i].agreeing[3] < matches[i].neighbours[3];
    off_surface += matches[i].surface_residual > 2.0f;
  }
  EXPECT_LE(off_by_one, 5);  // of about 24,000 counts
  EXPECT_GT(some_disagree, 100);
  EXPECT_GT(off_surface, 100);           // the outliers
  EXPECT_GT(residual_checked, 2000);     // most matches have a fitted surface
  EXPECT_EQ(matches.back().neighbours[0], 1);  // the lone pair, 3 px apart
  EXPECT_EQ(matches.back().agreeing[0], 1);
}

// A coarse-to-fine pair counts in its coarsest level's pixels: matches at twice the size counted
// at scale 1/2 get the counts of the same matches at the size the radii were chosen for, and
// keep their own points.
TEST(CountAgreeingNeighbours, ScaleCountsInAnImageThatManyTimesTheSize) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> x(0.0f, 200.0f), y(0.0f, 150.0f), jitter(-0.4f, 0.4f);
  std::vector<StereoMatch> small;
  for (int i = 0; i < 800; ++i) {
    const float px = x(rng);
    small.push_back(MatchAt(px, y(rng), (px < 100.0f ? -8.0f : -20.0f) + jitter(rng), 0.0f));
  }
  std::vector<StereoMatch> large = small;
  for (StereoMatch& m : large) {
    m.left *= 2.0f;
    m.right *= 2.0f;
  }
  const std::vector<StereoMatch> large_points = large;
  CountAgreeingNeighbours(small);
  CountAgreeingNeighbours(large, 0.5f);
  int counted_differently = 0;
  for (std::size_t i = 0; i < small.size(); ++i) {
    counted_differently += small[i].neighbours != large[i].neighbours ||
                           small[i].agreeing != large[i].agreeing;
    EXPECT_EQ(large[i].left, large_points[i].left);
  }
  EXPECT_EQ(counted_differently, 0);
  // Counted in its own pixels, the large image's radii hold a quarter of the scene.
  std::vector<StereoMatch> as_given = large_points;
  CountAgreeingNeighbours(as_given);
  EXPECT_LT(as_given[0].neighbours[3], large[0].neighbours[3]);
}

TEST(CountAgreeingNeighbours, LoneAndEmpty) {
  std::vector<StereoMatch> none;
  CountAgreeingNeighbours(none);
  std::vector<StereoMatch> one = {MatchAt(5.0f, 5.0f, -2.0f, 0.0f)};
  CountAgreeingNeighbours(one);
  EXPECT_EQ(one[0].neighbours[2], 0);
  EXPECT_EQ(one[0].agreeing[2], 0);
}

// Both fitted models (ZNCC's, the in-class default, and the census data term's, hnn-default's).
TEST(MatchConfidence, RisesWithAgreementAndSupportAndStaysInZeroOne) {
  for (const ConfidenceOptions& options : {ConfidenceOptions{}, CensusConfidenceOptions()}) {
    ASSERT_TRUE(options.Check().empty()) << options.Check();
    StereoMatch m = MatchAt(10.0f, 10.0f, -5.0f, 0.0f);
    m.potential_margin = 200.0f;
    m.correlation = 0.8f;
    m.correlation_margin = 0.1f;
    m.neighbours = {4, 12, 40, 150};
    m.agreeing = {1, 3, 10, 40};
    m.surface_residual = 3.0f;
    const float disagreeing = MatchConfidence(m, options);
    m.agreeing = {4, 12, 40, 150};
    const float agreeing = MatchConfidence(m, options);
    EXPECT_GT(agreeing, disagreeing);
    m.correlation = 0.9f;  // more alike windows
    EXPECT_GT(MatchConfidence(m, options), agreeing);
    m.correlation_margin = 0.3f;  // and further ahead of the row's next candidate
    EXPECT_GT(MatchConfidence(m, options), agreeing);
    m.correlation = 0.8f;
    m.correlation_margin = 0.1f;
    // On its neighbours' plane, or with a larger lead in support: never ranked lower (the census
    // model weighs these two 0, the ZNCC model raises the confidence with them).
    m.surface_residual = 0.0f;
    EXPECT_GE(MatchConfidence(m, options), agreeing);
    if (options.w_surface_residual != 0.0) EXPECT_GT(MatchConfidence(m, options), agreeing);
    m.surface_residual = 3.0f;
    m.potential_margin = 900.0f;
    EXPECT_GE(MatchConfidence(m, options), agreeing);
    if (options.w_potential_margin != 0.0) EXPECT_GT(MatchConfidence(m, options), agreeing);
    m.potential_margin = std::numeric_limits<float>::max();  // clamped by the cap, still finite
    const float capped = MatchConfidence(m, options);
    EXPECT_TRUE(std::isfinite(capped));
    for (const float c : {disagreeing, agreeing, capped}) {
      EXPECT_GE(c, 0.0f);
      EXPECT_LE(c, 1.0f);
    }
  }
  // Each data term gets the model fitted for it.
  DataTermOptions census;
  census.kind = DataTermOptions::Kind::kCensus;
  EXPECT_EQ(ConfidenceOptionsFor(census).bias, CensusConfidenceOptions().bias);
  EXPECT_EQ(ConfidenceOptionsFor(DataTermOptions{}).bias, ConfidenceOptions{}.bias);
  EXPECT_NE(CensusConfidenceOptions().bias, ConfidenceOptions{}.bias);
}

// hnn-default's model reads how many matches lie within 3 and 6 px (edge continuity) but not
// how many within 12 and 24 px: that is how textured the scene is (a repeated facade outdoors is
// dense and wrong), so two matches whose neighbourhoods agree alike rank alike however dense.
TEST(MatchConfidence, CensusModelDoesNotRankByHowTexturedTheSceneIs) {
  const ConfidenceOptions census = CensusConfidenceOptions();
  StereoMatch plain = MatchAt(10.0f, 10.0f, -5.0f, 0.0f);
  plain.correlation = 0.75f;
  plain.correlation_margin = 0.2f;
  plain.neighbours = {7, 23, 60, 200};
  plain.agreeing = {7, 23, 54, 180};
  StereoMatch textured = plain;
  textured.neighbours = {7, 23, 120, 400};
  textured.agreeing = {7, 23, 108, 360};  // the same shares agree
  EXPECT_FLOAT_EQ(MatchConfidence(plain, census), MatchConfidence(textured, census));
  StereoMatch broken = plain;  // fewer matches along the edge itself: less continuity
  broken.neighbours = {3, 10, 60, 200};
  broken.agreeing = {3, 10, 54, 180};
  EXPECT_LT(MatchConfidence(broken, census), MatchConfidence(plain, census));
}

TEST(ConfidenceOptions, RefusesNonFiniteWeights) {
  ConfidenceOptions options;
  options.w_agreement[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(options.Check().empty());
  options = {};
  options.w_neighbours[3] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(options.Check().empty());
  options = {};
  options.w_surface_residual = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(options.Check().empty());
  options = {};
  options.bias = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(options.Check().empty());
}

// The whole matcher on the vendored Teddy pair, scored against its ground truth as `eval` scores
// (correct = |d - d_true| <= 1 px at the rounded left pixel, occluded pixels left out): the top
// quarter by confidence must be far cleaner than all matches (docs/accuracy.md: 0.03 here).
TEST(MatchConfidence, RanksTheMatchesOfARealPair) {
  const MiddleburyPair pair =
      LoadMiddlebury(std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy");
  MatcherPreset preset = AccurateDefaultPreset();
  preset.matcher.engine = hnn::EngineKind::kCpu;
  preset.matcher.candidates.rectified = true;
  preset.matcher.candidates.min_disparity = pair.min_disparity;
  preset.matcher.candidates.max_disparity = pair.max_disparity;
  const MatchReport report = MatchWithPreset(pair.left_grey, pair.right_grey, nullptr, preset, nullptr);
  struct Scored {
    float confidence;
    bool wrong;
  };
  std::vector<Scored> scored;
  for (const StereoMatch& m : report.matches) {
    const int x = static_cast<int>(std::lround(m.left.x())), y = static_cast<int>(std::lround(m.left.y()));
    if (x < 0 || y < 0 || x >= pair.disparity.cols || y >= pair.disparity.rows) continue;
    const float truth = pair.disparity.at<float>(y, x);
    if (!std::isfinite(truth) || pair.nonoccluded.at<std::uint8_t>(y, x) == 0) continue;
    scored.push_back({m.confidence, std::abs((m.left.x() - m.right.x()) - truth) > 1.0f});
  }
  ASSERT_GT(scored.size(), 5000u);
  std::sort(scored.begin(), scored.end(),
            [](const Scored& a, const Scored& b) { return a.confidence > b.confidence; });
  const auto error_of_top = [&](std::size_t n) {
    return static_cast<double>(std::count_if(scored.begin(), scored.begin() + static_cast<long>(n),
                                             [](const Scored& s) { return s.wrong; })) /
           static_cast<double>(n);
  };
  const double all = error_of_top(scored.size());
  const double top_quarter = error_of_top(scored.size() / 4);
  EXPECT_GT(all, 0.03);  // the pair has errors to rank
  EXPECT_LE(top_quarter, 0.25 * all) << "top 25 % " << top_quarter << " vs all " << all;
  // Not a constant: the confidences spread over the unit interval.
  EXPECT_GT(scored.front().confidence - scored.back().confidence, 0.5f);
}

}  // namespace
}  // namespace hnnstereo::vision
