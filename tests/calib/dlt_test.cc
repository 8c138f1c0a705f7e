#include "calib/dlt.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "calib/epipolar.h"
#include "synthetic_rig.h"

namespace hnnstereo::calib {
namespace {

constexpr std::uint64_t kSeed = 20240603;

// Points on three planes z = 0, 50, 100 over the work area: what the circle target gives.
void MakeCorrespondences(const ProjectionMatrix& P, int n, double noise_px, std::uint64_t seed,
                         std::vector<Eigen::Vector3d>* world, std::vector<Eigen::Vector2d>* image) {
  std::mt19937_64 generator(seed);
  std::uniform_real_distribution<double> uniform(-60.0, 60.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d X(100.0 + uniform(generator), 385.0 + uniform(generator), 50.0 * (i % 3));
    world->push_back(X);
    image->push_back(Project(P, X) + Eigen::Vector2d(noise(generator), noise(generator)));
  }
}

TEST(Dlt, RecoversProjectionExactlyWithoutNoise) {
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  const testing::StereoRig rig = testing::ThesisRig();
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> image;
  MakeCorrespondences(rig.P1, 27, 0.0, kSeed, &world, &image);
  DltOptions options;
  options.refine_nonlinear = false;
  const DltReport report = EstimateProjectionDlt(world, image, options);
  EXPECT_NEAR(report.P(2, 3), 1.0, 1e-12);
  const ProjectionMatrix expected = rig.P1 / rig.P1(2, 3);
  EXPECT_LT((report.P - expected).norm() / expected.norm(), 1e-8);
  EXPECT_LT(report.final.max_px, 1e-6);
  EXPECT_LT((report.camera_centre - rig.C1).norm(), 1e-5);
  EXPECT_FALSE(report.refined);
}

TEST(Dlt, SmallReprojectionErrorWithNoiseAndRefinementHelps) {
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  const testing::StereoRig rig = testing::ThesisRig();
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> image;
  const double sigma = 0.2;
  MakeCorrespondences(rig.P2, 54, sigma, kSeed + 1, &world, &image);
  const DltReport report = EstimateProjectionDlt(world, image);
  EXPECT_TRUE(report.refined);
  EXPECT_LE(report.final.rms_px, report.linear.rms_px + 1e-12);
  // With 11 of 108 degrees of freedom absorbed, the residual RMS is about sigma*sqrt(97/108).
  EXPECT_LT(report.final.rms_x_px, 1.5 * sigma);
  EXPECT_LT(report.final.rms_y_px, 1.5 * sigma);
  EXPECT_LT(report.final.mae_px, 0.3);
  EXPECT_LT((report.camera_centre - rig.C2).norm(), 10.0);
  // MAE <= RMS always; per-point figures consistent with per-axis ones.
  EXPECT_LE(report.final.mae_x_px, report.final.rms_x_px);
  EXPECT_LE(report.final.mae_px, report.final.rms_px);
  EXPECT_NEAR(
      report.final.rms_px * report.final.rms_px,
      report.final.rms_x_px * report.final.rms_x_px + report.final.rms_y_px * report.final.rms_y_px,
      1e-9);
}

TEST(Dlt, CameraCentreIsNullVector) {
  const testing::StereoRig rig = testing::ThesisRig();
  EXPECT_LT((rig.P1 * rig.C1.homogeneous()).norm(), 1e-6 * rig.P1.norm());
  EXPECT_LT((CameraCentre(rig.P1) - rig.C1).norm(), 1e-6);
  EXPECT_LT((CameraCentre(rig.P2) - rig.C2).norm(), 1e-6);
  // The thesis rig: baseline about 188 mm, both about 72 cm above the table.
  EXPECT_NEAR((rig.C1 - rig.C2).norm(), 188.5, 1.0);
}

TEST(Dlt, RefusesPlanarPoints) {
  const testing::StereoRig rig = testing::ThesisRig();
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> image;
  for (int i = 0; i < 9; ++i) {
    const Eigen::Vector3d X(80.0 + 25.0 * (i % 3), 360.0 + 25.0 * (i / 3), 0.0);
    world.push_back(X);
    image.push_back(Project(rig.P1, X));
  }
  try {
    EstimateProjectionDlt(world, image);
    FAIL() << "planar points were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("coplanar"), std::string::npos) << e.what();
  }
  // A tilted plane is refused too.
  for (auto& X : world) X.z() = 0.3 * X.x() - 0.1 * X.y() + 7.0;
  EXPECT_THROW(EstimateProjectionDlt(world, image), std::invalid_argument);
}

TEST(Dlt, RefusesTooFewPoints) {
  const testing::StereoRig rig = testing::ThesisRig();
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> image;
  MakeCorrespondences(rig.P1, 5, 0.0, kSeed, &world, &image);
  try {
    EstimateProjectionDlt(world, image);
    FAIL() << "5 points were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 6"), std::string::npos) << e.what();
  }
}

TEST(Dlt, RefusesNonFiniteAndMismatchedInput) {
  const testing::StereoRig rig = testing::ThesisRig();
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> image;
  MakeCorrespondences(rig.P1, 12, 0.0, kSeed, &world, &image);
  auto bad_image = image;
  bad_image[3].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(EstimateProjectionDlt(world, bad_image), std::invalid_argument);
  auto short_image = image;
  short_image.pop_back();
  EXPECT_THROW(EstimateProjectionDlt(world, short_image), std::invalid_argument);
  DltOptions options;
  options.min_points = 3;
  EXPECT_FALSE(options.Check().empty());
  EXPECT_THROW(EstimateProjectionDlt(world, image, options), std::invalid_argument);
}

TEST(Dlt, HartleyNormalisationHasUnitScale) {
  std::vector<Eigen::Vector2d> points = {{10, 20}, {30, 50}, {400, 20}, {200, 300}};
  const Eigen::Matrix3d T = HartleyNormalisation2D(points);
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  double mean_distance = 0.0;
  for (const auto& p : points) centroid += (T * p.homogeneous()).hnormalized() / 4.0;
  for (const auto& p : points) mean_distance += (T * p.homogeneous()).hnormalized().norm() / 4.0;
  EXPECT_LT(centroid.norm(), 1e-12);
  EXPECT_NEAR(mean_distance, std::sqrt(2.0), 1e-12);
  std::vector<Eigen::Vector3d> points3D = {{1, 2, 3}, {4, 0, 6}, {7, 8, -9}, {0, 5, 5}};
  const Eigen::Matrix4d T3 = HartleyNormalisation3D(points3D);
  double mean3 = 0.0;
  for (const auto& p : points3D) mean3 += (T3 * p.homogeneous()).hnormalized().norm() / 4.0;
  EXPECT_NEAR(mean3, std::sqrt(3.0), 1e-12);
}

TEST(ReprojectionStatistics, MaeAndRmsAreLabelledCorrectly) {
  const ReprojectionStatistics s = SummariseResiduals({{3, 0}, {0, -4}, {-3, 4}});
  EXPECT_NEAR(s.mae_x_px, 2.0, 1e-12);
  EXPECT_NEAR(s.mae_y_px, 8.0 / 3.0, 1e-12);
  EXPECT_NEAR(s.rms_x_px, std::sqrt(18.0 / 3.0), 1e-12);
  EXPECT_NEAR(s.mae_px, (3.0 + 4.0 + 5.0) / 3.0, 1e-12);
  EXPECT_NEAR(s.rms_px, std::sqrt((9.0 + 16.0 + 25.0) / 3.0), 1e-12);
  EXPECT_NEAR(s.max_px, 5.0, 1e-12);
}

}  // namespace
}  // namespace hnnstereo::calib
