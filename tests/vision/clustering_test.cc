// Leader clustering (thesis 6.2.10) and 3D grid density clustering on seeded synthetic points.
#include "vision/sensing/clustering.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

namespace hnnstereo::vision {
namespace {

constexpr unsigned kSeed = 20240704;

// Points on the outline and top of an axis-aligned box footprint, at its height, with depth noise.
void AddBoxTop(const Eigen::Vector2d& centre, double half_x, double half_y, double height,
               int count, double z_sigma, std::mt19937* random, std::vector<Eigen::Vector3d>* points) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, z_sigma);
  for (int k = 0; k < count; ++k) {
    const double along = uniform(*random);
    Eigen::Vector2d xy;
    switch (k % 4) {
      case 0: xy = {along * half_x, -half_y}; break;
      case 1: xy = {along * half_x, half_y}; break;
      case 2: xy = {-half_x, along * half_y}; break;
      default: xy = {half_x, along * half_y}; break;
    }
    xy += centre;
    points->emplace_back(xy.x(), xy.y(), height + noise(*random));
  }
}

void AddTableNoise(int count, std::mt19937* random, std::vector<Eigen::Vector3d>* points) {
  std::uniform_real_distribution<double> xy(-150.0, 150.0);
  std::normal_distribution<double> z(0.0, 1.0);
  for (int k = 0; k < count; ++k) points->emplace_back(xy(*random), xy(*random), z(*random));
}

TEST(Clustering, ParsesMethodNames) {
  EXPECT_EQ(ParseClusteringMethod("grid"), ClusteringMethod::kGrid);
  EXPECT_EQ(ParseClusteringMethod("thesis"), ClusteringMethod::kThesisLeader);
  EXPECT_FALSE(ParseClusteringMethod("kmeans").has_value());
  EXPECT_EQ(ClusteringMethodName(ClusteringMethod::kGrid), "grid");
}

TEST(Clustering, ThesisSeparatesDistinctHeightsAndRejectsTable) {
  std::mt19937 random(kSeed);
  std::vector<Eigen::Vector3d> points;
  AddBoxTop({0, 0}, 20, 15, 30.0, 200, 1.0, &random, &points);
  AddBoxTop({80, 0}, 25, 10, 60.0, 200, 1.0, &random, &points);
  AddTableNoise(300, &random, &points);
  const ClusteringReport report = ClusterByHeightLeader(points);
  ASSERT_EQ(report.clusters.size(), 2u);
  EXPECT_EQ(report.n_outside_height_window, 300);
  ASSERT_EQ(report.labels.size(), points.size());
  for (int i = 0; i < 200; ++i) EXPECT_EQ(report.labels[static_cast<std::size_t>(i)], report.labels[0]);
  EXPECT_NE(report.labels[0], report.labels[200]);
}

// The thesis's reported failure: parts of the same height that stand apart are one cluster, and
// close heights merge; the grid separates both.
TEST(Clustering, ThesisMergesSimilarHeightsWhereGridSeparates) {
  std::mt19937 random(kSeed + 1);
  std::vector<Eigen::Vector3d> points;
  AddBoxTop({0, 0}, 20, 15, 40.0, 200, 0.8, &random, &points);
  AddBoxTop({100, 50}, 20, 15, 40.0, 200, 0.8, &random, &points);   // same height, apart
  AddBoxTop({-80, 60}, 15, 15, 43.0, 200, 0.8, &random, &points);   // 3 mm taller
  AddTableNoise(200, &random, &points);
  const ClusteringReport thesis = ClusterByHeightLeader(points);
  const ClusteringReport grid = ClusterOnGrid(points);
  EXPECT_EQ(thesis.clusters.size(), 1u) << "the thesis clustering should fail here";
  ASSERT_EQ(grid.clusters.size(), 3u);
  for (int part = 0; part < 3; ++part) {
    const int label = grid.labels[static_cast<std::size_t>(part * 200)];
    ASSERT_GE(label, 0);
    for (int i = part * 200; i < part * 200 + 200; ++i) {
      EXPECT_EQ(grid.labels[static_cast<std::size_t>(i)], label) << "point " << i;
    }
  }
}

TEST(Clustering, GridDropsSparseMismatchesAndKeepsArbitraryShapes) {
  std::mt19937 random(kSeed + 2);
  std::vector<Eigen::Vector3d> points;
  // A ring (an arbitrary, non-convex shape) at 25 mm.
  std::normal_distribution<double> noise(0.0, 0.7);
  for (int k = 0; k < 400; ++k) {
    const double angle = 2 * std::numbers::pi * k / 400.0;
    points.emplace_back(60 * std::cos(angle), 60 * std::sin(angle), 25.0 + noise(random));
  }
  // Isolated mismatches in the air.
  std::uniform_real_distribution<double> anywhere(-200.0, 200.0), height(10.0, 200.0);
  for (int k = 0; k < 15; ++k) points.emplace_back(anywhere(random), anywhere(random), height(random));
  const ClusteringReport report = ClusterOnGrid(points);
  ASSERT_EQ(report.clusters.size(), 1u);
  EXPECT_GE(report.clusters[0].size(), 400u);
  EXPECT_LE(report.clusters[0].size(), 402u);  // at most a stray point that fell onto the ring
  EXPECT_GE(report.n_in_small_clusters, 13);
}

TEST(Clustering, BadOptionsThrowWithTheFieldName) {
  GridClusteringOptions grid;
  grid.cell_mm = 0.0;
  EXPECT_NE(grid.Check().find("cell_mm"), std::string::npos);
  EXPECT_THROW(ClusterOnGrid({}, grid), std::invalid_argument);
  LeaderClusteringOptions leader;
  leader.threshold_mm = -1.0;
  EXPECT_NE(leader.Check().find("threshold_mm"), std::string::npos);
  EXPECT_THROW(ClusterByHeightLeader({}, leader), std::invalid_argument);
  leader = {};
  leader.min_height_mm = 200.0;
  EXPECT_THROW(ClusterByHeightLeader({}, leader), std::invalid_argument);
}

TEST(Clustering, EmptyInputGivesNoClusters) {
  EXPECT_TRUE(ClusterOnGrid({}).clusters.empty());
  EXPECT_TRUE(ClusterByHeightLeader({}).clusters.empty());
}

}  // namespace
}  // namespace hnnstereo::vision
