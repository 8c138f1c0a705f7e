#include "calib/circle_target.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "calib/circle_calibration.h"
#include "vision/synth/circle_target_render.h"
#include "calib/dlt.h"
#include "synthetic_rig.h"

namespace hnnstereo::calib {
namespace {

constexpr std::uint64_t kSeed = 4242;

// Applies a rotation index to canonical centres (see GridRotations).
std::vector<Eigen::Vector2d> Rotated(const std::vector<Eigen::Vector2d>& centres,
                                     const std::vector<int>& rotation) {
  std::vector<Eigen::Vector2d> out(rotation.size());
  for (size_t i = 0; i < rotation.size(); ++i) out[i] = centres[static_cast<size_t>(rotation[i])];
  return out;
}

double MaxDistance(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

TEST(CircleTarget, GridRotationsAreRotations) {
  const auto square = GridRotations(3, 3);
  ASSERT_EQ(square.size(), 4u);
  // 90 degrees four times is the identity; corners move to corners.
  std::vector<int> composed = square[0];
  for (int k = 0; k < 4; ++k) {
    std::vector<int> next(9);
    for (int i = 0; i < 9; ++i) next[i] = composed[square[1][i]];
    composed = next;
  }
  EXPECT_EQ(composed, square[0]);
  EXPECT_EQ(square[1][0], 2);  // new (0,0) comes from old (0,2): a corner stays a corner
  EXPECT_EQ(square[2][0], 8);
  const auto oblong = GridRotations(3, 4);
  ASSERT_EQ(oblong.size(), 2u);
  EXPECT_EQ(oblong[1][0], 11);
}

TEST(CircleTarget, DetectsSubPixelCentres) {
  const testing::StereoRig rig = testing::ThesisRig();
  CircleGridGeometry grid;
  CircleTargetRenderOptions render;
  render.random_seed = kSeed;
  const Eigen::Matrix4d pose = WorldFromTargetFlat(Eigen::Vector3d(80, 360, 20), 0.0);
  const RenderedCircleTarget rendered = RenderCircleTarget(rig.P1, pose, grid, render);
  ASSERT_TRUE(rendered.fully_visible);
  const std::vector<CircleBlob> blobs = DetectCircleBlobs(rendered.image);
  ASSERT_EQ(blobs.size(), 9u);
  double worst = 0.0;
  for (const Eigen::Vector2d& truth : rendered.centres_px) {
    double nearest = 1e9;
    for (const CircleBlob& blob : blobs)
      nearest = std::min(nearest, (blob.centre_px - truth).norm());
    worst = std::max(worst, nearest);
  }
  EXPECT_LT(worst, 0.1) << "sub-pixel centre error";
  // Intermeans + 40 (thesis code) finds them too on this contrast.
  CircleDetectionOptions intermeans;
  intermeans.threshold = CircleDetectionOptions::Threshold::kIntermeans;
  EXPECT_EQ(DetectCircleBlobs(rendered.image, intermeans).size(), 9u);
}

TEST(CircleTarget, OrdersGridUpToRotationDespiteDistractors) {
  const testing::StereoRig rig = testing::ThesisRig();
  CircleGridGeometry grid;
  CircleTargetRenderOptions render;
  render.num_distractors = 8;
  render.random_seed = kSeed;
  for (double yaw : {0.0, 30.0, 100.0, 200.0, 315.0}) {
    const Eigen::Matrix4d pose = WorldFromTargetFlat(Eigen::Vector3d(70, 360, 40), yaw);
    const RenderedCircleTarget rendered = RenderCircleTarget(rig.P2, pose, grid, render);
    const CircleGridDetection detection = DetectCircleGrid(rendered.image, grid);
    ASSERT_TRUE(detection.found) << detection.message;
    EXPECT_GT(detection.blobs.size(), 9u) << "some distractors should pass the circularity check";
    bool some_rotation_matches = false;
    for (const auto& rotation : GridRotations(3, 3)) {
      some_rotation_matches |=
          MaxDistance(Rotated(detection.centres_px, rotation), rendered.centres_px) < 0.5;
    }
    EXPECT_TRUE(some_rotation_matches) << "yaw " << yaw;
  }
}

TEST(CircleTarget, NonSquareGridIsOrderedExactly) {
  // A 3 x 4 grid has only a 180-degree symmetry; with world +X to the right and a small yaw the
  // canonical labeling is the true one.
  const testing::StereoRig rig = testing::ThesisRig();
  CircleGridGeometry grid;
  grid.rows = 3;
  grid.cols = 4;
  grid.pitch_mm = 20.0;
  grid.circle_radius_mm = 5.0;
  CircleTargetRenderOptions render;
  render.num_distractors = 5;
  const Eigen::Matrix4d pose = WorldFromTargetFlat(Eigen::Vector3d(60, 360, 10), 12.0);
  const RenderedCircleTarget rendered = RenderCircleTarget(rig.P1, pose, grid, render);
  const CircleGridDetection detection = DetectCircleGrid(rendered.image, grid);
  ASSERT_TRUE(detection.found) << detection.message;
  EXPECT_LT(MaxDistance(detection.centres_px, rendered.centres_px), 0.5);
}

TEST(CircleTarget, ReportsMissingGrid) {
  cv::Mat blank(240, 320, CV_8UC1, cv::Scalar(200));
  const CircleGridDetection detection = DetectCircleGrid(blank, CircleGridGeometry{});
  EXPECT_FALSE(detection.found);
  EXPECT_NE(detection.message.find("circular blobs"), std::string::npos) << detection.message;
}

struct OrderingOutcome {
  int views_ordered = 0;  // views whose circles all got the right grid position, both cameras
  DltReport dlt[2];
};

// Detects and orders the target in every placement, then calibrates each camera by DLT.
OrderingOutcome DetectOrderCalibrate(const std::vector<testing::SyntheticPlacement>& placements,
                                     const CircleGridGeometry& grid) {
  const auto rotations = GridRotations(grid.rows, grid.cols);
  std::vector<std::vector<Eigen::Vector3d>> world;
  std::vector<std::vector<Eigen::Vector2d>> canonical[2], truth[2];
  for (const auto& placement : placements) {
    world.push_back(grid.PointsInWorld(placement.world_from_target));
    for (int camera = 0; camera < 2; ++camera) {
      const RenderedCircleTarget& rendered = camera == 0 ? placement.left : placement.right;
      const CircleGridDetection detection = DetectCircleGrid(rendered.image, grid);
      EXPECT_TRUE(detection.found) << detection.message;
      canonical[camera].push_back(detection.found ? detection.centres_px
                                                  : std::vector<Eigen::Vector2d>(9));
      truth[camera].push_back(rendered.centres_px);
    }
  }
  OrderingOutcome outcome;
  std::vector<bool> ordered_view(placements.size(), true);
  for (int camera = 0; camera < 2; ++camera) {
    const GridRotationChoice choice = ChooseGridRotations(world, canonical[camera], rotations);
    EXPECT_FALSE(choice.decided_by_image_rule) << "random poses decide the rotation";
    std::vector<Eigen::Vector3d> all_world;
    std::vector<Eigen::Vector2d> all_image;
    for (size_t v = 0; v < world.size(); ++v) {
      const auto ordered = Rotated(canonical[camera][v],
                                   rotations[static_cast<size_t>(choice.rotation_per_view[v])]);
      // The jitter is part of the truth: a correct ordering matches within detection error.
      if (MaxDistance(ordered, truth[camera][v]) > 1.0) ordered_view[v] = false;
      all_world.insert(all_world.end(), world[v].begin(), world[v].end());
      all_image.insert(all_image.end(), ordered.begin(), ordered.end());
    }
    outcome.dlt[camera] = EstimateProjectionDlt(all_world, all_image);
  }
  for (bool ok : ordered_view) outcome.views_ordered += ok ? 1 : 0;
  return outcome;
}

CircleTargetRenderOptions AcceptanceRenderOptions() {
  CircleTargetRenderOptions render;
  render.centre_jitter_px = 0.2;  // "0.2 px noise": per-axis localisation noise of each circle
  render.noise_sigma_grey = 2.0;
  render.blur_sigma_px = 0.8;
  render.num_distractors = 6;  // reflections, some with circular marks
  return render;
}

// Acceptance (issue 3): seeded, 3 heights, 0.2 px noise, random poses and in-plane rotations,
// distracting blobs: circles ordered correctly in 100 of 100 poses; camera centres within 2 mm;
// reprojection MAE at most 0.3 px. One calibration from 100 random poses spread over 3 heights
// (0, 50, 100 mm), thesis rig and target (3 x 3, 25 mm).
TEST(CircleTargetAcceptance, HundredRandomPosesOrderedAndCalibrated) {
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  const testing::StereoRig rig = testing::ThesisRig();
  const CircleGridGeometry grid;
  const auto placements = testing::RenderRandomPlacements(
      rig, grid, 100, kSeed, AcceptanceRenderOptions(), true, 40.0, 50.0, 3);
  ASSERT_EQ(placements.size(), 100u);
  const OrderingOutcome outcome = DetectOrderCalibrate(placements, grid);
  const double centre_error[2] = {(outcome.dlt[0].camera_centre - rig.C1).norm(),
                                  (outcome.dlt[1].camera_centre - rig.C2).norm()};
  std::printf(
      "[acceptance] 100 poses, 3 heights: ordered correctly %d of 100; camera centre error "
      "left %.3f mm, right %.3f mm; reprojection MAE left %.3f px, right %.3f px (RMS %.3f, "
      "%.3f)\n",
      outcome.views_ordered, centre_error[0], centre_error[1], outcome.dlt[0].final.mae_px,
      outcome.dlt[1].final.mae_px, outcome.dlt[0].final.rms_px, outcome.dlt[1].final.rms_px);
  EXPECT_EQ(outcome.views_ordered, 100);
  for (int camera = 0; camera < 2; ++camera) {
    EXPECT_LE(centre_error[camera], 2.0) << "camera " << camera;
    EXPECT_LE(outcome.dlt[camera].final.mae_px, 0.3) << "camera " << camera;
  }
}

// The thesis's procedure, repeated: 100 independent calibrations, each from 3 heights only
// (0, 100, 200 mm; 27 points per camera). Ordering must be right every time; the camera centre from
// 27 points at 0.2 px is only good to a few mm (the geometry, not the detector: see
// docs/calibration.md).
TEST(CircleTargetAcceptance, HundredThreeHeightCalibrations) {
  const testing::StereoRig rig = testing::ThesisRig();
  const CircleGridGeometry grid;
  int correctly_ordered = 0;
  double worst_centre_error_mm = 0.0, worst_mae_px = 0.0, sum_mae_px = 0.0;
  double sum_centre_error_mm = 0.0;
  constexpr int kTrials = 100;
  for (int trial = 0; trial < kTrials; ++trial) {
    const std::uint64_t seed = kSeed + 1 + static_cast<std::uint64_t>(trial);
    SCOPED_TRACE("trial " + std::to_string(trial) + ", seed " + std::to_string(seed));
    const auto placements = testing::RenderRandomPlacements(
        rig, grid, 3, seed, AcceptanceRenderOptions(), true, 40.0, 100.0);
    ASSERT_EQ(placements.size(), 3u);
    const OrderingOutcome outcome = DetectOrderCalibrate(placements, grid);
    correctly_ordered += outcome.views_ordered == 3 ? 1 : 0;
    for (int camera = 0; camera < 2; ++camera) {
      const double centre_error =
          (outcome.dlt[camera].camera_centre - (camera == 0 ? rig.C1 : rig.C2)).norm();
      EXPECT_LE(outcome.dlt[camera].final.mae_px, 0.3) << "camera " << camera;
      EXPECT_LE(centre_error, 20.0) << "camera " << camera;
      worst_centre_error_mm = std::max(worst_centre_error_mm, centre_error);
      worst_mae_px = std::max(worst_mae_px, outcome.dlt[camera].final.mae_px);
      sum_mae_px += outcome.dlt[camera].final.mae_px;
      sum_centre_error_mm += centre_error;
    }
  }
  std::printf(
      "[acceptance] 100 x 3-height calibrations: ordered correctly %d of %d; camera centre "
      "error mean %.3f mm, worst %.3f mm; reprojection MAE mean %.3f px, worst %.3f px\n",
      correctly_ordered, kTrials, sum_centre_error_mm / (2 * kTrials), worst_centre_error_mm,
      sum_mae_px / (2 * kTrials), worst_mae_px);
  EXPECT_EQ(correctly_ordered, kTrials);
}

TEST(CircleTargetOrdering, VerticalMovesOnlyUseTheImageRule) {
  // The thesis's setup: the robot lifts the plate straight up. The poses cannot tell the four
  // rotations apart; the rule (world +X appears rightward) decides, and with this rig it is right.
  const testing::StereoRig rig = testing::ThesisRig();
  CircleGridGeometry grid;
  CircleTargetRenderOptions render;
  std::vector<std::vector<Eigen::Vector3d>> world;
  std::vector<std::vector<Eigen::Vector2d>> canonical, truth;
  for (int h = 0; h < 3; ++h) {
    const Eigen::Matrix4d pose = WorldFromTargetFlat(Eigen::Vector3d(75, 360, 40.0 * h), 0.0);
    render.random_seed = kSeed + static_cast<std::uint64_t>(h);
    const RenderedCircleTarget rendered = RenderCircleTarget(rig.P1, pose, grid, render);
    const CircleGridDetection detection = DetectCircleGrid(rendered.image, grid);
    ASSERT_TRUE(detection.found);
    world.push_back(grid.PointsInWorld(pose));
    canonical.push_back(detection.centres_px);
    truth.push_back(rendered.centres_px);
  }
  const auto rotations = GridRotations(3, 3);
  const GridRotationChoice choice = ChooseGridRotations(world, canonical, rotations);
  EXPECT_TRUE(choice.decided_by_image_rule);
  EXPECT_EQ(choice.num_equivalent, 4);
  for (size_t v = 0; v < world.size(); ++v) {
    EXPECT_LT(MaxDistance(Rotated(canonical[v],
                                  rotations[static_cast<size_t>(choice.rotation_per_view[v])]),
                          truth[v]),
              0.5);
  }
}

}  // namespace
}  // namespace hnnstereo::calib
