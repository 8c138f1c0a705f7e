// Picking through lens distortion, end to end: the cell rendered with Brown-Conrady distortion
// (render --distortion), calibrated from its own board images (calib/board_calibration.h: K D,
// R T, the table frame), sensed as `pick` senses (through the lens by
// PositionSensingOptions::lens_route, P for undistorted pixels), scored against the truth - and
// the same images calibrated with the DLT of the circle plate, which has no distortion model.
// The default run checks one scene; HNNSTEREO_LENS_ACCEPTANCE=N runs N scenes from
// HNNSTEREO_LENS_FIRST_SEED (default 300) and prints the figures of docs/sensing.md against the
// same seeds rendered without distortion (the board-calibrated scenes by both lens routes, and
// sensed with the render's own K D R T: what the calibration adds).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "calib/board_calibration.h"
#include "calib/circle_calibration.h"
#include "vision/eval/truth_comparison.h"
#include "vision/sensing/position_sensing.h"
#include "vision/stereo/lens_distortion.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::vision {
namespace {

namespace fs = std::filesystem;

const std::vector<double> kDistortion = {-0.25, 0.08, 0.001, -0.001};

// A scene and its two calibrations from its own target/ images.
struct CalibratedScene {
  RenderedScene scene;
  calib::StereoCalibration board;  // calibrate --dir: K D R T and the table frame
  calib::StereoCalibration dlt;    // calibrate --target circles: no distortion model
};

CalibratedScene RenderAndCalibrate(std::uint64_t seed, const std::vector<double>& distortion) {
  SceneRenderOptions options;
  options.seed = seed;
  options.cameras.distortion = distortion;
  options.shrink_to_fit = true;
  CalibratedScene result;
  result.scene = RenderScene(options);
  const RenderedTarget target = RenderTargetPlacements(result.scene.cameras, options);
  const fs::path dir = fs::temp_directory_path() / ("hnnstereo_lens_pick_" +
                                                    std::to_string(::getpid()) + "_" +
                                                    std::to_string(seed));
  WriteSceneDirectory(result.scene, target, dir.string());
  const std::string target_dir = (dir / "target").string();
  result.board = calib::CalibrateBoardTarget(*calib::LoadBoardTarget(target_dir)).calibration;
  result.dlt = calib::CalibrateCircleTarget(target_dir).calibration;
  fs::remove_all(dir);
  return result;
}

// What `pick` does with a calibration (app/cell_sensing.cc): senses the captured images, through
// the lens by `route` when D is present. `match_ms` (when not null) adds the match and
// refinement time (the image route's undistortion included).
TruthComparison SenseAndScore(const RenderedScene& scene, const calib::StereoCalibration& calibration,
                              LensRoute route = PositionSensingOptions().lens_route,
                              double* match_ms = nullptr) {
  PositionSensingOptions options;
  options.matcher.engine = hnn::EngineKind::kCpu;
  options.lens_route = route;
  const PositionSensingReport report =
      SensePositions(scene.left, scene.right, calibration, options, nullptr);
  if (match_ms != nullptr) *match_ms += report.timing_ms.match + report.timing_ms.refine;
  return CompareWithTruth(report.objects, scene.objects);
}

// Recall, false parts and centroid errors over scenes.
struct Figures {
  int true_parts = 0, detected = 0, false_objects = 0;
  std::vector<double> centroid_mm;
  void Add(const TruthComparison& comparison, std::size_t num_true) {
    true_parts += static_cast<int>(num_true);
    detected += comparison.detected;
    false_objects += comparison.false_objects;
    for (const TruthPairing& pair : comparison.pairs) {
      if (pair.detected_index >= 0) centroid_mm.push_back(pair.centroid_error_mm);
    }
  }
  double Recall() const { return true_parts ? static_cast<double>(detected) / true_parts : 0.0; }
  double FalseRate() const {
    return detected + false_objects ? static_cast<double>(false_objects) / (detected + false_objects)
                                    : 0.0;
  }
  double Percentile(double q) const {
    if (centroid_mm.empty()) return 0.0;
    std::vector<double> sorted = centroid_mm;
    std::sort(sorted.begin(), sorted.end());
    const auto rank = static_cast<std::size_t>(q * static_cast<double>(sorted.size()));
    return sorted[std::min(sorted.size() - 1, rank)];
  }
  void Print(const std::string& title) const {
    std::cout << title << ": recall " << detected << "/" << true_parts << ", false "
              << false_objects << ", centroid median " << Percentile(0.5) << " p99 "
              << Percentile(0.99) << " worst " << Percentile(1.0) << " mm\n";
  }
};

TEST(LensDistortionPick, BoardCalibrationUndoesTheLensAndTheDltDoesNot) {
  const CalibratedScene distorted = RenderAndCalibrate(7, kDistortion);
  Figures board, dlt;
  board.Add(SenseAndScore(distorted.scene, distorted.board), distorted.scene.objects.size());
  dlt.Add(SenseAndScore(distorted.scene, distorted.dlt), distorted.scene.objects.size());
  board.Print("seed 7 distorted, board calibration");
  dlt.Print("seed 7 distorted, circle-plate DLT");
  EXPECT_EQ(board.detected, board.true_parts);
  EXPECT_EQ(board.false_objects, 0);
  EXPECT_LE(board.Percentile(1.0), 0.5);
  // The model matters: without it the centroids are further off, by the acceptance's factor.
  EXPECT_GE(dlt.Percentile(1.0), 2.0 * board.Percentile(1.0));
  EXPECT_GE(dlt.Percentile(1.0), 0.5);
}

TEST(LensDistortionPick, AcceptanceAgainstThePinholeCell) {
  const char* count = std::getenv("HNNSTEREO_LENS_ACCEPTANCE");
  if (count == nullptr) GTEST_SKIP() << "HNNSTEREO_LENS_ACCEPTANCE=N runs N scenes";
  const char* first = std::getenv("HNNSTEREO_LENS_FIRST_SEED");
  const std::uint64_t first_seed = first ? std::stoull(first) : 300;
  // distorted_true: the render's own K D R T, apart from any calibration error. The distorted
  // scenes calibrated from their boards are sensed by both lens routes (match + refine time).
  Figures pinhole_dlt, pinhole_board, distorted_points, distorted_images, distorted_dlt,
      distorted_true;
  double points_ms = 0.0, images_ms = 0.0;
  for (int s = 0; s < std::stoi(count); ++s) {
    const std::uint64_t seed = first_seed + static_cast<std::uint64_t>(s);
    const CalibratedScene pinhole = RenderAndCalibrate(seed, {});
    const CalibratedScene distorted = RenderAndCalibrate(seed, kDistortion);
    const std::size_t parts = pinhole.scene.objects.size();
    const TruthComparison scored[6] = {
        SenseAndScore(pinhole.scene, pinhole.dlt),
        SenseAndScore(pinhole.scene, pinhole.board),
        SenseAndScore(distorted.scene, distorted.board, LensRoute::kPoints, &points_ms),
        SenseAndScore(distorted.scene, distorted.board, LensRoute::kImages, &images_ms),
        SenseAndScore(distorted.scene, distorted.dlt),
        SenseAndScore(distorted.scene, distorted.scene.cameras)};
    Figures* figures[6] = {&pinhole_dlt,      &pinhole_board, &distorted_points,
                           &distorted_images, &distorted_dlt, &distorted_true};
    std::cout << "seed " << seed << " (" << parts << " parts), worst centroid / false:";
    for (int route = 0; route < 6; ++route) {
      figures[route]->Add(scored[route], parts);
      Figures one;
      one.Add(scored[route], parts);
      std::cout << " " << one.Percentile(1.0) << " / " << one.false_objects;
    }
    std::cout << "\n";
  }
  pinhole_dlt.Print("pinhole, circle-plate DLT");
  pinhole_board.Print("pinhole, board");
  distorted_points.Print("distorted, board, points route");
  distorted_images.Print("distorted, board, images route");
  distorted_dlt.Print("distorted, circle-plate DLT");
  distorted_true.Print("distorted, true K D R T");
  std::cout << "match + refine per scene: points route " << points_ms / std::stoi(count)
            << " ms, images route (with undistortion) " << images_ms / std::stoi(count) << " ms\n";
  const Figures& distorted_board =
      PositionSensingOptions().lens_route == LensRoute::kPoints ? distorted_points : distorted_images;
  // Within 10 % of the pinhole cell (recall and false rate as fractions of it, p99 relative).
  EXPECT_GE(distorted_board.Recall(), 0.9 * pinhole_dlt.Recall());
  EXPECT_LE(distorted_board.FalseRate(), pinhole_dlt.FalseRate() + 0.1 * pinhole_dlt.Recall());
  EXPECT_LE(distorted_board.Percentile(0.99), 1.1 * pinhole_dlt.Percentile(0.99));
  EXPECT_GT(distorted_dlt.Percentile(0.99), 2.0 * distorted_board.Percentile(0.99));
}

}  // namespace
}  // namespace hnnstereo::vision
