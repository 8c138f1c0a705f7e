// The pick pipeline end to end on seeded synthetic scenes (issue 4 acceptance): render, calibrate
// from the rendered target images (not the truth), match, triangulate, cluster, poses.
//
// The default run checks a few scenes; HNNSTEREO_ACCEPTANCE=1 runs the full acceptance set (20
// scenes with 1-9 parts, and the same with Gaussian noise on F) and prints the figures.
#include "vision/sensing/position_sensing.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <unistd.h>

#include "calib/circle_calibration.h"
#include "calib/epipolar.h"
#include "vision/eval/truth_comparison.h"

namespace hnnstereo::vision {
namespace {

namespace fs = std::filesystem;

bool FullAcceptance() {
  const char* value = std::getenv("HNNSTEREO_ACCEPTANCE");
  return value != nullptr && std::string(value) == "1";
}

// Renders scene `seed`, writes its target images, calibrates from them.
struct CalibratedScene {
  RenderedScene scene;
  calib::StereoCalibration calibrated;
};

CalibratedScene RenderAndCalibrate(std::uint64_t seed, int num_objects) {
  SceneRenderOptions options;
  options.seed = seed;
  options.num_objects = num_objects;
  CalibratedScene result;
  result.scene = RenderScene(options);
  const RenderedTarget target = RenderTargetPlacements(result.scene.cameras, options);
  const fs::path dir = fs::temp_directory_path() /
                       ("hnnstereo_sensing_" + std::to_string(::getpid()) + "_" + std::to_string(seed));
  WriteSceneDirectory(result.scene, target, dir.string());
  result.calibrated = calib::CalibrateCircleTarget((dir / "target").string()).calibration;
  fs::remove_all(dir);
  return result;
}

// Zero-mean Gaussian noise on the entries of F (unit Frobenius norm), sigma relative to |F|.
calib::StereoCalibration WithNoisyF(calib::StereoCalibration calibration, double sigma,
                                    std::uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  calibration.F /= calibration.F.norm();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) calibration.F(r, c) += noise(random);
  }
  return calibration;
}

struct Figures {
  int true_parts = 0, detected = 0, false_objects = 0;
  std::vector<double> centroid_mm, height_mm, yaw_deg;
  double Median(std::vector<double> v) const {
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  }
  double Max(const std::vector<double>& v) const {
    double m = 0.0;
    for (double x : v) m = std::max(m, std::abs(x));
    return m;
  }
  void Add(const TruthComparison& comparison, std::size_t num_true) {
    true_parts += static_cast<int>(num_true);
    detected += comparison.detected;
    false_objects += comparison.false_objects;
    for (const TruthPairing& pair : comparison.pairs) {
      if (pair.detected_index < 0) continue;
      centroid_mm.push_back(pair.centroid_error_mm);
      height_mm.push_back(pair.height_error_mm);
      if (pair.yaw_defined) yaw_deg.push_back(pair.yaw_error_deg);
    }
  }
  void Print(const std::string& title) const {
    std::cout << title << ": recall " << detected << "/" << true_parts << ", false " << false_objects
              << ", centroid median " << Median(centroid_mm) << " max " << Max(centroid_mm)
              << " mm, |height| median " << Median([&] {
                   std::vector<double> a;
                   for (double h : height_mm) a.push_back(std::abs(h));
                   return a;
                 }())
              << " max " << Max(height_mm) << " mm, box yaw median " << Median(yaw_deg) << " max "
              << Max(yaw_deg) << " deg\n";
  }
};

// Per-scene detail for the acceptance run: every true part's errors and every false object.
void PrintScene(std::uint64_t seed, const PositionSensingReport& report, const RenderedScene& scene,
                const TruthComparison& comparison) {
  std::vector<bool> used(report.objects.size(), false);
  for (const TruthPairing& pair : comparison.pairs) {
    const SceneObject& object = scene.objects[static_cast<std::size_t>(pair.truth_index)];
    std::cout << "seed " << seed << " part " << pair.truth_index << " at (" << object.centre_mm.x()
              << ", " << object.centre_mm.y() << ") h " << object.height_mm();
    if (pair.detected_index < 0) {
      int strong = 0, weak = 0;
      for (std::size_t i = 0; i < report.points_in_world.size(); ++i) {
        const Eigen::Vector3d& p = report.points_in_world[i];
        if ((p.head<2>() - object.centre_mm).norm() < 0.5 * object.size_mm.head<2>().norm() + 3.0 &&
            std::abs(p.z() - object.height_mm()) < 5.0) {
          ++(report.weak[i] ? weak : strong);
        }
      }
      std::cout << ": MISSED (top points: " << strong << " strong, " << weak << " weak)\n";
      for (std::size_t i = 0; i < report.points_in_world.size(); ++i) {
        const Eigen::Vector3d& p = report.points_in_world[i];
        if ((p.head<2>() - object.centre_mm).norm() < 0.5 * object.size_mm.head<2>().norm() + 3.0 &&
            std::abs(p.z() - object.height_mm()) < 5.0 && std::getenv("HNNSTEREO_DEBUG")) {
          std::cout << "  " << p.transpose() << " weak " << report.weak[i] << " label "
                    << report.clustering.labels[i] << "\n";
        }
      }
      continue;
    }
    used[static_cast<std::size_t>(pair.detected_index)] = true;
    const ObjectPose& pose = report.objects[static_cast<std::size_t>(pair.detected_index)];
    std::cout << ": centroid " << pair.centroid_error_mm << " height " << pair.height_error_mm
              << " yaw " << pair.yaw_error_deg << " (points " << pose.points << ", top "
              << pose.top_points << (pose.round ? ", round" : "") << ")\n";
    if (std::getenv("HNNSTEREO_DEBUG") != nullptr) {
      std::cout << "  rectangle " << pose.top_rectangle.centre.transpose() << " "
                << pose.top_rectangle.length << " x " << pose.top_rectangle.width << " circle "
                << pose.circle_centre.transpose() << " r " << pose.circle_radius << "\n";
    }
  }
  for (std::size_t d = 0; d < report.objects.size(); ++d) {
    if (used[d]) continue;
    const ObjectPose& pose = report.objects[d];
    std::cout << "seed " << seed << " FALSE at (" << pose.centroid.x() << ", " << pose.centroid.y()
              << ") h " << pose.height_mm << " (points " << pose.points << ", top "
              << pose.top_points << ")\n";
  }
}

PositionSensingOptions CpuOptions() {
  PositionSensingOptions options;
  options.matcher.engine = hnn::EngineKind::kCpu;
  // The regression seeds' failures were found with the energy stop rule, the default until
  // the decisions rule: the tests keep the matches they were written on, so that each rule is
  // shown to matter on its own seed (the stress acceptance runs the defaults).
  options.matcher.dynamics.stop_rule = hnn::DynamicsOptions::StopRule::kEnergy;
  options.matcher.dynamics.energy_interval = 5;
  options.matcher.dynamics.stable_checks = 3;
  return options;
}

TEST(PositionSensing, TriangulationRejectsBehindCameraAndLargeResiduals) {
  const calib::StereoCalibration cameras = PickCellCameras({});
  auto project = [](const calib::ProjectionMatrix& P, const Eigen::Vector3d& X) {
    return Eigen::Vector2f((P * X.homogeneous()).hnormalized().cast<float>());
  };
  MatchReport match;
  const Eigen::Vector3d on_part(100, 380, 40);
  match.matches.push_back({project(cameras.P1, on_part), project(cameras.P2, on_part), 1.0f, 0, 0});
  // Off the epipolar line by 20 px: the rays miss each other.
  match.matches.push_back({project(cameras.P1, on_part),
                           project(cameras.P2, on_part) + Eigen::Vector2f(20.0f, 0.0f), 1.0f, 1, 1});
  // Above both cameras: reprojects exactly, but behind them.
  const Eigen::Vector3d behind(100, 380, 2000);
  match.matches.push_back({project(cameras.P1, behind), project(cameras.P2, behind), 1.0f, 2, 2});
  const PositionSensingReport report = SensePositionsFromMatches(match, cameras, CpuOptions());
  EXPECT_EQ(report.triangulation.accepted, 1);
  EXPECT_EQ(report.triangulation.large_residual, 1);
  EXPECT_EQ(report.triangulation.behind_camera, 1);
  ASSERT_EQ(report.points_in_world.size(), 1u);
  EXPECT_LT((report.points_in_world[0] - on_part).norm(), 1e-2);
  EXPECT_EQ(report.match_of_point[0], 0);
}

TEST(PositionSensing, BadOptionsAreRefused) {
  PositionSensingOptions options = CpuOptions();
  options.max_reprojection_error_px = 0.0;
  EXPECT_NE(options.Check().find("max_reprojection_error_px"), std::string::npos);
  EXPECT_THROW(SensePositionsFromMatches({}, PickCellCameras({}), options), std::invalid_argument);
  options = CpuOptions();
  options.matcher.candidates.rectified = true;
  EXPECT_FALSE(options.Check().empty());
  options = CpuOptions();
  options.touch_min_points = 0;
  EXPECT_NE(options.Check().find("touch_min_points"), std::string::npos);
  options = CpuOptions();
  options.min_touching_top_fill = 1.5;
  EXPECT_NE(options.Check().find("min_touching_top_fill"), std::string::npos);
  options = CpuOptions();
  options.min_whole_top_width_mm = -1.0;
  EXPECT_NE(options.Check().find("min_whole_top_width_mm"), std::string::npos);
  options = CpuOptions();
  options.min_points_above_top = -1;
  EXPECT_NE(options.Check().find("min_points_above_top"), std::string::npos);
  options = CpuOptions();
  options.max_whole_top_length_mm = -1.0;
  EXPECT_NE(options.Check().find("max_whole_top_length_mm"), std::string::npos);
  options = CpuOptions();
  options.image_border_px = -1.0;
  EXPECT_NE(options.Check().find("image_border_px"), std::string::npos);
  options = CpuOptions();
  options.left_out_piece_reach_mm = -1.0;
  EXPECT_NE(options.Check().find("left_out_piece_reach_mm"), std::string::npos);
  options = CpuOptions();
  options.max_round_top_roundness = -1.0;
  EXPECT_NE(options.Check().find("max_round_top_roundness"), std::string::npos);
  options = CpuOptions();
  options.min_taller_touching_points = -1;
  EXPECT_NE(options.Check().find("min_taller_touching_points"), std::string::npos);
  options = CpuOptions();
  options.shadow_strip_reach_mm = -1.0;
  EXPECT_NE(options.Check().find("shadow_strip_reach_mm"), std::string::npos);
  options = CpuOptions();
  options.pose.face_end_line_mm = -1.0;
  EXPECT_NE(options.Check().find("face_end_line_mm"), std::string::npos);
  EXPECT_THROW(SensePositionsFromMatches({}, calib::StereoCalibration{}, CpuOptions()),
               std::invalid_argument);
}

TEST(PositionSensing, CompareWithTruthPairsNearestAndCountsFalseObjects) {
  SceneObject box;
  box.centre_mm = {100, 300};
  box.size_mm = {60, 30, 50};
  box.yaw_deg = 80.0;
  ObjectPose near_box;
  near_box.centroid = {101, 300, 51};
  near_box.height_mm = 51;
  near_box.yaw_deg = -88.0;  // 12 degrees from 80 across the +-90 wrap
  ObjectPose far_away;
  far_away.centroid = {300, 100, 20};
  const TruthComparison comparison = CompareWithTruth({far_away, near_box}, {box});
  EXPECT_EQ(comparison.detected, 1);
  EXPECT_EQ(comparison.false_objects, 1);
  EXPECT_EQ(comparison.pairs[0].detected_index, 1);
  EXPECT_NEAR(comparison.pairs[0].centroid_error_mm, 1.0, 1e-12);
  EXPECT_NEAR(comparison.pairs[0].height_error_mm, 1.0, 1e-12);
  EXPECT_NEAR(comparison.pairs[0].yaw_error_deg, 12.0, 1e-9);
}

// The acceptance figures on seeded scenes calibrated from the target images.
TEST(PositionSensing, AcceptanceOnSeededScenes) {
  const int num_scenes = FullAcceptance() ? 20 : 3;
  // HNNSTEREO_ACCEPTANCE_FIRST_SEED moves the set, e.g. to held-out scenes (the thresholds were
  // tuned on seeds 100-119).
  const char* first_seed = std::getenv("HNNSTEREO_ACCEPTANCE_FIRST_SEED");
  const std::uint64_t first = first_seed ? std::stoull(first_seed) : 100;
  Figures figures;
  for (int s = 0; s < num_scenes; ++s) {
    const auto seed = first + static_cast<std::uint64_t>(s);
    const int num_objects = 1 + s % 9;
    if (const char* only = std::getenv("HNNSTEREO_ACCEPTANCE_SEED");
        only != nullptr && std::to_string(seed) != only) {
      continue;
    }
    const CalibratedScene scene = RenderAndCalibrate(seed, num_objects);
    const PositionSensingReport report =
        SensePositions(scene.scene.left, scene.scene.right, scene.calibrated, CpuOptions(), nullptr);
    const TruthComparison comparison = CompareWithTruth(report.objects, scene.scene.objects);
    if (FullAcceptance()) PrintScene(seed, report, scene.scene, comparison);
    EXPECT_EQ(comparison.detected, num_objects) << "seed " << seed;
    EXPECT_EQ(comparison.false_objects, 0) << "seed " << seed;
    figures.Add(comparison, scene.scene.objects.size());
  }
  figures.Print(std::to_string(num_scenes) + " scenes");
  EXPECT_LE(figures.Median(figures.centroid_mm), 1.5);
  EXPECT_LE(figures.Max(figures.centroid_mm), 4.0);
  EXPECT_LE(figures.Max(figures.height_mm), 2.0);
  EXPECT_LE(figures.Max(figures.yaw_deg), 2.0);
}

// Thesis 6.2.10 reports that its leader clustering on height fails when parts have too small
// height differences (or there are too many parts). A rendered scene with four parts whose
// heights lie within 4 mm (below the thesis's 5 mm threshold): the thesis clustering finds fewer
// parts than there are, the default grid clustering finds each one, from the same matches.
TEST(PositionSensing, RenderedSceneWhereThesisClusteringFailsAndGridSucceeds) {
  SceneRenderOptions options;
  // Seeds 1-6 all pass; seed 7 gives the grid clustering a false flat part at 12 mm between two
  // close parts (docs/sensing.md, known limits).
  options.seed = 1;
  options.num_objects = 4;
  options.min_height_mm = 40.0;
  options.max_height_mm = 44.0;
  const RenderedScene scene = RenderScene(options);
  ASSERT_EQ(scene.objects.size(), 4u);
  PositionSensingOptions grid = CpuOptions();
  const MatchReport match =
      MatchStereo(scene.left, scene.right, &scene.cameras, grid.matcher, nullptr);
  const PositionSensingReport grid_report =
      SensePositionsFromMatches(match, scene.cameras, grid, scene.left);
  const TruthComparison by_grid = CompareWithTruth(grid_report.objects, scene.objects);
  PrintScene(options.seed, grid_report, scene, by_grid);
  PositionSensingOptions thesis = CpuOptions();
  thesis.clustering = ClusteringMethod::kThesisLeader;
  const PositionSensingReport thesis_report =
      SensePositionsFromMatches(match, scene.cameras, thesis, scene.left);
  const TruthComparison by_thesis = CompareWithTruth(thesis_report.objects, scene.objects);
  EXPECT_EQ(by_grid.detected, 4);
  EXPECT_EQ(by_grid.false_objects, 0);
  EXPECT_LT(by_thesis.detected, 4);
  EXPECT_LT(thesis_report.objects.size(), 4u);  // parts merged into one height cluster
}

TEST(PositionSensing, ALineOfPointsOnATallPartsSideIsNotAPart) {
  // `render --seed 11 --objects 4`: an edge across the side face of a 143 mm box triangulates to
  // a 52.5 x 0.56 mm line of points at 67.7 mm - a "part" a robot would drive into the box's side
  // for. min_top_width_mm drops it.
  SceneRenderOptions options;
  options.seed = 11;
  options.num_objects = 4;
  const RenderedScene scene = RenderScene(options);
  PositionSensingOptions sensing = CpuOptions();
  // As `pick` runs it (the hnn-default preset's objective).
  sensing.matcher.energy.objective = hnn::Objective::kGeometrySimilarity;
  const MatchReport match =
      MatchStereo(scene.left, scene.right, &scene.cameras, sensing.matcher, nullptr);
  const PositionSensingReport report =
      SensePositionsFromMatches(match, scene.cameras, sensing, scene.left);
  const TruthComparison truth = CompareWithTruth(report.objects, scene.objects);
  PrintScene(options.seed, report, scene, truth);
  EXPECT_EQ(truth.detected, static_cast<int>(scene.objects.size()));
  EXPECT_EQ(truth.false_objects, 0);
  EXPECT_GE(report.narrow_top_face, 1);
  sensing.min_top_width_mm = 0.0;
  const PositionSensingReport without =
      SensePositionsFromMatches(match, scene.cameras, sensing, scene.left);
  EXPECT_GT(CompareWithTruth(without.objects, scene.objects).false_objects, 0)
      << "the failure this option exists for";
}

TEST(PositionSensing, APlainTopFaceSeenOnlyOnItsOutlineIsOnePart) {
  // Issue 12, `render --seed 549` at its defaults: a 74.8 x 59.2 mm box, 119.5 mm tall, yaw
  // -89.8 degrees, whose top face shows little but its outline. Its long edges run along the
  // epipolar lines (weak), so its top fell apart into two pieces 60 mm apart at the same height,
  // beyond the 30 mm split-face gap: two false parts 25-29 mm from the true centre and the box
  // missed. PiecesOutlineOneFace joins them.
  SceneRenderOptions options;
  options.seed = 549;
  const RenderedScene scene = RenderScene(options);
  ASSERT_EQ(scene.objects.size(), 3u);
  ASSERT_NEAR(scene.objects[0].size_mm.x(), 74.8, 0.1);
  const PositionSensingOptions sensing = CpuOptions();
  const MatchReport match =
      MatchStereo(scene.left, scene.right, &scene.cameras, sensing.matcher, nullptr);
  const PositionSensingReport report =
      SensePositionsFromMatches(match, scene.cameras, sensing, scene.left);
  const TruthComparison truth = CompareWithTruth(report.objects, scene.objects);
  PrintScene(options.seed, report, scene, truth);
  EXPECT_EQ(truth.detected, 3);
  EXPECT_EQ(truth.false_objects, 0);
  ASSERT_GE(truth.pairs[0].detected_index, 0);
  EXPECT_LT(truth.pairs[0].centroid_error_mm, 3.0);
  EXPECT_LT(truth.pairs[0].yaw_error_deg, 2.0);
  PositionSensingOptions before = sensing;
  before.pose.join_face_outlines = false;
  const PositionSensingReport split =
      SensePositionsFromMatches(match, scene.cameras, before, scene.left);
  EXPECT_GT(CompareWithTruth(split.objects, scene.objects).false_objects, 0)
      << "the failure the outline join exists for";
}

// Senses scene `options` from its true cameras with the library defaults (cpu engine).
struct SensedScene {
  RenderedScene scene;
  PositionSensingReport report;
  TruthComparison truth;
};
SensedScene SenseRendered(const SceneRenderOptions& options,
                          const PositionSensingOptions& sensing = CpuOptions()) {
  SensedScene sensed;
  sensed.scene = RenderScene(options);
  sensed.report =
      SensePositions(sensed.scene.left, sensed.scene.right, sensed.scene.cameras, sensing, nullptr);
  sensed.truth = CompareWithTruth(sensed.report.objects, sensed.scene.objects);
  PrintScene(options.seed, sensed.report, sensed.scene, sensed.truth);
  return sensed;
}

TEST(PositionSensing, SubPixelMatchesTightenTheHeights) {
  // PickCellRefinementOptions: each right point snapped onto its epipolar line and moved along
  // it to the parabola vertex of ZNCC before triangulating. `render --seed 85011`, 8 parts:
  // the worst height error with it against without (the snap alone).
  EXPECT_TRUE(PickCellRefinementOptions().epipolar_snap);
  EXPECT_TRUE(PickCellRefinementOptions().epipolar_subpixel);
  EXPECT_TRUE(PositionSensingOptions{}.refinement.epipolar_subpixel);
  SceneRenderOptions scene;
  scene.seed = 85011;
  PositionSensingOptions snap_only = CpuOptions();
  snap_only.refinement.epipolar_subpixel = false;
  const SensedScene with = SenseRendered(scene);
  const SensedScene without = SenseRendered(scene, snap_only);
  const auto worst_height = [](const SensedScene& sensed) {
    double worst = 0.0;
    for (const TruthPairing& pair : sensed.truth.pairs) {
      EXPECT_GE(pair.detected_index, 0);
      worst = std::max(worst, std::abs(pair.height_error_mm));
    }
    return worst;
  };
  EXPECT_LT(worst_height(with), 0.6 * worst_height(without));
  EXPECT_LT(worst_height(with), 0.2);
  EXPECT_GT(with.report.timing_ms.refine, 0.0);
}

TEST(PositionSensing, TwoTallPartsHidingTheTableBetweenThemStayTwo) {
  // Issue 12 stress run, `render --seed 5022`: two boxes 122 mm tall (67 x 50 and 48 x 25 mm)
  // stand 15+ mm apart; from 720 mm up they hide the table between them, so the split-face
  // join's hidden-point rule saw nothing in the gap and joined them into one part between them
  // (37.5 mm from either). Each has its own edge facing the other: they stay two.
  SceneRenderOptions options;
  options.seed = 5022;
  const SensedScene sensed = SenseRendered(options);
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  for (const TruthPairing& pair : sensed.truth.pairs) EXPECT_LT(pair.centroid_error_mm, 4.0);
}

// Scene `seed` at render's defaults as the stress run sees it (calibrated from its own target
// images: the failures below need those cameras' matches), matched once, sensed with the library
// defaults and with `before` (one rule of the island merge undone) on the same matches.
struct SensedTwice {
  RenderedScene scene;
  PositionSensingReport report, before;
  TruthComparison truth, truth_before;
};
SensedTwice SenseWithAndWithout(const SceneRenderOptions& options,
                                PositionSensingOptions before,
                                PositionSensingOptions sensing = CpuOptions()) {
  // The two flags that read a top's outline against the image and its neighbours
  // (flag_unplaced_sides, shadow_strip_reach_mm), and the vetoes on island joins
  // (join_islands_seen_as_one_face, keep_apart_longer_than_any_part), also catch many of the
  // failures the older rules were built on: where a comparison does not test one of them, it
  // is off on both sides, so that each rule is shown to matter on its own seed.
  if (before.flag_unplaced_sides == sensing.flag_unplaced_sides) {
    before.flag_unplaced_sides = sensing.flag_unplaced_sides = false;
  }
  if (before.join_islands_seen_as_one_face == sensing.join_islands_seen_as_one_face) {
    before.join_islands_seen_as_one_face = sensing.join_islands_seen_as_one_face = false;
  }
  if (before.shadow_strip_reach_mm == sensing.shadow_strip_reach_mm) {
    before.shadow_strip_reach_mm = sensing.shadow_strip_reach_mm = 0.0;
  }
  if (before.keep_apart_longer_than_any_part == sensing.keep_apart_longer_than_any_part) {
    before.keep_apart_longer_than_any_part = sensing.keep_apart_longer_than_any_part = false;
  }
  const std::uint64_t seed = options.seed;
  SensedTwice sensed;
  sensed.scene = RenderScene(options);
  const RenderedTarget target = RenderTargetPlacements(sensed.scene.cameras, options);
  const fs::path dir = fs::temp_directory_path() /
                       ("hnnstereo_sensing_" + std::to_string(::getpid()) + "_" + std::to_string(seed));
  WriteSceneDirectory(sensed.scene, target, dir.string());
  const calib::StereoCalibration cameras =
      calib::CalibrateCircleTarget((dir / "target").string()).calibration;
  fs::remove_all(dir);
  const MatchReport match =
      MatchStereo(sensed.scene.left, sensed.scene.right, &cameras, sensing.matcher, nullptr);
  sensed.report = SensePositionsFromMatches(match, cameras, sensing, sensed.scene.left);
  sensed.truth = CompareWithTruth(sensed.report.objects, sensed.scene.objects);
  PrintScene(seed, sensed.report, sensed.scene, sensed.truth);
  sensed.before = SensePositionsFromMatches(match, cameras, before, sensed.scene.left);
  sensed.truth_before = CompareWithTruth(sensed.before.objects, sensed.scene.objects);
  return sensed;
}

SensedTwice SenseWithAndWithout(std::uint64_t seed, const PositionSensingOptions& before) {
  SceneRenderOptions options;
  options.seed = seed;
  return SenseWithAndWithout(options, before);
}

// With the rule: every part found within 4 mm of its true centre, no false part; without it
// (`truth_before`), at least one part lost - the failure the rule exists for.
void ExpectEveryPartFoundAndOneLostWithoutTheRule(const SensedTwice& sensed, const char* what) {
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  for (const TruthPairing& pair : sensed.truth.pairs) EXPECT_LT(pair.centroid_error_mm, 4.0);
  EXPECT_LT(sensed.truth_before.detected, static_cast<int>(sensed.scene.objects.size())) << what;
}

// With the rule: every part found within `within_mm` of its true centre, no false part; without
// it (`truth_before`), some part's pose more than `far_before_mm` off - the failure the rule
// exists for.
void ExpectEveryPartWithinAndOneFarWithoutTheRule(const SensedTwice& sensed, double within_mm,
                                                  double far_before_mm) {
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  for (const TruthPairing& pair : sensed.truth.pairs) EXPECT_LT(pair.centroid_error_mm, within_mm);
  double worst_before = 0.0;
  for (const TruthPairing& pair : sensed.truth_before.pairs) {
    worst_before = std::max(worst_before, pair.centroid_error_mm);
  }
  EXPECT_GT(worst_before, far_before_mm) << "the failure the rule exists for";
}

TEST(PositionSensing, TwoPartsShowingTheTableBetweenThemStayTwo) {
  // Issue 12 stress run, `render --seed 10080`: a 70 x 34 mm and a 68 x 54 mm box, 58 and 57 mm
  // tall, stand 15+ mm apart. Neither shows an edge facing the other along the whole gap, and
  // the table points in the gap are few next to their points (under max_hidden_fraction), so the
  // island merge joined them into one part between them (29 mm from either, both missed). The
  // table seen in the gap (PointsSeenInTheGap, more than max_gap_points) keeps them apart.
  PositionSensingOptions before = CpuOptions();
  before.pose.max_gap_points = std::numeric_limits<int>::max();
  const SensedTwice sensed = SenseWithAndWithout(10080, before);
  ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the failure the gap-point guard exists for");
}

TEST(PositionSensing, TwoBoxesThatTheImageShowsApartStayTwo) {
  // Stress runs, `render --seed 155183`: boxes 47 x 32 and 61 x 42 mm, 50 and 48 mm tall, in a
  // row 17 mm apart with nearly the same yaw; `--seed 17139`: boxes 68 x 55 and 67 x 46 mm, 44
  // and 42 mm tall, side by side at yaws 37 degrees apart. The table between them lies in
  // shadow (few points), and the island merge joined each pair into one flagged top between
  // them: both missed. In the left image the joint top's sides do not run across the gap and
  // each box ends at an edge facing the other (join_islands_seen_as_one_face).
  PositionSensingOptions before = CpuOptions();
  before.join_islands_seen_as_one_face = false;
  for (const std::uint64_t seed : {155183u, 17139u}) {
    SCOPED_TRACE(seed);
    const SensedTwice sensed = SenseWithAndWithout(seed, before);
    ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the join the image vetoes");
  }
}

TEST(PositionSensing, TwoPiecesLongerThanAnyPartStayTwo) {
  // Fresh stress run, `render --seed 419163`: two boxes 58 x 34 and 59 x 36 mm, both 11 mm
  // tall, 72 mm apart centre to centre; the island merge joined them into one top longer than
  // any part, flagged as parts joined: both missed. A join whose top would be longer than
  // max_whole_top_length_mm is refused (keep_apart_longer_than_any_part).
  PositionSensingOptions before = CpuOptions();
  before.keep_apart_longer_than_any_part = false;
  const SensedTwice sensed = SenseWithAndWithout(419163, before);
  ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the join refused");
}

TEST(PositionSensing, ASmallBoxWithWeakLongSidesIsKeptWhenNothingFlagsIt) {
  // Stress run, `render --seed 155008`: a 54 x 29 mm box, 25 mm tall, its long sides along the
  // epipolar lines, so only its short sides' points are strong: 51, under min_strong_points,
  // and it was dropped (missed). Its top is a full 54 x 28 mm rectangle that no check flags
  // (min_strong_points_whole_top).
  PositionSensingOptions before = CpuOptions();
  before.min_strong_points_whole_top = 0;
  const SensedTwice sensed = SenseWithAndWithout(155008, before);
  ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the small part kept");
  // The part kept is one under min_strong_points, and it is sent (not flagged).
  int small_sent = 0;
  for (const ObjectPose& pose : sensed.report.objects) {
    if (pose.points < PositionSensingOptions{}.min_strong_points && !pose.merged) ++small_sent;
  }
  EXPECT_EQ(small_sent, 1);
}

TEST(PositionSensing, APlainTopFaceSeenAsItsTwoStrongEdgesIsOnePart) {
  // Stress run, hard profile (`render --seed 6017 --noise 6 --blur 1.0 --texture plain`): a
  // 43 x 35 mm box, 26 mm tall, seen only as its two 43 mm edges (strips 1 mm wide) 33 mm
  // apart. Each faced the other with a full side, as two parts' edges do, so they never joined
  // and the box was missed. Strips that long and thin are no part's face: as a face's opposite
  // ends that outline it together they join (min_edge_strip_aspect).
  SceneRenderOptions options;
  options.seed = 6017;
  options.noise_sigma_grey = 6.0;
  options.blur_sigma_px = 1.0;
  options.top_texture = TopTexture::kPlain;
  PositionSensingOptions before = CpuOptions();
  before.pose.min_edge_strip_aspect = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(options, before);
  ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the failure the rule exists for");
}

TEST(PositionSensing, APlainBoxsBaseEdgeDoesNotKeepItsTopFaceApart) {
  // Stress run, hard profile (`render --seed 6080 --noise 6 --blur 1.0 --texture plain`): a
  // 75 x 52 mm box, 80 mm tall, whose plain top came out as two halves 10 mm apart. Its base
  // edge, seen at the table 1-3 mm inside the top's outline, counted as points hidden under
  // the joint top (28, over max_hidden_fraction), so the halves stayed apart: a false part and
  // the box's pose 18 mm off. Points within hidden_margin_mm of the outline are not hidden.
  SceneRenderOptions options;
  options.seed = 6080;
  options.noise_sigma_grey = 6.0;
  options.blur_sigma_px = 1.0;
  options.top_texture = TopTexture::kPlain;
  PositionSensingOptions before = CpuOptions();
  before.pose.hidden_margin_mm = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(options, before);
  ExpectEveryPartWithinAndOneFarWithoutTheRule(sensed, 4.0, 10.0);
  EXPECT_GT(sensed.truth_before.false_objects, 0) << "the failure the rule exists for";
}

TEST(PositionSensing, PiecesInLineOutlineNoFace) {
  // Stress run, `render --seed 13124`: a 35 mm line of points on a tall box's side and a piece
  // of a cylinder's rim 162 mm away, both at 53.5 mm, lay on the outline of their joint 220 x
  // 7.5 mm rectangle and joined into a false part once the base edge no longer counted as
  // hidden (hidden_margin_mm: a 7.5 mm wide hull has no point 3 mm inside it). A joint
  // rectangle that is itself a strip (min_edge_strip_aspect) outlines no face.
  PositionSensingOptions before = CpuOptions();
  before.pose.min_edge_strip_aspect = 0.0;
  before.max_whole_top_length_mm = 0.0;  // the strip rule drops that false part too: off
  const SensedTwice sensed = SenseWithAndWithout(13124, before);
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  EXPECT_GT(sensed.truth_before.false_objects, 0) << "the failure the rule exists for";
}

TEST(PositionSensing, SpecksDoNotOutlineOneFaceAcrossTwoParts) {
  // Issue 12 stress run, `render --seed 10163`: two 72 x 52 mm boxes, 31 mm tall, 40 mm apart
  // end to end, each seen in pieces. A 3.5 x 3.0 mm speck "outlined one face" with a piece 140
  // mm away and the grown piece swallowed both boxes into a 185 mm part (a false part 56 mm
  // off, a pose 23 mm off, a box missed). A piece must be a stretch of the joint outline
  // (min_outline_piece_fraction).
  PositionSensingOptions before = CpuOptions();
  before.pose.min_outline_piece_fraction = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(10163, before);
  ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the failure the rule exists for");
}

TEST(PositionSensing, ATopFaceSeenAsItsTwoLongEdgesIsOnePart) {
  // Issue 12 stress run, `render --seed 10179`: a 71 x 58 mm box, 108 mm tall, seen as its two
  // 71 mm edges (lines 1-2 mm wide) 58 mm apart and specks. A 2.8 mm speck near one edge
  // "faced" it with its whole 2.8 mm side, so it never joined, and the two bare lines each
  // faced the other with a full edge: they stayed apart and the box was missed. A facing side
  // needs min_facing_side_mm; the speck joins the edge and the face comes together. The two
  // lines are edge strips too (min_edge_strip_aspect), which alone also joins them: both rules
  // are undone for the comparison.
  PositionSensingOptions before = CpuOptions();
  before.pose.min_facing_side_mm = 0.0;
  before.pose.min_edge_strip_aspect = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(10179, before);
  ExpectEveryPartFoundAndOneLostWithoutTheRule(sensed, "the failure the rule exists for");
}

TEST(PositionSensing, PiecesOfOneEdgeInLineJoin) {
  // Issue 12 stress run, `render --seed 10188`: a 74 x 62 mm box, 141 mm tall, whose far edge
  // came out as two pieces in line 17 mm apart; each "faced" the other with its 0.5 mm end, so
  // they never joined and the box's pose lay 16 mm off its centre (flagged merged). A facing
  // side needs min_facing_side_mm.
  PositionSensingOptions before = CpuOptions();
  before.pose.min_facing_side_mm = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(10188, before);
  ASSERT_GE(sensed.truth.pairs[0].detected_index, 0);
  EXPECT_LT(sensed.truth.pairs[0].centroid_error_mm, 3.0);
  EXPECT_EQ(sensed.truth.false_objects, 0);
  const TruthPairing& pair_before = sensed.truth_before.pairs[0];
  EXPECT_TRUE(pair_before.detected_index < 0 || pair_before.centroid_error_mm > 4.0)
      << "the failure the rule exists for";
}

TEST(PositionSensing, ALinePointingAtAPartDoesNotJoinIt) {
  // Issue 12 stress run, `render --seed 11088`: a 24 mm line of points at 24 mm height points
  // end-on at a 44 x 31 mm box, 23 mm tall, 11 mm away. With min_facing_side_mm applied towards
  // whole parts too, the line's end was no edge, the near-piece rule joined it and the box's pose
  // lay 17 mm off (flagged merged). An end is no edge only towards a line or a speck
  // (max_thin_piece_width_mm).
  PositionSensingOptions before = CpuOptions();
  before.pose.max_thin_piece_width_mm = std::numeric_limits<double>::infinity();
  const SensedTwice sensed = SenseWithAndWithout(11088, before);
  ExpectEveryPartWithinAndOneFarWithoutTheRule(sensed, 4.0, 10.0);
}

TEST(PositionSensing, ALoneMismatchDoesNotStretchTheTopFace) {
  // Issue 12 stress run, `render --seed 10147`: a 72 x 43 mm box, 114 mm tall; a streak of
  // mismatches rising off its top left one point in the top layer 12 mm beyond its edge, and
  // the top rectangle (72 x 56 mm) put the centre 5.8 mm off. Lone top points are left out of
  // the outline (min_top_group_points).
  // The image edges pull that side back in too (extend_tops_to_image_edges): off, to see this
  // rule alone.
  PositionSensingOptions with = CpuOptions();
  with.extend_tops_to_image_edges = false;
  PositionSensingOptions before = with;
  before.pose.min_top_group_points = 0;
  SceneRenderOptions scene;
  scene.seed = 10147;
  const SensedTwice sensed = SenseWithAndWithout(scene, before, with);
  ExpectEveryPartWithinAndOneFarWithoutTheRule(sensed, 3.0, 4.0);
}

TEST(PositionSensing, AChainOfPointsBeyondTheFaceDoesNotStretchIt) {
  // Stress run, `render --seed 17136`: a 64 x 46 mm box, 38 mm tall; a chain of 25 points at
  // its top height (an edge on a neighbour's side) ran from 14 to 29 mm past its end, a group
  // too large for min_top_group_points, and the top rectangle (91 x 47 mm) put the centre 13 mm
  // off, unflagged. Groups under a tenth of the largest are left out of the outline
  // (min_top_group_fraction).
  PositionSensingOptions before = CpuOptions();
  before.pose.min_top_group_fraction = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(17136, before);
  ExpectEveryPartWithinAndOneFarWithoutTheRule(sensed, 3.0, 10.0);
}

TEST(PositionSensing, ASmallTopKeepsTheCornersThatOrientIt) {
  // Issue 12 stress run, `render --seed 11054`: a 34 x 27 mm box, 120 mm tall, whose top shows
  // two of its corners as groups of under min_top_group_points. Left out as mismatches, they
  // turned the rectangle 73 degrees (flagged merged). Small groups are left out only where the
  // rectangle keeps its orientation (max_trim_yaw_change_deg): mismatches stretch it, they do
  // not turn it.
  PositionSensingOptions before = CpuOptions();
  before.pose.max_trim_yaw_change_deg = 180.0;
  const SensedTwice sensed = SenseWithAndWithout(11054, before);
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  for (const TruthPairing& pair : sensed.truth.pairs) {
    EXPECT_LT(pair.centroid_error_mm, 3.0);
    if (pair.yaw_defined) {
      EXPECT_LT(pair.yaw_error_deg, 2.0);
    }
  }
  EXPECT_EQ(sensed.report.merged, 0);
  double worst_yaw_before = 0.0;
  for (const TruthPairing& pair : sensed.truth_before.pairs) {
    if (pair.yaw_defined) worst_yaw_before = std::max(worst_yaw_before, pair.yaw_error_deg);
  }
  EXPECT_GT(worst_yaw_before, 10.0) << "the failure the rule exists for";
}

TEST(PositionSensing, ARoundTopStaysApartFromABoxBesideIt) {
  // Issue 12 stress run, `render --seed 10099`: a round 53 mm top and a 39 x 29 mm box, both
  // 12 mm tall, 15+ mm apart, joined into one part between them (27.7 mm from either, flagged
  // merged): the round-top rule refused only a piece outside the larger cluster's circle, and
  // here the round one was the smaller.
  SceneRenderOptions options;
  options.seed = 10099;
  const SensedScene sensed = SenseRendered(options);
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  for (const TruthPairing& pair : sensed.truth.pairs) EXPECT_LT(pair.centroid_error_mm, 4.0);
}

TEST(PositionSensing, ATopFaceSeenAsItsTwoEndsIsOnePart) {
  // Issue 12 stress run, `render --seed 5064`: a 68 x 49 mm box, 93 mm tall, yaw 89.5 degrees:
  // its long sides run along the epipolar lines (weak), so its top came out as its two ends
  // (48.4 x 21.9 and 47.9 x 16.3 mm pieces, each an edge with the marks near it) 68 mm apart:
  // a false part and a pose 23 mm off. PiecesAreOppositeEndsOfOneFace joins them.
  SceneRenderOptions options;
  options.seed = 5064;
  const SensedScene sensed = SenseRendered(options);
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_EQ(sensed.truth.false_objects, 0);
  for (const TruthPairing& pair : sensed.truth.pairs) EXPECT_LT(pair.centroid_error_mm, 4.0);
}

TEST(PositionSensing, TouchingPartsGiveNoUnflaggedPoseBetweenThem) {
  // `render --seed 7018 --min-gap 0`: parts of similar height touch and join in the clustering;
  // the joint top face fills its rectangle poorly (0.78), so the part is flagged merged (the
  // safety gate refuses it) instead of being sent as a pose 29 mm from either part.
  SceneRenderOptions options;
  options.seed = 7018;
  options.min_gap_mm = 0.0;
  const SensedScene sensed = SenseRendered(options);
  int merged = 0;
  for (const ObjectPose& pose : sensed.report.objects) {
    double nearest_mm = 1e300;
    for (const SceneObject& object : sensed.scene.objects) {
      nearest_mm = std::min(nearest_mm, (pose.centroid.head<2>() - object.centre_mm).norm());
    }
    if (pose.merged) ++merged;
    EXPECT_TRUE(pose.merged || nearest_mm <= 4.0)
        << "pose at (" << pose.centroid.x() << ", " << pose.centroid.y() << ") is " << nearest_mm
        << " mm from every part and not flagged merged";
  }
  EXPECT_GE(merged, 1);
  EXPECT_EQ(sensed.report.merged, merged);
  const nlohmann::json json = ObjectsJson(sensed.report, CpuOptions());
  int flagged = 0;
  for (const auto& object : json["objects"]) flagged += object["merged"].get<bool>() ? 1 : 0;
  EXPECT_EQ(flagged, merged);
}

TEST(ObjectsJson, ARoundPartHasYawNull) {
  // A round part has no orientation: OBJECTS.json says null rather than a meaningless angle.
  PositionSensingReport report;
  report.objects.resize(2);
  report.objects[0].round = true;
  report.objects[0].yaw_deg = 86.8;
  report.objects[1].yaw_deg = 12.5;
  const nlohmann::json json = ObjectsJson(report, PositionSensingOptions{});
  ASSERT_EQ(json["objects"].size(), 2u);
  EXPECT_TRUE(json["objects"][0]["yaw_deg"].is_null());
  EXPECT_EQ(json["objects"][1]["yaw_deg"].get<double>(), 12.5);
}

// The thesis's robustness test: zero-mean Gaussian noise on the entries of F (unit Frobenius
// norm), sigma = kFNoiseSigma. The test prints the mean epipolar distance this noise puts between
// true correspondences (the calibrated F gives about 0.05 px).
constexpr double kFNoiseSigma = 5e-7;

// Unflagged poses of `report` more than 4 mm from every true top-face centre.
int FarUnflaggedPoses(const PositionSensingReport& report, const RenderedScene& scene) {
  int far = 0;
  for (const ObjectPose& pose : report.objects) {
    double nearest_mm = 1e300;
    for (const SceneObject& object : scene.objects) {
      nearest_mm = std::min(nearest_mm, (pose.centroid.head<2>() - object.centre_mm).norm());
    }
    if (!pose.merged && nearest_mm > 4.0) ++far;
  }
  return far;
}

// With the rule: no unflagged pose more than 4 mm from every true centre; without it
// (`before`), at least one - the failure the rule exists for.
void ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(const SensedTwice& sensed) {
  EXPECT_EQ(FarUnflaggedPoses(sensed.report, sensed.scene), 0);
  EXPECT_GE(FarUnflaggedPoses(sensed.before, sensed.scene), 1) << "the failure the rule exists for";
}

// `render --seed SEED --min-gap 0` (touching parts) sensed with the defaults and with `before`.
SensedTwice SenseTouchingWithAndWithout(std::uint64_t seed, const PositionSensingOptions& before,
                                        const PositionSensingOptions& sensing = CpuOptions()) {
  SceneRenderOptions options;
  options.seed = seed;
  options.min_gap_mm = 0.0;
  return SenseWithAndWithout(options, before, sensing);
}

TEST(PositionSensing, TouchingPartsOfUnequalHeightAreSeparated) {
  // Stress run, `render --seed 9034 --min-gap 0`: two touching cylinders, 74 and 63 mm across,
  // 71 and 66 mm tall, joined in the clustering; both tops lay in one top layer, so the part
  // was reported unflagged at 68.6 mm, 32 mm from either. Its top layer holds two heights side
  // by side: SplitTopLevels separates them (the 63 mm one is found; the other's remaining
  // cluster is flagged merged).
  SceneRenderOptions options;
  options.seed = 9034;
  options.min_gap_mm = 0.0;
  PositionSensingOptions before = CpuOptions();
  before.pose.min_top_level_difference_mm = 0.0;
  // The touch, length and image-border rules flag it too: off, to see this rule alone.
  before.min_touching_top_fill = 0.0;
  before.max_whole_top_length_mm = 0.0;
  before.image_border_px = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(options, before);
  EXPECT_EQ(FarUnflaggedPoses(sensed.report, sensed.scene), 0);
  EXPECT_GE(sensed.report.top_level_splits, 1);
  EXPECT_GT(sensed.truth.detected, sensed.truth_before.detected);
  EXPECT_GE(FarUnflaggedPoses(sensed.before, sensed.scene), 1) << "the failure the rule exists for";
}

TEST(PositionSensing, APieceOfAnOutlineThatFitsACircleByChanceIsFlagged) {
  // Stress run, `render --seed 9029 --min-gap 0`: a 72 x 36 mm box, 19 mm tall, touching
  // others, seen as a 72 x 27 mm piece of its outline (fill 0.52) whose few hull vertices fit a
  // circle to 2.3 % - exempt from the merged flag as if a disc, its pose 4.9 mm off. Any piece
  // of a disc fills at least 2/3 of its rectangle (min_round_top_fill).
  PositionSensingOptions before = CpuOptions();
  before.min_round_top_fill = 0.0;
  // The piece touches its neighbours, so min_touching_top_fill flags it too: off, to see this
  // rule alone.
  before.min_touching_top_fill = 0.0;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(9029, before));
}

TEST(PositionSensing, TwoTouchingPartsJoinedIntoOneAreFlagged) {
  // Stress run, `render --seed 39002 --min-gap 0`: a 64 x 45 mm box and a cylinder 64 mm across,
  // both 89 mm tall, touching, joined by the clustering into one 145 x 69 mm top that filled
  // 0.80 of its rectangle (just at min_top_fill): reported unflagged 34 mm from either part.
  // Beside another part (touching_points), only a full rectangle is trusted
  // (min_touching_top_fill).
  PositionSensingOptions before = CpuOptions();
  before.min_touching_top_fill = 0.0;
  before.max_whole_top_length_mm = 0.0;  // 145 mm long: the length rule flags it too
  const SensedTwice sensed = SenseTouchingWithAndWithout(39002, before);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  int touching = 0;
  for (const ObjectPose& pose : sensed.report.objects) touching += pose.touching_points > 0;
  EXPECT_GE(touching, 1);
}

TEST(PositionSensing, ATopCutByATallerNeighboursShadowIsFlagged) {
  // Stress run, `render --seed 19027 --min-gap 0`: a 61 x 35 mm box, 25 mm tall, among taller
  // parts that hide part of its top from the cameras: seen as 47 x 30 mm (fill 0.87), its pose
  // 7.5 mm off and unflagged; the neighbours' points lie 12 mm or more from the cut rectangle
  // in the table plane, but their rays from the cameras cross the plane of its top beside it.
  PositionSensingOptions before = CpuOptions();
  before.min_touching_top_fill = 0.0;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(19027, before));
}

TEST(PositionSensing, AStripWhoseHullFitsACircleIsNotRound) {
  // Stress run, `render --seed 25025`: a 158 x 22 mm strip of points at 15.6 mm (edges of
  // several parts' sides) whose hull vertices sat at its two ends, near its corners, on the
  // rectangle's circumscribed circle: the whole-hull circle fit was 1.6 % off, so the strip was
  // "round" (radius 89 mm), exempt from every flag, and reported as a part 41 mm from any. Its
  // points cover a twelfth of that rim; the rim-coverage test now holds for the whole-hull fit.
  PositionSensingOptions before = CpuOptions();
  before.pose.min_rim_coverage = 0.0;
  before.max_whole_top_length_mm = 0.0;  // 158 mm long: the length rule flags it too
  const SensedTwice sensed = SenseWithAndWithout(25025, before);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  for (const ObjectPose& pose : sensed.report.objects) {
    if (pose.round) {
      EXPECT_LT(pose.circle_radius, 40.0);  // render's discs are at most 75 mm across
    }
  }
}

TEST(PositionSensing, APartJoinedWithATallerUnreportedPartIsFlagged) {
  // Stress run, `render --seed 59096 --min-gap 0`: a 48 x 37 mm box, 12 mm tall, touching a
  // 31 x 25 mm box 20 mm tall; the clustering joined them, the lower top was the denser, and the
  // taller box's walls stretched its rectangle to 85 x 38 mm (fill 0.84): reported unflagged
  // 18 mm off, the taller box missed. 130 of the cluster's points lie more than 5 mm above its
  // top (min_points_above_top).
  PositionSensingOptions before = CpuOptions();
  before.min_points_above_top = 0;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(59096, before));
}

TEST(PositionSensing, ATopLongerThanAnyPartIsFlagged) {
  // Stress run, `render --seed 79045 --min-gap 0`: two touching parts of equal height joined
  // into one 119 x 66 mm top that filled 0.80 of its rectangle, with nothing else beside them:
  // reported unflagged 27 mm from either. No part render draws is that long
  // (max_whole_top_length_mm).
  PositionSensingOptions before = CpuOptions();
  before.max_whole_top_length_mm = 0.0;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(79045, before));
}

TEST(PositionSensing, AFaceEndCutOffWithTheSmallGroupsComesBack) {
  // Stress run, `render --seed 69083 --min-gap 0`: a 74 x 28 mm box, 146 mm tall, nothing
  // beside it; its end edges lie along the epipolar lines (weak), so its far corners were two
  // groups of 12 and 10 points beside a chain of 135, left out as mismatches: seen 62 mm long,
  // reported unflagged 6.1 mm off. Both corners lie on the lines of the sides
  // (ObjectPoseOptions::face_end_line_mm).
  // The image edges complete these tops too (extend_tops_to_image_edges): off, to see this rule
  // alone.
  PositionSensingOptions with = CpuOptions();
  with.extend_tops_to_image_edges = false;
  PositionSensingOptions before = with;
  before.pose.face_end_line_mm = 0.0;
  const SensedTwice sensed = SenseTouchingWithAndWithout(69083, before, with);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  for (const TruthPairing& pair : sensed.truth.pairs) EXPECT_LT(pair.centroid_error_mm, 1.0);
  // `render --seed 79061 --min-gap 0`: a 68 x 29 mm top seen 57 mm long (4.7 mm off) whose far
  // corners were groups of 3 and 2 points, both about 10 mm past the kept points' end.
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(79061, before, with));
}

TEST(PositionSensing, ABoxTopStretchedPastItsEdgeMovesInToTheImageEdge) {
  // Stress runs: `render --seed 85156`, a 43 x 36 mm box, 78 mm tall, seen 53 mm long (a taller
  // neighbour's points joined to it at its top height), reported unflagged 4.6 mm off; hard
  // profile `render --seed 48039 --noise 6 --blur 1.0 --texture plain`, a 39 x 28 mm plain top
  // seen 38 mm wide, 4.7 mm off. No image edge lies under the stretched side, the face's edge
  // lies inside it, and few of the top's points lie beyond that edge
  // (TopFaceEdgeOptions::max_inward_mm, max_cut_fraction).
  PositionSensingOptions before = CpuOptions();
  before.extend_tops_to_image_edges = false;
  // (85156 also holds two touching parts reported as one, flagged merged, far from both.)
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseWithAndWithout(85156, before));
  SceneRenderOptions hard;
  hard.seed = 48039;
  hard.noise_sigma_grey = 6.0;
  hard.blur_sigma_px = 1.0;
  hard.top_texture = TopTexture::kPlain;
  ExpectEveryPartWithinAndOneFarWithoutTheRule(SenseWithAndWithout(hard, before), 3.0, 4.0);
}

TEST(PositionSensing, ABoxTopWhoseEndEdgesAreWeakIsCompletedFromTheImage) {
  // Stress run, `render --seed 85011`: a 67 x 36 mm box, 48 mm tall, nothing beside it; its end
  // edges lie along the epipolar lines, and the matches at one end were weak or wrong: seen
  // 58 mm long, reported unflagged 4.2 mm off. The left image shows that end's edge and the
  // sides running up to it (PositionSensingOptions::extend_tops_to_image_edges).
  PositionSensingOptions before = CpuOptions();
  before.extend_tops_to_image_edges = false;
  const SensedTwice sensed = SenseWithAndWithout(85011, before);
  ExpectEveryPartWithinAndOneFarWithoutTheRule(sensed, 1.0, 4.0);
  double extension = 0.0;
  for (const ObjectPose& pose : sensed.report.objects) {
    extension = std::max(extension, pose.image_edge_moved_mm);
  }
  EXPECT_GT(extension, 5.0);
  // The face-end rule's seed (below) is completed by the image too, without that rule.
  PositionSensingOptions without_face_ends = CpuOptions();
  without_face_ends.pose.face_end_line_mm = 0.0;
  PositionSensingOptions neither = without_face_ends;
  neither.extend_tops_to_image_edges = false;
  const SensedTwice face_end = SenseTouchingWithAndWithout(69083, neither, without_face_ends);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(face_end);
}

TEST(PositionSensing, ABoxTopEndingInANeighboursShadowIsCompletedFromTheImage) {
  // Stress run, `render --seed 69049 --min-gap 0`: a 64 x 49 mm box, 43 mm tall, the far third
  // of its top in a neighbour's shadow. The points stopped at the shadow's edge, a strong image
  // edge, and it was seen 51 mm long, reported unflagged 6.3 mm off. The top's sides go on past
  // that edge in the image, still brighter than the shadowed table, to its end
  // (TopFaceEdgeOptions::look_past_lines_on_face).
  PositionSensingOptions before = CpuOptions();
  before.top_edges.look_past_lines_on_face = false;
  const SensedTwice sensed = SenseTouchingWithAndWithout(69049, before);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
}

TEST(PositionSensing, ABoxTopEndingInAShadowAsDarkAsItsWallIsCompletedOrFlagged) {
  // Fresh stress runs: `render --seed 259055`, a 65 x 40 mm box 58 mm tall, and `render --seed
  // 239086 --min-gap 0`, a 59 x 41 mm box 56 mm tall, each with its far 11-15 mm in a taller
  // neighbour's shadow. There the face and the wall the camera sees beside one of its sides are
  // equally dark, so that side's only edge is the wall's base, 2.5 mm further out: the look past
  // the shadow's edge failed, and the tops were sent 6.5 and 7.7 mm off. The sides' lines may
  // now lie out to the wall's seen width; an edge found outward is looked past too; a side at
  // such a line whose end is not found counts as unplaced (flagged).
  PositionSensingOptions before = CpuOptions();
  before.top_edges.look_past_lines_on_face = false;
  {
    SCOPED_TRACE(259055);
    const SensedTwice sensed = SenseWithAndWithout(259055, before);
    EXPECT_EQ(FarUnflaggedPoses(sensed.report, sensed.scene), 0);
    EXPECT_GE(FarUnflaggedPoses(sensed.before, sensed.scene), 1) << "the failure the rule exists for";
  }
  {
    SCOPED_TRACE(239086);
    ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(239086, before));
  }
}

TEST(PositionSensing, ABoxTopStretchedToItsShadowsFarEdgeIsCutBack) {
  // Fresh stress run, `render --seed 249002 --min-gap 0`: a lone 67 x 45 mm box, 36 mm tall;
  // 49 points matched along the far edge of its shadow on the table, at the top's height 13
  // mm beyond its side, were joined to its top, seen 58 mm wide and sent 6.6 mm off. That edge
  // is brighter outward, the face darker outward along its sides: it is no end of the face
  // (TopFaceEdgeOptions::end_edge_polarity), and the side moves in to the face's edge.
  PositionSensingOptions before = CpuOptions();
  before.top_edges.end_edge_polarity = false;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(249002, before));
}

// The unplaced sides (TopFaceEdgeReport::unplaced_sides) of the last pose that `is_it`
// picks, -1 when none does.
int UnplacedSidesOfThePose(const PositionSensingReport& report,
                           const std::function<bool(const ObjectPose&)>& is_it) {
  int unplaced = -1;
  for (const ObjectPose& pose : report.objects) {
    if (is_it(pose)) unplaced = pose.unplaced_sides;
  }
  return unplaced;
}

TEST(PositionSensing, ABoxTopsSidesAreTestedAgainWhereTheyMoved) {
  // Fresh stress run, `render --seed 299057 --min-gap 0`: a 71 x 30 mm box, 12 mm tall, whose
  // far end lies in a 138 mm cylinder's shadow, seen 52 x 36 mm. Its end at the shadow's edge
  // was tested while its sides still lay 2-5 mm off the face's edges (one moved in after it),
  // so the face's sides did not show past that edge and the top was sent 9.6 mm off. Tested
  // again where the sides moved (TopFaceEdgeOptions::second_pass), the end is a line across
  // the face whose end is not found: flagged.
  // (SenseWithAndWithout turns the unplaced-side flag off on both sides: the test reads the
  // count it flags on.)
  PositionSensingOptions before = CpuOptions();
  before.top_edges.second_pass = false;
  const SensedTwice sensed = SenseTouchingWithAndWithout(299057, before);
  const auto unplaced_at_the_low_box = [](const PositionSensingReport& report) {
    return UnplacedSidesOfThePose(report, [](const ObjectPose& pose) {
      return std::abs(pose.height_mm - 12.4) < 2.0;
    });
  };
  EXPECT_GE(unplaced_at_the_low_box(sensed.report), 1);
  EXPECT_EQ(unplaced_at_the_low_box(sensed.before), 0) << "the failure the rule exists for";
  EXPECT_GE(FarUnflaggedPoses(sensed.before, sensed.scene), 1);
}

TEST(PositionSensing, ABoxTopsEndBesideItsOwnWallIsPlaced) {
  // Development range, `render --seed 155049`: a 54 x 27 mm box, 56 mm tall, the left camera
  // seeing its end wall 11 mm wide beyond its end, in line with its sides. Once its sides had
  // moved onto the face's edges (the second pass), the wall's edges went on past that end like
  // the face's sides past a shadow's edge, no end was found beyond the wall, and the good
  // pose (0.1 mm off) was flagged unplaced. The sides stop past the wall: the end is placed
  // (TopFaceEdgeOptions::end_at_own_wall).
  PositionSensingOptions before = CpuOptions();
  before.top_edges.end_at_own_wall = false;
  const SensedTwice sensed = SenseWithAndWithout(155049, before);
  const auto unplaced_at = [](const PositionSensingReport& report) {
    return UnplacedSidesOfThePose(report, [](const ObjectPose& pose) {
      return (pose.centroid.head<2>() - Eigen::Vector2d(148.1, 320.1)).norm() < 2.0;
    });
  };
  EXPECT_EQ(unplaced_at(sensed.report), 0);
  EXPECT_GE(unplaced_at(sensed.before), 1) << "the cost the rule exists for";
}

TEST(PositionSensing, BoxTopsTakeTheirYawFromTheImagesEdges) {
  // Fresh stress run, `render --seed 389145`: a 55 x 43 mm box whose points' rectangle was
  // turned 9.7 degrees off the face - the outline points scatter and stop short where the
  // edges run along the epipolar lines. Turned to the image's edges
  // (TopFaceEdgeOptions::max_yaw_turn_deg), every box is within 2 degrees.
  PositionSensingOptions before = CpuOptions();
  before.top_edges.max_yaw_turn_deg = 0.0;
  for (const std::uint64_t seed : {389145u}) {
    SCOPED_TRACE(seed);
    const SensedTwice sensed = SenseWithAndWithout(seed, before);
    const auto worst_yaw = [](const TruthComparison& truth) {
      double worst = 0.0;
      for (const TruthPairing& pair : truth.pairs) {
        if (pair.detected_index >= 0 && pair.yaw_defined) {
          worst = std::max(worst, pair.yaw_error_deg);
        }
      }
      return worst;
    };
    EXPECT_LE(worst_yaw(sensed.truth), 2.0);
    EXPECT_GE(worst_yaw(sensed.truth_before), 3.0) << "the failure the rule exists for";
  }
}

TEST(PositionSensing, ABoxTopThatFillsItsRectangleIsNoDisc) {
  // Fresh stress run, `render --seed 389199`: a 72 x 29 mm box whose top, a full rectangle
  // (fill 0.99), fitted the robust circle of a partly seen disc - its ends lie on the
  // circumscribed circle - and was sent as a round top, with yaw 0 (gap0 439006 likewise: a
  // 73 x 59 mm box sent 4.1 mm off from the circle's centre). A disc, whole or cut by a
  // chord, fills at most about 0.85 of its rectangle (ObjectPoseOptions::max_round_top_fill).
  PositionSensingOptions before = CpuOptions();
  before.pose.max_round_top_fill = 1.0;
  const SensedTwice sensed = SenseWithAndWithout(389199, before);
  int round_boxes = 0, round_boxes_before = 0;
  double worst_yaw = 0.0, worst_yaw_before = 0.0;
  for (std::size_t i = 0; i < sensed.scene.objects.size(); ++i) {
    if (sensed.scene.objects[i].shape != SceneObject::Shape::kBox) continue;
    const TruthPairing& pair = sensed.truth.pairs[i];
    const TruthPairing& pair_before = sensed.truth_before.pairs[i];
    if (pair.detected_index >= 0) {
      round_boxes += sensed.report.objects[static_cast<std::size_t>(pair.detected_index)].round;
      worst_yaw = std::max(worst_yaw, pair.yaw_error_deg);  // the yaw sent: 0 when round
    }
    if (pair_before.detected_index >= 0) {
      round_boxes_before +=
          sensed.before.objects[static_cast<std::size_t>(pair_before.detected_index)].round;
      worst_yaw_before = std::max(worst_yaw_before, pair_before.yaw_error_deg);
    }
  }
  EXPECT_EQ(round_boxes, 0);
  EXPECT_LE(worst_yaw, 2.0);
  EXPECT_GE(round_boxes_before, 1) << "the failure the rule exists for";
  EXPECT_GT(worst_yaw_before, 10.0);
}

TEST(PositionSensing, ABoxTopWithAnEmptyStripToATallerPartIsFlagged) {
  // Stress run, `render --seed 179050 --min-gap 0`: a 75 x 50 mm box, 80 mm tall; the far 7 mm
  // of its top lie in a 115 mm neighbour's shadow, as dark as the ground around, so its sides
  // do not show there. Seen 68 mm long, reported unflagged 4.0 mm off. No point at any height
  // lies in the 13 mm between its side and the taller part: nothing shows where the top ends
  // (PositionSensingOptions::shadow_strip_reach_mm).
  PositionSensingOptions before = CpuOptions();
  before.shadow_strip_reach_mm = 0.0;
  const SensedTwice sensed = SenseTouchingWithAndWithout(179050, before);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  double strip = 0.0;
  for (const ObjectPose& pose : sensed.report.objects) strip = std::max(strip, pose.shadow_strip_mm);
  EXPECT_GT(strip, 5.0);
  EXPECT_LT(strip, 20.0);
}

TEST(PositionSensing, ABoxTopWithASideTheImageDoesNotPlaceIsFlagged) {
  // Stress run, `render --seed 189079 --min-gap 0`: a 68 x 48 mm box, 48 mm tall, between a
  // 90 mm box and a 75 mm cylinder; the matches missed its end edge beside them, and it was
  // seen 58 mm long, reported unflagged 4.9 mm off. That side has no edge under it in the
  // left image, and the image-edge fit could not move it out: the face's side along the
  // cylinder shows no edge against the cylinder's bright top, and the cylinder's square
  // blocks the move (PositionSensingOptions::flag_unplaced_sides).
  PositionSensingOptions before = CpuOptions();
  before.flag_unplaced_sides = false;
  const SensedTwice sensed = SenseTouchingWithAndWithout(189079, before);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  int unplaced = 0;
  for (const ObjectPose& pose : sensed.report.objects) unplaced += pose.unplaced_sides;
  EXPECT_GE(unplaced, 1);
}

TEST(PositionSensing, APartBesideAPieceOfItsTopLeftOutIsFlagged) {
  // Stress run, `render --seed 69062 --min-gap 0`: a plain-looking 73 x 61 mm top, 116 mm tall,
  // fell apart into its far edge (84 points in a line) and the rest; 10 mismatches at 62 mm
  // "in the gap" between them kept the two apart, the line was dropped as too narrow to be a
  // part, and the rest was reported unflagged 13.8 mm off. A dropped line at a part's height
  // within 30 mm of it flags the part (PositionSensingOptions::left_out_piece_reach_mm).
  PositionSensingOptions before = CpuOptions();
  before.left_out_piece_reach_mm = 0.0;
  const SensedTwice sensed = SenseTouchingWithAndWithout(69062, before);
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  bool flagged = false;
  for (const ObjectPose& pose : sensed.report.objects) flagged = flagged || pose.piece_left_out;
  EXPECT_TRUE(flagged);
  EXPECT_GE(sensed.report.narrow_top_face, 1);
}

TEST(PositionSensing, APartBesideASliverOfItsTopIsFlagged) {
  // Fresh stress run, `render --seed 289060`: a plain 67 x 51 mm top, 146 mm tall, fell apart
  // into a 60 x 16 mm strip along one long side (reported, flagged as a sliver) and a 67 x 37
  // mm rest whose hull fitted a partly seen disc; as a round top it passed every fill and
  // outline flag and was sent 13.3 mm off. A sliver at a part's height within 30 mm of it
  // flags the part (PositionSensingOptions::flag_tops_beside_slivers).
  PositionSensingOptions before = CpuOptions();
  before.flag_tops_beside_slivers = false;
  const SensedTwice sensed = SenseWithAndWithout(289060, before);
  EXPECT_EQ(FarUnflaggedPoses(sensed.report, sensed.scene), 0);
  EXPECT_GE(FarUnflaggedPoses(sensed.before, sensed.scene), 1) << "the failure the rule exists for";
  bool flagged = false;
  for (const ObjectPose& pose : sensed.report.objects) flagged = flagged || pose.piece_left_out;
  EXPECT_TRUE(flagged);
}

TEST(PositionSensing, ABoxTopCutStraightByATallerNeighbourIsFlagged) {
  // Stress runs, `render --seed 39001 --min-gap 0` and `--seed 119031 --min-gap 0`: a 67 x 47
  // mm box, 87 mm tall, touching a 114 mm one, seen as 58 x 48 (fill 0.96, 4.6 mm off); a 68 x
  // 43 mm box, 35 mm tall, beside a 131 mm one, seen as 57 x 26 (fill 0.92, 9.2 mm off). The
  // taller neighbour hid a straight strip of each top from one camera: what is left is a full
  // rectangle, so the fill rule of touching parts passes it
  // (PositionSensingOptions::min_taller_touching_points).
  PositionSensingOptions before = CpuOptions();
  before.min_taller_touching_points = 0;
  for (const std::uint64_t seed : {39001u, 119031u}) {
    SCOPED_TRACE(seed);
    const SensedTwice sensed = SenseTouchingWithAndWithout(seed, before);
    ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(sensed);
  }
}

TEST(PositionSensing, AStripLongerAndNarrowerThanAnyPartIsNoPart) {
  // Stress run, `render --seed 55091`: a 203 x 6 mm strip of points at 107 mm, a line across
  // the sides of tall parts, was reported as a (flagged) false part. No part and no union of
  // parts is both longer than 95 mm and narrower than 18 mm: it is dropped.
  PositionSensingOptions before = CpuOptions();
  before.max_whole_top_length_mm = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(55091, before);
  EXPECT_EQ(sensed.truth.false_objects, 0);
  EXPECT_EQ(sensed.truth.detected, static_cast<int>(sensed.scene.objects.size()));
  EXPECT_GE(sensed.truth_before.false_objects, 1) << "the failure the rule exists for";
}

TEST(PositionSensing, ABoxTopWhoseHullFitsACircleLooselyIsFlagged) {
  // Stress run, `render --seed 99051 --min-gap 0`: a 73 x 34 mm box, 13 mm tall, seen as a
  // 60 x 34 mm piece filling 0.76 of its rectangle, whose hull fitted a circle to 4.1 %:
  // exempt from the fill flag as if a disc under the old 6 % limit, reported 7.1 mm off. A
  // disc's rim fits to 1-2 % (PositionSensingOptions::max_round_top_roundness, 3 %).
  PositionSensingOptions before = CpuOptions();
  before.max_round_top_roundness = 0.06;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(99051, before));
}

TEST(PositionSensing, ATopCutByTheImageBorderIsFlagged) {
  // `render --seed 69062 --min-gap 0` with both images cut to their top 430 rows (P unchanged):
  // the left image shows only part of the 116 mm box's top (rows 388-468 in full), the right
  // all of it, so only the piece in view is matched, and its centre is far from the part's.
  // The top's outline reaches the left image's border (PositionSensingOptions::image_border_px):
  // flagged merged and at_image_border.
  SceneRenderOptions options;
  options.seed = 69062;
  options.min_gap_mm = 0.0;
  const RenderedScene scene = RenderScene(options);
  const cv::Rect kept(0, 0, scene.left.cols, 430);
  const cv::Mat left = scene.left(kept).clone(), right = scene.right(kept).clone();
  // The outline flags off on both sides, as in SenseWithAndWithout: this rule alone.
  PositionSensingOptions sensing = CpuOptions();
  sensing.flag_unplaced_sides = false;
  sensing.shadow_strip_reach_mm = 0.0;
  PositionSensingOptions before = sensing;
  before.image_border_px = 0.0;
  const MatchReport match = MatchStereo(left, right, &scene.cameras, before.matcher, nullptr);
  const PositionSensingReport with = SensePositionsFromMatches(match, scene.cameras, sensing, left);
  const PositionSensingReport without = SensePositionsFromMatches(match, scene.cameras, before, left);
  EXPECT_EQ(FarUnflaggedPoses(with, scene), 0);
  EXPECT_GE(FarUnflaggedPoses(without, scene), 1) << "the failure the rule exists for";
  int at_border = 0;
  for (const ObjectPose& pose : with.objects) {
    if (pose.at_image_border) {
      ++at_border;
      EXPECT_TRUE(pose.merged);
    }
  }
  EXPECT_GE(at_border, 1);
  for (const ObjectPose& pose : without.objects) EXPECT_FALSE(pose.at_image_border);
}

TEST(PositionSensing, ASliverOfATopFaceIsFlagged) {
  // Stress run, `render --seed 29020 --min-gap 0`: a cylinder 68 mm across, 82 mm tall, between
  // touching neighbours, seen only as a 27 x 8 mm piece of its top; reported unflagged 5.6 mm
  // from its centre. No part's top is that narrow (min_whole_top_width_mm).
  PositionSensingOptions before = CpuOptions();
  before.min_whole_top_width_mm = 0.0;
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(29020, before));
}

TEST(PositionSensing, APartlySeenRoundTopIsRound) {
  // Stress run, `render --seed 17181`: a round top 70 mm across, 41 mm tall, whose rim found no
  // matches along a 90 degree arc; the hull closed it with a chord, the circle fit to all hull
  // vertices was 5 % off, and the rectangle's centre 6.0 mm from the disc's, unflagged. Most
  // hull vertices still lie on the rim (FitCircleRobust, min_circle_inlier_fraction).
  PositionSensingOptions before = CpuOptions();
  before.pose.min_circle_inlier_fraction = 0.0;
  const SensedTwice sensed = SenseWithAndWithout(17181, before);
  ExpectEveryPartWithinAndOneFarWithoutTheRule(sensed, 3.0, 5.0);
}

TEST(PositionSensing, ARoundTopLessThanHalfSeenIsRound) {
  // Stress run, `render --seed 9013 --min-gap 0`: a round top 61 mm across, 31 mm tall, seen
  // along only 150 degrees of its rim; the rectangle of what was seen put its centre 12 mm off,
  // unflagged. The robust circle through the seen arc finds the disc's centre.
  PositionSensingOptions before = CpuOptions();
  before.pose.min_circle_inlier_fraction = 0.0;
  before.min_touching_top_fill = 0.0;  // the touch rule flags it too: off, to see this rule alone
  ExpectNoFarUnflaggedPoseAndOneWithoutTheRule(SenseTouchingWithAndWithout(9013, before));
}

TEST(PositionSensing, RecallWithGaussianNoiseOnF) {
  const int num_scenes = FullAcceptance() ? 20 : 2;
  Figures figures;
  double shift_sum = 0.0;
  int shift_count = 0;
  for (int s = 0; s < num_scenes; ++s) {
    const auto seed = static_cast<std::uint64_t>(100 + s);
    const int num_objects = 1 + s % 9;
    const CalibratedScene scene = RenderAndCalibrate(seed, num_objects);
    const calib::StereoCalibration noisy = WithNoisyF(scene.calibrated, kFNoiseSigma, seed);
    for (const SceneObject& object : scene.scene.objects) {
      for (const Eigen::Vector2d& corner : object.Footprint()) {
        const Eigen::Vector4d X(corner.x(), corner.y(), object.height_mm(), 1.0);
        shift_sum += calib::EpipolarDistancePx(noisy.F, (scene.scene.cameras.P1 * X).hnormalized(),
                                               (scene.scene.cameras.P2 * X).hnormalized());
        ++shift_count;
      }
    }
    const PositionSensingReport report =
        SensePositions(scene.scene.left, scene.scene.right, noisy, CpuOptions(), nullptr);
    figures.Add(CompareWithTruth(report.objects, scene.scene.objects), scene.scene.objects.size());
  }
  std::cout << "F noise sigma " << kFNoiseSigma << ": mean epipolar distance of true points "
            << shift_sum / std::max(1, shift_count) << " px\n";
  figures.Print(std::to_string(num_scenes) + " scenes, noisy F");
  EXPECT_GE(figures.detected, static_cast<int>(std::ceil(0.95 * figures.true_parts)));
}

}  // namespace
}  // namespace hnnstereo::vision
