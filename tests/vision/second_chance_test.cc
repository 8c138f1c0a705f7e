// The second chance over the unmatched features (vision/stereo/second_chance.h): on a seeded
// synthetic pair it fills a hole left in the first pass's matches with the right disparities,
// on both sides of a depth step; its matches carry a lower confidence; on a real pair it adds
// density, mostly right, ranked below the first pass.
#include "vision/stereo/second_chance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "host/opencl_runtime.h"
#include "vision/eval/middlebury.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {
namespace {

constexpr int kSize = 96;
constexpr int kStepRow = kSize / 2;  // rows above: disparity 6; from here down: 12
constexpr int kNearDisparity = 6, kFarDisparity = 12;

int TrueDisparity(float y) { return y < kStepRow ? kNearDisparity : kFarDisparity; }

// A seeded random texture and its right view: every row shifted by its disparity (a horizontal
// depth step: rows stay independent, so the pair has no occlusion).
struct StepPair {
  cv::Mat left, right;
};

StepPair MakeStepPair(std::uint64_t seed) {
  StepPair pair;
  cv::Mat noise(kSize, kSize + 2 * kFarDisparity, CV_8U);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(3, 3), 0.8);
  pair.left = noise(cv::Rect(kFarDisparity, 0, kSize, kSize)).clone();
  pair.right = cv::Mat(kSize, kSize, CV_8U);
  for (int y = 0; y < kSize; ++y) {
    const int d = TrueDisparity(static_cast<float>(y));
    // right(x - d) = left(x) = noise(x + kFarDisparity).
    noise.row(y).colRange(kFarDisparity + d, kFarDisparity + d + kSize).copyTo(pair.right.row(y));
  }
  return pair;
}

MatcherOptions CpuDefault() {
  MatcherOptions matcher = AccurateDefaultPreset().matcher;
  matcher.engine = hnn::EngineKind::kCpu;
  matcher.candidates.min_disparity = 0;
  matcher.candidates.max_disparity = 20;
  return matcher;
}

// Features on a grid; the first pass's matches at their true disparity everywhere except in a
// hole straddling the depth step, which is left unmatched.
struct FirstPass {
  std::vector<Eigen::Vector2f> features;
  std::vector<StereoMatch> matches;
  int in_hole = 0;
};

bool InHole(const Eigen::Vector2f& p) {
  return p.x() >= 40 && p.x() <= 56 && p.y() >= 34 && p.y() <= 62;
}

FirstPass MakeFirstPass(const ZnccMatcher& similarity) {
  FirstPass first;
  for (int y = 12; y < kSize - 12; y += 2) {
    for (int x = 24; x < kSize - 12; x += 2) {
      const Eigen::Vector2f p(static_cast<float>(x), static_cast<float>(y));
      first.features.push_back(p);
      if (InHole(p)) {
        ++first.in_hole;
        continue;
      }
      StereoMatch m{p, p - Eigen::Vector2f(static_cast<float>(TrueDisparity(p.y())), 0.0f), 1.0f,
                    static_cast<int>(first.features.size()) - 1, TrueDisparity(p.y())};
      m.correlation = similarity(m.left, m.right);
      first.matches.push_back(m);
    }
  }
  return first;
}

// RetryUnmatchedFeatures on the first pass, on the cpu engine.
struct Retried {
  std::vector<StereoMatch> matches;
  std::vector<DisparityBand> bands;
  SecondChanceReport report;
};

Retried Retry(const ZnccMatcher& similarity, const FirstPass& first, const MatcherOptions& matcher,
              const SecondChanceOptions& options) {
  Retried retried;
  RetryUnmatchedFeatures(similarity, first.features, first.matches, matcher, options, nullptr,
                         &retried.matches, &retried.bands, &retried.report);
  return retried;
}

TEST(SecondChance, FillsAHoleWithTheRightDisparitiesOnBothSidesOfADepthStep) {
  const StepPair pair = MakeStepPair(42);
  const MatcherOptions matcher = CpuDefault();
  const ZnccMatcher similarity(pair.left, pair.right, matcher.zncc_window, matcher.data_term);
  const FirstPass first = MakeFirstPass(similarity);
  const Retried second = Retry(similarity, first, matcher, SecondChanceOptions{});
  const std::vector<StereoMatch>& retried = second.matches;
  const std::vector<DisparityBand>& bands = second.bands;
  const SecondChanceReport& report = second.report;
  EXPECT_TRUE(report.applied);
  EXPECT_EQ(report.unmatched, first.in_hole);
  EXPECT_EQ(report.retried, first.in_hole);  // the hole is narrower than two support radii
  EXPECT_GT(report.support, 0);
  ASSERT_EQ(bands.size(), first.features.size());
  int scored = 0, right = 0, straddling = 0;
  for (const StereoMatch& m : retried) {
    EXPECT_TRUE(m.second_chance);
    ASSERT_GE(m.left_index, 0);
    EXPECT_TRUE(InHole(first.features[static_cast<std::size_t>(m.left_index)]));
    const DisparityBand& band = bands[static_cast<std::size_t>(m.left_index)];
    if (band.lo <= kNearDisparity && band.hi >= kFarDisparity) ++straddling;
    // Away from the step (the census window mixes both rows' shifts within 6 px of it).
    if (std::abs(m.left.y() - kStepRow) < 7.0f) continue;
    ++scored;
    right += std::abs(m.left.x() - m.right.x() - TrueDisparity(m.left.y())) <= 1.0f ? 1 : 0;
  }
  EXPECT_GT(straddling, 0);  // both disparities were candidates near the step
  EXPECT_GE(static_cast<int>(retried.size()), first.in_hole * 9 / 10);
  ASSERT_GT(scored, 0);
  EXPECT_GE(right, scored * 95 / 100) << right << " of " << scored;
}

TEST(SecondChance, ItsMatchesCarryTheConfidencePenalty) {
  const StepPair pair = MakeStepPair(7);
  const MatcherOptions matcher = CpuDefault();
  const ZnccMatcher similarity(pair.left, pair.right, matcher.zncc_window, matcher.data_term);
  FirstPass first = MakeFirstPass(similarity);
  CountAgreeingNeighbours(first.matches);
  for (StereoMatch& m : first.matches) m.confidence = MatchConfidence(m, matcher.confidence);
  SecondChanceOptions options;
  const std::vector<StereoMatch> retried = Retry(similarity, first, matcher, options).matches;
  ASSERT_FALSE(retried.empty());
  std::vector<StereoMatch> all = first.matches;
  const int added = AddSecondChanceMatches(retried, matcher.confidence, options, 1.0f, &all);
  EXPECT_GT(added, 0);
  ASSERT_EQ(all.size(), first.matches.size() + static_cast<std::size_t>(added));
  for (std::size_t k = 0; k < first.matches.size(); ++k) {
    EXPECT_EQ(all[k].confidence, first.matches[k].confidence);  // the first pass keeps its own
  }
  for (std::size_t k = first.matches.size(); k < all.size(); ++k) {
    const StereoMatch& m = all[k];
    EXPECT_TRUE(m.second_chance);
    // The model's confidence of the same evidence, at least min_model_confidence, times the
    // documented penalty: below every first-pass match the model rates as high.
    const float model = MatchConfidence(m, matcher.confidence);
    EXPECT_GE(model, options.min_model_confidence);
    EXPECT_NEAR(m.confidence, options.confidence_scale * model, 1e-6);
    EXPECT_LT(m.confidence, model);
  }
  // Nothing below min_model_confidence is kept.
  options.min_model_confidence = 1.0;
  std::vector<StereoMatch> none = first.matches;
  EXPECT_EQ(AddSecondChanceMatches(retried, matcher.confidence, options, 1.0f, &none), 0);
  EXPECT_EQ(none.size(), first.matches.size());
}

TEST(SecondChance, OnTeddyAddsDensityMostlyRightAndRankedBelowTheFirstPass) {
  const MiddleburyPair pair =
      LoadMiddlebury(std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy");
  MatcherPreset preset = AccurateDefaultPreset();
  preset.matcher.engine = hnn::EngineKind::kCpu;
  preset.matcher.candidates.min_disparity = pair.min_disparity;
  preset.matcher.candidates.max_disparity = pair.max_disparity;
  ASSERT_TRUE(preset.refinement.second_chance.enabled);
  const MatchReport with = MatchWithPreset(pair.left_grey, pair.right_grey, nullptr, preset, nullptr);
  preset.refinement.second_chance.enabled = false;
  const MatchReport without =
      MatchWithPreset(pair.left_grey, pair.right_grey, nullptr, preset, nullptr);
  EXPECT_FALSE(without.second_chance.applied);
  const SecondChanceReport& s = with.second_chance;
  ASSERT_TRUE(s.applied);
  EXPECT_EQ(s.unmatched, with.n_left - static_cast<int>(without.matches.size()));
  EXPECT_GT(s.retried, s.unmatched / 2);
  EXPECT_EQ(with.matches.size(), without.matches.size() + static_cast<std::size_t>(s.matched));
  EXPECT_GT(s.matched, with.n_left / 50);  // 2.4 % of Teddy's features from model confidence 0.5
  double first_confidence = 0.0, second_confidence = 0.0;
  int scored = 0, right = 0;
  for (const StereoMatch& m : with.matches) {
    (m.second_chance ? second_confidence : first_confidence) += m.confidence;
    if (!m.second_chance) continue;
    const int x = static_cast<int>(std::lround(m.left.x())), y = static_cast<int>(std::lround(m.left.y()));
    const float d = pair.disparity.at<float>(y, x);
    if (!std::isfinite(d) || pair.nonoccluded.at<std::uint8_t>(y, x) == 0) continue;
    ++scored;
    right += std::abs(m.left.x() - m.right.x() - d) <= 1.0f ? 1 : 0;
  }
  ASSERT_GT(scored, 0);
  EXPECT_GT(right, scored * 7 / 10) << right << " of " << scored;
  EXPECT_LT(second_confidence / s.matched,
            first_confidence / static_cast<double>(without.matches.size()));
}

// A small second network is solved by the cpu engine even when the opencl engine is asked for
// (SecondChanceOptions::cpu_below_neurons); with the threshold at 0 the opencl engine solves
// it, and both choose the same winners (the cpu engine is the opencl kernels' reference).
TEST(SecondChance, SmallNetworksGoToTheCpuEngineWithTheSameWinners) {
  const StepPair pair = MakeStepPair(42);
  MatcherOptions matcher = CpuDefault();
  matcher.engine = hnn::EngineKind::kOpenCL;
  const ZnccMatcher similarity(pair.left, pair.right, matcher.zncc_window, matcher.data_term);
  const FirstPass first = MakeFirstPass(similarity);
  std::string why_not;
  const auto runtime = ocl::Runtime::Create(ocl::DeviceSelection::FromEnvironment(), &why_not);
  if (!runtime) GTEST_SKIP() << "no OpenCL device: " << why_not;
  SecondChanceOptions options;
  Retried small;
  RetryUnmatchedFeatures(similarity, first.features, first.matches, matcher, options, runtime.get(),
                         &small.matches, &small.bands, &small.report);
  ASSERT_LT(small.report.neurons, options.cpu_below_neurons);
  EXPECT_EQ(small.report.engine, "cpu");
  options.cpu_below_neurons = 0;
  Retried opencl;
  RetryUnmatchedFeatures(similarity, first.features, first.matches, matcher, options, runtime.get(),
                         &opencl.matches, &opencl.bands, &opencl.report);
  EXPECT_EQ(opencl.report.engine, "opencl");
  ASSERT_EQ(opencl.matches.size(), small.matches.size());
  ASSERT_FALSE(small.matches.empty());
  for (std::size_t k = 0; k < small.matches.size(); ++k) {
    EXPECT_EQ(opencl.matches[k].left_index, small.matches[k].left_index);
    EXPECT_NEAR(opencl.matches[k].right.x(), small.matches[k].right.x(), 1e-3);
  }
}

TEST(SecondChanceOptions, RejectsBadValues) {
  SecondChanceOptions options;
  EXPECT_EQ(options.Check(), "");
  options.min_support = 0;
  EXPECT_NE(options.Check().find("min_support"), std::string::npos);
  options = {};
  options.confidence_scale = 1.5;
  EXPECT_NE(options.Check().find("confidence_scale"), std::string::npos);
  options = {};
  options.support_radius_px = 0.0;
  EXPECT_NE(options.Check().find("support_radius_px"), std::string::npos);
  options = {};
  options.min_model_confidence = -0.1;
  EXPECT_NE(options.Check().find("min_model_confidence"), std::string::npos);
  options = {};
  options.band_margin = -1;
  EXPECT_NE(options.Check().find("band_margin"), std::string::npos);
  options = {};
  options.cpu_below_neurons = -1;
  EXPECT_NE(options.Check().find("cpu_below_neurons"), std::string::npos);
}

}  // namespace
}  // namespace hnnstereo::vision
