// Camera-sized pairs: the coarse-to-fine match (vision/stereo/coarse_to_fine.h) against the
// one-pass match on a real pair with ground truth, and the memory-budget fit of MatchStereo.
#include "vision/stereo/coarse_to_fine.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "host/hopfield_network.h"
#include "vision/eval/middlebury.h"
#include "vision/stereo/matcher_presets.h"

namespace hnnstereo::vision {
namespace {

const std::string kTeddy = std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy";

struct Scored {
  double within_1px = 0.0;  ///< share of the matches with ground truth within 1 px
  double density = 0.0;     ///< matches with ground truth / left features with ground truth
};

Scored Score(const MiddleburyPair& pair, const MatchReport& report) {
  auto known = [&](const Eigen::Vector2f& p, float* d) {
    const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
    if (x < 0 || y < 0 || x >= pair.disparity.cols || y >= pair.disparity.rows) return false;
    *d = pair.disparity.at<float>(y, x);
    return std::isfinite(*d) && pair.nonoccluded.at<std::uint8_t>(y, x) != 0;
  };
  int with_truth = 0, good = 0, features_with_truth = 0;
  float d = 0.0f;
  for (const Eigen::Vector2f& p : report.left_features) features_with_truth += known(p, &d) ? 1 : 0;
  for (const StereoMatch& m : report.matches) {
    if (!known(m.left, &d)) continue;
    ++with_truth;
    good += std::abs((m.left.x() - m.right.x()) - d) <= 1.0f ? 1 : 0;
  }
  return {with_truth ? static_cast<double>(good) / with_truth : 0.0,
          features_with_truth ? static_cast<double>(with_truth) / features_with_truth : 0.0};
}

MatcherPreset DefaultFor(const MiddleburyPair& pair) {
  MatcherPreset preset = AccurateDefaultPreset();
  preset.matcher.engine = hnn::EngineKind::kCpu;
  preset.matcher.candidates.min_disparity = pair.min_disparity;
  preset.matcher.candidates.max_disparity = pair.max_disparity;
  // The bands are what these tests measure: the second chance over the unmatched features, which
  // fills differently behind either first pass, has its own (second_chance_test.cc).
  preset.refinement.second_chance.enabled = false;
  return preset;
}

TEST(CoarseToFine, AtTwiceTeddysSizeMatchesAsWellAsOnePassWithNarrowBands) {
  const MiddleburyPair pair = UpsampledMiddlebury(LoadMiddlebury(kTeddy), 2.0);  // 900 x 750
  MatcherPreset preset = DefaultFor(pair);
  ASSERT_TRUE(CoarseToFineApplies(preset.matcher, pair.left_grey.size()));
  const MatchReport coarse_to_fine =
      MatchWithPreset(pair.left_grey, pair.right_grey, nullptr, preset, nullptr);
  preset.matcher.coarse_to_fine.min_megapixels = 0.0;  // one pass over the whole range
  ASSERT_FALSE(CoarseToFineApplies(preset.matcher, pair.left_grey.size()));
  const MatchReport one_pass = MatchWithPreset(pair.left_grey, pair.right_grey, nullptr, preset, nullptr);

  const CoarseToFineReport& c = coarse_to_fine.coarse_to_fine;
  ASSERT_TRUE(c.applied);
  EXPECT_FALSE(one_pass.coarse_to_fine.applied);
  EXPECT_EQ(c.levels, 1);
  EXPECT_EQ(c.coarse_size, cv::Size(450, 375));
  EXPECT_GT(c.coarse_matches, 3000);
  // A feature searches a few levels of the 129, and nearly every feature has coarse support.
  const double levels = pair.max_disparity - pair.min_disparity + 1;
  EXPECT_LT(c.mean_band_levels, 0.2 * levels) << c.mean_band_levels;
  EXPECT_LT(c.features_whole_range, coarse_to_fine.n_left / 50);
  EXPECT_LT(coarse_to_fine.n_neurons, one_pass.n_neurons);
  EXPECT_EQ(coarse_to_fine.disparity_bands.size(), static_cast<std::size_t>(coarse_to_fine.n_left));

  const Scored banded = Score(pair, coarse_to_fine), whole = Score(pair, one_pass);
  EXPECT_GT(whole.within_1px, 0.85);
  EXPECT_GE(banded.within_1px, whole.within_1px - 0.015)
      << banded.within_1px << " vs " << whole.within_1px;
  EXPECT_GE(banded.density, whole.density - 0.02) << banded.density << " vs " << whole.density;
}

TEST(CoarseToFine, LeavesPairsUpToHalfAMegapixelAndUnrectifiedPairsAlone) {
  const MatcherPreset preset = AccurateDefaultPreset();
  EXPECT_FALSE(CoarseToFineApplies(preset.matcher, cv::Size(640, 480)));
  EXPECT_FALSE(CoarseToFineApplies(preset.matcher, cv::Size(718, 496)));
  EXPECT_TRUE(CoarseToFineApplies(preset.matcher, cv::Size(1280, 1024)));
  MatcherOptions feature_network = preset.matcher;
  feature_network.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
  EXPECT_FALSE(CoarseToFineApplies(feature_network, cv::Size(1280, 1024)));
  CoarseToFineOptions bad;
  bad.band_margin = -1;
  EXPECT_NE(bad.Check(), "");
}

TEST(MemoryBudgetFit, ANetworkOverTheBudgetMatchesASpreadShareOfTheFeatures) {
  const MiddleburyPair pair = LoadMiddlebury(kTeddy);
  MatcherOptions options = DefaultFor(pair).matcher;
  options.memory_budget_bytes = 10 * hnn::kBytesPerMegabyte;  // about 1/30 of what all need
  const MatchReport fitted = MatchStereo(pair.left_grey, pair.right_grey, nullptr, options, nullptr);
  ASSERT_TRUE(fitted.memory_fit.applied);
  EXPECT_GT(fitted.memory_fit.needed_bytes, options.memory_budget_bytes);
  EXPECT_LT(fitted.memory_fit.left_features_matched, fitted.n_left / 3);
  EXPECT_GT(fitted.memory_fit.left_features_matched, fitted.n_left / 20);
  // The share is spread over the image: matches in every quarter of it, and still right.
  int quarters[4] = {0, 0, 0, 0};
  for (const StereoMatch& m : fitted.matches) {
    ++quarters[(m.left.x() < pair.left_grey.cols / 2 ? 0 : 1) + (m.left.y() < pair.left_grey.rows / 2 ? 0 : 2)];
  }
  for (int q : quarters) EXPECT_GT(q, 100);
  EXPECT_GT(Score(pair, fitted).within_1px, 0.8);

  options.fit_memory_budget = false;
  EXPECT_THROW(MatchStereo(pair.left_grey, pair.right_grey, nullptr, options, nullptr),
               hnn::MemoryBudgetExceeded);
}

}  // namespace
}  // namespace hnnstereo::vision
