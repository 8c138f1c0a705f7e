// The per-match confidence (vision/stereo_matcher.h, ConfidenceOptions): the neighbourhood
// counts it reads, the model's monotonicity, and that it ranks real matches (vendored Teddy).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "vision/matcher_presets.h"
#include "vision/middlebury.h"
#include "vision/stereo_matcher.h"

namespace hnnstereo::vision {
namespace {

StereoMatch MatchAt(float x, float y, float dx, float dy) {
  StereoMatch m{};
  m.left = {x, y};
  m.right = {x + dx, y + dy};
  return m;
}

// The definition, pair by pair: other matches within r px whose displacement is within 1 px.
void BruteForceCounts(const std::vector<StereoMatch>& matches, std::size_t i,
                      std::array<int, 3>* neighbours, std::array<int, 3>* agreeing) {
  *neighbours = {0, 0, 0};
  *agreeing = {0, 0, 0};
  const StereoMatch& a = matches[i];
  for (std::size_t j = 0; j < matches.size(); ++j) {
    if (j == i) continue;
    const StereoMatch& b = matches[j];
    const float ex = b.left.x() - a.left.x(), ey = b.left.y() - a.left.y();
    const float d2 = ex * ex + ey * ey;
    const float fx = (b.right.x() - b.left.x()) - (a.right.x() - a.left.x());
    const float fy = (b.right.y() - b.left.y()) - (a.right.y() - a.left.y());
    const bool agrees = fx * fx + fy * fy <= 1.0f;
    for (std::size_t r = 0; r < kAgreementRadiiPx.size(); ++r) {
      if (d2 <= kAgreementRadiiPx[r] * kAgreementRadiiPx[r]) {
        ++(*neighbours)[r];
        if (agrees) ++(*agreeing)[r];
      }
    }
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
  int some_disagree = 0;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    std::array<int, 3> neighbours{}, agreeing{};
    BruteForceCounts(original, i, &neighbours, &agreeing);
    for (std::size_t r = 0; r < 3; ++r) {
      ASSERT_EQ(matches[i].neighbours[r], neighbours[r]) << "match " << i << " radius " << r;
      ASSERT_EQ(matches[i].agreeing[r], agreeing[r]) << "match " << i << " radius " << r;
    }
    EXPECT_EQ(matches[i].left, original[i].left);  // order and points untouched
    some_disagree += matches[i].agreeing[2] < matches[i].neighbours[2];
  }
  EXPECT_GT(some_disagree, 100);
  EXPECT_EQ(matches.back().neighbours[0], 1);  // the lone pair, 3 px apart
  EXPECT_EQ(matches.back().agreeing[0], 1);
}

TEST(CountAgreeingNeighbours, LoneAndEmpty) {
  std::vector<StereoMatch> none;
  CountAgreeingNeighbours(none);
  std::vector<StereoMatch> one = {MatchAt(5.0f, 5.0f, -2.0f, 0.0f)};
  CountAgreeingNeighbours(one);
  EXPECT_EQ(one[0].neighbours[2], 0);
  EXPECT_EQ(one[0].agreeing[2], 0);
}

TEST(MatchConfidence, RisesWithAgreementAndSupportAndStaysInZeroOne) {
  const ConfidenceOptions options;
  ASSERT_TRUE(options.Check().empty()) << options.Check();
  StereoMatch m = MatchAt(10.0f, 10.0f, -5.0f, 0.0f);
  m.potential_margin = 200.0f;
  m.correlation = 0.8f;
  m.correlation_margin = 0.1f;
  m.neighbours = {4, 12, 40};
  m.agreeing = {1, 3, 10};
  const float disagreeing = MatchConfidence(m, options);
  m.agreeing = {4, 12, 40};
  const float agreeing = MatchConfidence(m, options);
  EXPECT_GT(agreeing, disagreeing);
  m.potential_margin = 900.0f;
  EXPECT_GT(MatchConfidence(m, options), agreeing);
  m.potential_margin = std::numeric_limits<float>::max();  // clamped by the cap, still finite
  const float capped = MatchConfidence(m, options);
  EXPECT_TRUE(std::isfinite(capped));
  for (const float c : {disagreeing, agreeing, capped}) {
    EXPECT_GE(c, 0.0f);
    EXPECT_LE(c, 1.0f);
  }
}

TEST(ConfidenceOptions, RefusesNonFiniteWeights) {
  ConfidenceOptions options;
  options.w_agreement[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(options.Check().empty());
  options = {};
  options.w_neighbours[2] = std::numeric_limits<double>::infinity();
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
