// Candidate gating: rows, disparity range, top-K, height range, dense and feature-vs-disparity.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>
#include <random>
#include <set>

#include "calib/calibration.h"
#include "calib/epipolar.h"
#include "vision/stereo/candidates.h"
#include "vision/stereo/correlation.h"

namespace hnnstereo::vision {
namespace {

constexpr float kShift = 10.0f;  // true disparity of the synthetic pair

struct Pair {
  cv::Mat left, right;
  std::vector<Eigen::Vector2f> left_points, right_points;
};

// Random texture; the right image is the left shifted by kShift px (a fronto-parallel plane).
Pair TexturedPair(std::uint64_t seed) {
  Pair pair;
  pair.left = cv::Mat(80, 160, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(pair.left, cv::RNG::UNIFORM, 0, 255);
  pair.right = cv::Mat(80, 160, CV_8UC1, cv::Scalar(0));
  pair.left(cv::Rect(static_cast<int>(kShift), 0, 160 - static_cast<int>(kShift), 80))
      .copyTo(pair.right(cv::Rect(0, 0, 160 - static_cast<int>(kShift), 80)));
  for (int y = 10; y < 70; y += 6) {
    for (int x = 30; x < 150; x += 7) pair.left_points.emplace_back(static_cast<float>(x), static_cast<float>(y));
  }
  for (int y = 10; y < 70; y += 6) {
    for (int x = 5; x < 150; x += 1) pair.right_points.emplace_back(static_cast<float>(x), static_cast<float>(y));
  }
  return pair;
}

TEST(BuildCandidates, RectifiedGatesByRowAndDisparity) {
  const Pair pair = TexturedPair(1);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;
  options.rectified = true;
  options.min_disparity = 2;
  options.max_disparity = 20;
  options.top_k = 0;
  const CandidateReport report = BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options);
  ASSERT_EQ(report.problem.Check(), "");
  ASSERT_FALSE(report.problem.candidates.empty());
  for (const hnn::Candidate& c : report.problem.candidates) {
    const Eigen::Vector2f& l = pair.left_points[static_cast<std::size_t>(c.left)];
    EXPECT_LE(std::abs(l.y() - c.right_point.y()), options.max_epipolar_distance_px);
    const float d = l.x() - c.right_point.x();
    EXPECT_GE(d, 2.0f);
    EXPECT_LE(d, 20.0f);
    EXPECT_FLOAT_EQ(c.epipolar_distance_px, std::abs(l.y() - c.right_point.y()));
  }
  // Every left point has all 19 disparities 2..20 of its own row available.
  EXPECT_EQ(report.problem.candidates.size(), pair.left_points.size() * 19);
}

TEST(BuildCandidates, TopKKeepsTheBestCorrelatedIncludingTheTrueMatch) {
  const Pair pair = TexturedPair(2);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;
  options.rectified = true;
  options.max_disparity = 30;
  options.top_k = 3;
  const CandidateReport report = BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options);
  std::map<int, int> per_left;
  std::map<int, bool> has_true;
  for (const hnn::Candidate& c : report.problem.candidates) {
    ++per_left[c.left];
    const Eigen::Vector2f& l = pair.left_points[static_cast<std::size_t>(c.left)];
    if (std::abs(l.x() - c.right_point.x() - kShift) < 0.01f) {
      has_true[c.left] = true;
      EXPECT_GT(c.correlation, 0.99f);
    }
  }
  for (const auto& [left, count] : per_left) EXPECT_LE(count, 3);
  EXPECT_EQ(has_true.size(), pair.left_points.size());
}

TEST(BuildCandidates, DenseIsAllPairs) {
  const Pair pair = TexturedPair(3);
  const ZnccMatcher zncc(pair.left, pair.right, 5);
  CandidateOptions options;
  options.rectified = true;
  options.dense = true;
  std::vector<Eigen::Vector2f> left(pair.left_points.begin(), pair.left_points.begin() + 12);
  std::vector<Eigen::Vector2f> right(pair.right_points.begin(), pair.right_points.begin() + 15);
  const CandidateReport report = BuildCandidates(left, right, zncc, nullptr, options);
  EXPECT_TRUE(report.problem.dense);
  EXPECT_EQ(report.problem.candidates.size(), 12u * 15u);
  EXPECT_EQ(report.problem.Check(), "");
}

TEST(BuildCandidates, FeatureVersusDisparityNetwork) {
  const Pair pair = TexturedPair(4);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;
  options.rectified = true;
  options.kind = hnn::NetworkKind::kFeatureVsDisparity;
  options.min_disparity = 4;
  options.max_disparity = 15;
  options.top_k = 0;
  const CandidateReport report = BuildCandidates(pair.left_points, {}, zncc, nullptr, options);
  EXPECT_EQ(report.problem.n_columns, 12);
  EXPECT_EQ(report.problem.candidates.size(), pair.left_points.size() * 12);
  for (const hnn::Candidate& c : report.problem.candidates) {
    const Eigen::Vector2f& l = pair.left_points[static_cast<std::size_t>(c.left)];
    EXPECT_FLOAT_EQ(l.x() - c.right_point.x(), static_cast<float>(c.column + 4));
  }
}

TEST(BuildCandidates, ZnccPeaksWithSubpixelDisparities) {
  const Pair pair = TexturedPair(5);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;
  options.rectified = true;
  options.kind = hnn::NetworkKind::kFeatureVsDisparity;
  options.min_disparity = 4;
  options.max_disparity = 15;
  options.top_k = 0;
  options.zncc_peaks = true;
  options.subpixel_peaks = true;
  const CandidateReport report = BuildCandidates(pair.left_points, {}, zncc, nullptr, options);
  // Fewer candidates than levels (only the peaks), every left feature keeps its true disparity
  // as a peak, and the sub-pixel vertex stays within 0.5 px of the integer level.
  EXPECT_LT(report.problem.candidates.size(), pair.left_points.size() * 12);
  std::map<int, bool> has_true;
  for (const hnn::Candidate& c : report.problem.candidates) {
    const Eigen::Vector2f& l = pair.left_points[static_cast<std::size_t>(c.left)];
    const float d = l.x() - c.right_point.x();
    EXPECT_LE(std::abs(d - static_cast<float>(c.column + 4)), 0.5f + 1e-4f);
    if (c.column + 4 == static_cast<int>(kShift)) {
      has_true[c.left] = true;
      EXPECT_NEAR(d, kShift, 0.25f);  // an exact integer shift: a nearly symmetric peak
    }
  }
  EXPECT_EQ(has_true.size(), pair.left_points.size());
  // Feature-vs-feature networks refuse the peak options.
  options.kind = hnn::NetworkKind::kFeatureVsFeature;
  EXPECT_THROW(BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options),
               std::invalid_argument);
}

TEST(BuildCandidates, DisparityBandsLimitTheLevelsAndKeepTheColumns) {
  const Pair pair = TexturedPair(5);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;
  options.rectified = true;
  options.kind = hnn::NetworkKind::kFeatureVsDisparity;
  options.min_disparity = 4;
  options.max_disparity = 15;
  options.top_k = 0;
  options.zncc_peaks = true;
  const CandidateReport whole = BuildCandidates(pair.left_points, {}, zncc, nullptr, options);
  // A band over the whole range (or wider) is the same problem as no band.
  const std::vector<DisparityBand> everything(pair.left_points.size(), DisparityBand{0, 40});
  const CandidateReport same = BuildCandidates(pair.left_points, {}, zncc, nullptr, options, everything);
  ASSERT_EQ(same.problem.candidates.size(), whole.problem.candidates.size());
  for (std::size_t a = 0; a < whole.problem.candidates.size(); ++a) {
    EXPECT_EQ(same.problem.candidates[a].column, whole.problem.candidates[a].column);
    EXPECT_EQ(same.problem.candidates[a].correlation, whole.problem.candidates[a].correlation);
  }
  // Bands 8..12 around the true shift (10): only those levels, columns still counted from 4,
  // the true disparity still a peak of every feature; an empty band leaves its feature out.
  std::vector<DisparityBand> bands(pair.left_points.size(), DisparityBand{8, 12});
  bands[0] = DisparityBand{};
  const CandidateReport banded = BuildCandidates(pair.left_points, {}, zncc, nullptr, options, bands);
  EXPECT_EQ(banded.problem.n_columns, 12);
  // Each feature profiles its band and one level beyond each end (peaks), the first none.
  EXPECT_EQ(banded.pairs_tested, 7 * static_cast<std::int64_t>(pair.left_points.size() - 1));
  std::set<int> with_true;
  for (const hnn::Candidate& c : banded.problem.candidates) {
    EXPECT_NE(c.left, 0);
    EXPECT_GE(c.column + 4, 8);
    EXPECT_LE(c.column + 4, 12);
    if (c.column + 4 == static_cast<int>(kShift)) with_true.insert(c.left);
  }
  EXPECT_EQ(with_true.size(), pair.left_points.size() - 1);
  // One band per left feature, or none.
  bands.pop_back();
  EXPECT_THROW(BuildCandidates(pair.left_points, {}, zncc, nullptr, options, bands),
               std::invalid_argument);
}

TEST(BuildCandidates, HeightRangeGatesThroughTriangulation) {
  const Pair pair = TexturedPair(5);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  // Rectified cameras looking along +Z: Z = f b / d with f = 100 px, b = 50 mm.
  calib::StereoCalibration calibration;
  Eigen::Matrix3d K;
  K << 100, 0, 80, 0, 100, 40, 0, 0, 1;
  calibration.P1 << K, Eigen::Vector3d::Zero();
  calibration.P2 << K, K * Eigen::Vector3d(-50, 0, 0);
  calibration.DeriveFromProjections();
  CandidateOptions options;
  options.top_k = 0;
  options.max_epipolar_distance_px = 0.5;
  options.z_range_mm = std::make_pair(250.0, 1000.0);  // d in [5, 20]
  const CandidateReport report =
      BuildCandidates(pair.left_points, pair.right_points, zncc, &calibration, options);
  ASSERT_FALSE(report.problem.candidates.empty());
  for (const hnn::Candidate& c : report.problem.candidates) {
    const float d = pair.left_points[static_cast<std::size_t>(c.left)].x() - c.right_point.x();
    EXPECT_GE(d, 5.0f - 1e-3f);
    EXPECT_LE(d, 20.0f + 1e-3f);
    EXPECT_LT(c.epipolar_distance_px, 0.5f);
  }
}

// Left features are gated in parallel chunks; the problem (order included) and the pair count
// must not depend on the number of threads, for both network kinds.
TEST(BuildCandidates, TheSameProblemOnOneThreadAsOnMany) {
  const Pair pair = TexturedPair(4);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  const int threads = cv::getNumThreads();
  for (const hnn::NetworkKind kind :
       {hnn::NetworkKind::kFeatureVsFeature, hnn::NetworkKind::kFeatureVsDisparity}) {
    CandidateOptions options;
    options.rectified = true;
    options.kind = kind;
    options.max_disparity = 30;
    options.top_k = 3;
    cv::setNumThreads(std::max(2, threads));  // more would only make TBB warn
    const CandidateReport many = BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options);
    cv::setNumThreads(1);
    const CandidateReport one = BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options);
    cv::setNumThreads(threads);
    ASSERT_EQ(many.problem.Check(), "");
    ASSERT_FALSE(one.problem.candidates.empty());
    EXPECT_EQ(many.pairs_tested, one.pairs_tested);
    ASSERT_EQ(many.problem.candidates.size(), one.problem.candidates.size());
    for (std::size_t a = 0; a < one.problem.candidates.size(); ++a) {
      const hnn::Candidate &x = many.problem.candidates[a], &y = one.problem.candidates[a];
      EXPECT_EQ(x.left, y.left);
      EXPECT_EQ(x.column, y.column);
      EXPECT_EQ(x.right_point, y.right_point);
      EXPECT_EQ(x.correlation, y.correlation);
    }
  }
}

// Unrectified gating visits only the grid cells the epipolar band crosses: the candidates must
// be exactly those of testing every pair, for steep, shallow and tilted epipolar lines.
TEST(BuildCandidates, EpipolarBandSearchFindsEveryPairOfTheAllPairsTest) {
  std::mt19937 random(17);
  cv::Mat left(120, 160, CV_8UC1), right(120, 160, CV_8UC1);
  cv::randu(left, 0, 255);
  cv::randu(right, 0, 255);
  const ZnccMatcher zncc(left, right, 5);
  std::uniform_real_distribution<float> x(0.0f, 159.0f), y(0.0f, 119.0f);
  std::vector<Eigen::Vector2f> left_points, right_points;
  for (int n = 0; n < 300; ++n) left_points.emplace_back(x(random), y(random));
  for (int n = 0; n < 3000; ++n) right_points.emplace_back(x(random), y(random));
  Eigen::Matrix3d K;
  K << 100, 0, 80, 0, 100, 60, 0, 0, 1;
  // Baselines along x (near-horizontal lines), along y (near-vertical) and oblique, plus a
  // rotation so that the lines tilt and converge.
  for (const Eigen::Vector3d& baseline :
       {Eigen::Vector3d(-50, 0, 0), Eigen::Vector3d(0, -50, 0), Eigen::Vector3d(-30, 25, 10)}) {
    calib::StereoCalibration calibration;
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, 1.0, 0.2).normalized()).toRotationMatrix();
    calibration.P1 << K, Eigen::Vector3d::Zero();
    calibration.P2 << K * R, K * baseline;
    calibration.DeriveFromProjections();
    CandidateOptions options;
    options.top_k = 0;
    options.min_correlation = -1.0f;
    options.max_epipolar_distance_px = 2.0;
    const CandidateReport report = BuildCandidates(left_points, right_points, zncc, &calibration, options);
    std::set<std::pair<int, int>> expected, found;
    for (int i = 0; i < static_cast<int>(left_points.size()); ++i) {
      const Eigen::Vector3d line =
          calib::EpipolarLineInRight(calibration.F, left_points[static_cast<std::size_t>(i)].cast<double>());
      for (int k = 0; k < static_cast<int>(right_points.size()); ++k) {
        const Eigen::Vector2f& r = right_points[static_cast<std::size_t>(k)];
        const auto tau = static_cast<float>(std::abs(line.x() * r.x() + line.y() * r.y() + line.z()));
        if (tau <= 2.0f) expected.insert({i, k});
      }
    }
    for (const hnn::Candidate& c : report.problem.candidates) found.insert({c.left, c.column});
    EXPECT_GT(expected.size(), 1000u);
    EXPECT_EQ(found, expected) << "baseline " << baseline.transpose();
    EXPECT_LT(report.pairs_tested, static_cast<std::int64_t>(left_points.size() * right_points.size() / 4));
  }
}

TEST(BuildCandidates, RefusesBadOptions) {
  const Pair pair = TexturedPair(6);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;  // not rectified and no calibration
  EXPECT_THROW(BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options),
               std::invalid_argument);
  options.rectified = true;
  options.min_disparity = 10;
  options.max_disparity = 5;
  EXPECT_THROW(BuildCandidates(pair.left_points, pair.right_points, zncc, nullptr, options),
               std::invalid_argument);
}

// A disparity range far beyond the image width (1e9 px) once allocated gigabytes of levels;
// it is refused at once, naming the width.
TEST(BuildCandidates, RefusesADisparityRangeBeyondTheImageWidth) {
  const Pair pair = TexturedPair(6);
  const ZnccMatcher zncc(pair.left, pair.right, 7);
  CandidateOptions options;
  options.rectified = true;
  options.kind = hnn::NetworkKind::kFeatureVsDisparity;
  for (const auto& [min_d, max_d] : {std::pair{0.0, 1e9}, std::pair{-1e6, 10.0}, std::pair{0.0, 160.0}}) {
    options.min_disparity = min_d;
    options.max_disparity = max_d;
    try {
      BuildCandidates(pair.left_points, {}, zncc, nullptr, options);
      ADD_FAILURE() << "no exception for [" << min_d << ", " << max_d << "]";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("image width (160 px"), std::string::npos) << e.what();
    }
  }
  options.min_disparity = -159;
  options.max_disparity = 159;  // the widest range that fits
  EXPECT_NO_THROW(BuildCandidates(pair.left_points, {}, zncc, nullptr, options));
}

}  // namespace
}  // namespace hnnstereo::vision
