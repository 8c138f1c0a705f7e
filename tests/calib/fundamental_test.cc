#include "calib/fundamental.h"

#include <gtest/gtest.h>

#include <Eigen/SVD>

#include <limits>
#include <random>
#include <stdexcept>

#include "calib/dlt.h"
#include "calib/epipolar.h"
#include "synthetic_rig.h"

namespace hnnstereo::calib {
namespace {

constexpr std::uint64_t kSeed = 77;

struct Matches {
  std::vector<Eigen::Vector2d> left, right;
  std::vector<bool> is_outlier;
};

// Random 3D points in a box in front of the rig, projected, with noise and gross outliers.
Matches MakeMatches(const testing::StereoRig& rig, int n, double noise_px, double outlier_ratio,
                    std::uint64_t seed) {
  std::mt19937_64 generator(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  Matches matches;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d X =
        rig.work_centre + Eigen::Vector3d(100 * uniform(generator), 80 * uniform(generator),
                                          75 + 75 * uniform(generator));
    Eigen::Vector2d left = Project(rig.P1, X) + Eigen::Vector2d(noise(generator), noise(generator));
    Eigen::Vector2d right =
        Project(rig.P2, X) + Eigen::Vector2d(noise(generator), noise(generator));
    const bool outlier = (uniform(generator) + 1.0) / 2.0 < outlier_ratio;
    if (outlier)
      right = Eigen::Vector2d(320 + 300 * uniform(generator), 240 + 220 * uniform(generator));
    matches.left.push_back(left);
    matches.right.push_back(right);
    matches.is_outlier.push_back(outlier);
  }
  return matches;
}

TEST(FundamentalFromProjections, EpipolarConstraintHolds) {
  const testing::StereoRig rig = testing::ThesisRig();
  const Eigen::Matrix3d F = FundamentalFromProjections(rig.P1, rig.P2);
  const Matches matches = MakeMatches(rig, 50, 0.0, 0.0, kSeed);
  for (size_t i = 0; i < matches.left.size(); ++i) {
    const double algebraic = matches.right[i].homogeneous().dot(F * matches.left[i].homogeneous());
    EXPECT_NEAR(algebraic, 0.0, 1e-9);
    EXPECT_LT(EpipolarDistancePx(F, matches.left[i], matches.right[i]), 1e-6);
  }
  EXPECT_NEAR(F.norm(), 1.0, 1e-12);
  EXPECT_LT(F.determinant(), 1e-12);
}

TEST(FundamentalEightPoint, ExactOnNoiseFreeData) {
  const testing::StereoRig rig = testing::ThesisRig();
  const Matches matches = MakeMatches(rig, 30, 0.0, 0.0, kSeed);
  const Eigen::Matrix3d F = EstimateFundamentalEightPoint(matches.left, matches.right);
  Eigen::Matrix3d F_true = FundamentalFromProjections(rig.P1, rig.P2);
  if (F.cwiseProduct(F_true).sum() < 0) F_true = -F_true;
  EXPECT_LT((F - F_true).norm(), 1e-6);
  EXPECT_LT(MeanEpipolarDistancePx(F, matches.left, matches.right), 1e-6);
  // Rank 2.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F);
  EXPECT_LT(svd.singularValues()(2), 1e-12);
}

TEST(FundamentalRansac, FindsInliersAmongOutliers) {
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  const testing::StereoRig rig = testing::ThesisRig();
  const Matches matches = MakeMatches(rig, 300, 0.3, 0.35, kSeed);
  FundamentalRansacOptions options;
  options.max_epipolar_distance_px = 1.5;
  const FundamentalReport report = EstimateFundamentalRansac(matches.left, matches.right, options);
  ASSERT_TRUE(report.success) << report.message;
  int true_inliers = 0, detected_true_inliers = 0, accepted_outliers = 0;
  for (size_t i = 0; i < matches.left.size(); ++i) {
    if (!matches.is_outlier[i]) {
      ++true_inliers;
      detected_true_inliers += report.inlier_mask[i] ? 1 : 0;
    } else {
      accepted_outliers += report.inlier_mask[i] ? 1 : 0;
    }
  }
  EXPECT_GE(detected_true_inliers, 0.95 * true_inliers);
  EXPECT_LE(accepted_outliers, 3);  // a random point may fall near its epipolar line
  EXPECT_LT(report.mean_epipolar_distance_px, 0.5);
  EXPECT_LT(report.num_iterations, options.max_iterations);
  // Against the true geometry: the clean matches lie near the estimated epipolar lines.
  std::vector<Eigen::Vector2d> clean_left, clean_right;
  for (size_t i = 0; i < matches.left.size(); ++i) {
    if (matches.is_outlier[i]) continue;
    clean_left.push_back(matches.left[i]);
    clean_right.push_back(matches.right[i]);
  }
  EXPECT_LT(MeanEpipolarDistancePx(report.F, clean_left, clean_right), 0.5);
  // Reproducible for a seed.
  const FundamentalReport again = EstimateFundamentalRansac(matches.left, matches.right, options);
  EXPECT_EQ(again.inlier_mask, report.inlier_mask);
}

TEST(FundamentalRansac, NoConsensusIsAnAnswerNotAnError) {
  std::mt19937_64 generator(kSeed);
  std::uniform_real_distribution<double> uniform(0.0, 600.0);
  std::vector<Eigen::Vector2d> left, right;
  for (int i = 0; i < 9; ++i) {
    left.emplace_back(uniform(generator), uniform(generator));
    right.emplace_back(uniform(generator), uniform(generator));
  }
  FundamentalRansacOptions options;
  options.max_epipolar_distance_px = 1e-9;
  options.max_iterations = 50;
  const FundamentalReport report = EstimateFundamentalRansac(left, right, options);
  EXPECT_FALSE(report.message.empty());
  if (!report.success) {
    EXPECT_EQ(report.num_inliers, 0);
  }
}

TEST(FundamentalRansac, BadInputThrows) {
  std::vector<Eigen::Vector2d> left(7, Eigen::Vector2d(1, 2)), right(7, Eigen::Vector2d(3, 4));
  EXPECT_THROW(EstimateFundamentalRansac(left, right), std::invalid_argument);
  left.resize(10, Eigen::Vector2d(5, 6));
  EXPECT_THROW(EstimateFundamentalRansac(left, right), std::invalid_argument);
  right.resize(10, Eigen::Vector2d(5, 6));
  right[2].x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(EstimateFundamentalRansac(left, right), std::invalid_argument);
  FundamentalRansacOptions options;
  options.confidence = 1.0;
  EXPECT_FALSE(options.Check().empty());
}

}  // namespace
}  // namespace hnnstereo::calib
