// `hnnstereo demo`: the main job end to end on the synthetic cell - render, calibrate from the
// target images, pick, compare with the truth.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "app/cli_support.h"
#include "app/commands.h"
#include "common/atomic_file.h"
#include "calib/circle_calibration.h"
#include "vision/stereo/overlay.h"
#include "vision/sensing/plots.h"
#include "vision/sensing/ply.h"
#include "vision/sensing/position_sensing.h"
#include "vision/eval/truth_comparison.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::app {
namespace {

struct DemoArgs {
  std::string out = "out/demo";
  std::uint64_t seed = 1;
  int objects = 6;
  std::string engine{vision::EngineName(vision::PickCellMatcherOptions().engine)};
  std::string device;
  bool quiet = false;
};

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void RunDemo(const DemoArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  vision::SceneRenderOptions render;
  render.seed = args.seed;
  render.num_objects = args.objects;
  render.shrink_to_fit = true;  // every --objects value (1-30) renders, as with `render`
  vision::PositionSensingOptions sensing;
  // pick's settings, through the library's resolver (--engine its only matcher flag here).
  sensing.matcher =
      api::ResolvePickCellSettings({{"engine", args.engine}}, vision::PickCellMatcherOptions())
          .matcher;

  // The output folder and the device are checked before the work.
  CheckOutputFolderWritable("--out", args.out);
  std::unique_ptr<ocl::Runtime> runtime = OpenRuntimeFor(sensing.matcher.engine, args.device);

  // 1. The scene (and its target images) into the output folder.
  const vision::RenderedScene scene = vision::RenderScene(render);
  const vision::RenderedTarget target = vision::RenderTargetPlacements(scene.cameras, render);
  vision::WriteSceneDirectory(scene, target, args.out);
  const double render_s = SecondsSince(start);

  // 2. Calibrate from the target images, not from the truth.
  auto step = std::chrono::steady_clock::now();
  const calib::CalibrationResult calibrated = calib::CalibrateCircleTarget(args.out + "/target");
  calib::SaveCalibration(calibrated.calibration, args.out + "/calibrated.yml");
  const double calibrate_s = SecondsSince(step);

  // 3. Pick.
  step = std::chrono::steady_clock::now();
  const vision::PositionSensingReport report = vision::SensePositions(
      scene.left, scene.right, calibrated.calibration, sensing, runtime.get());
  const double pick_s = SecondsSince(step);
  nlohmann::json json = vision::ObjectsJson(report, sensing);
  json["left"] = args.out + "/left.png";
  json["right"] = args.out + "/right.png";
  json["calib"] = args.out + "/calibrated.yml";
  calib::WriteFileAtomically(args.out + "/objects.json", json.dump(2) + "\n");
  vision::WritePngAtomically(args.out + "/overlay.png",
                             vision::DrawObjectOverlay(scene.left, report, calibrated.calibration.P1));
  vision::WritePngAtomically(args.out + "/heights.png", vision::PlotHeightHistogram(report));
  vision::WritePngAtomically(args.out + "/energy.png", vision::PlotEnergyTrace(report.match.solve));
  std::vector<int> labels(report.points_in_world.size(), -1);
  for (std::size_t o = 0; o < report.objects.size(); ++o) {
    for (int i : report.objects[o].point_indices) labels[static_cast<std::size_t>(i)] = static_cast<int>(o);
  }
  vision::WritePly(args.out + "/points.ply", report.points_in_world, labels);
  if (!report.match.engine_notice.empty()) {
    std::cerr << "hnnstereo: notice: " << report.match.engine_notice << "\n";
  }
  if (args.quiet) return;

  // 4. Detected versus true.
  const vision::TruthComparison comparison = vision::CompareWithTruth(report.objects, scene.objects);
  std::printf("demo: scene seed %llu, %zu parts; calibrated from %zu target heights "
              "(RMS %.3f / %.3f px); %zu matches (%s engine), %d points\n\n",
              static_cast<unsigned long long>(scene.seed), scene.objects.size(),
              target.description.placements.size(),
              calibrated.report.cameras.at(0).final.rms_px,
              calibrated.report.cameras.at(1).final.rms_px, report.match.matches.size(),
              report.match.solve.engine.c_str(), report.triangulation.accepted);
  std::printf("%-3s %-8s %7s %7s %6s %6s | %-3s %7s %7s %6s %6s | %6s %6s %6s\n", "id", "shape",
              "x", "y", "height", "yaw", "det", "x", "y", "height", "yaw", "d_xy", "d_h", "d_yaw");
  for (const vision::TruthPairing& pair : comparison.pairs) {
    const vision::SceneObject& truth = scene.objects[static_cast<std::size_t>(pair.truth_index)];
    std::printf("%-3d %-8s %7.1f %7.1f %6.1f %6.1f | ", pair.truth_index + 1,
                truth.ShapeName().c_str(), truth.centre_mm.x(), truth.centre_mm.y(),
                truth.height_mm(), truth.yaw_deg);
    if (pair.detected_index < 0) {
      std::printf("missed\n");
      continue;
    }
    const vision::ObjectPose& pose = report.objects[static_cast<std::size_t>(pair.detected_index)];
    std::printf("%-3d %7.1f %7.1f %6.1f %6.1f | %6.2f %+6.2f ", pair.detected_index + 1,
                pose.centroid.x(), pose.centroid.y(), pose.height_mm, pose.yaw_deg,
                pair.centroid_error_mm, pair.height_error_mm);
    if (pair.yaw_defined) {
      std::printf("%6.2f\n", pair.yaw_error_deg);
    } else {
      std::printf("%6s\n", "-");
    }
  }
  std::printf("\nfound %d of %zu parts, %d false; errors: d_xy = centroid in the table plane (mm), "
              "d_h = height (mm), d_yaw = box yaw (deg)\n",
              comparison.detected, scene.objects.size(), comparison.false_objects);
  std::printf("time: render %.2f s, calibrate %.2f s, pick %.2f s (match %.0f ms), total %.2f s\n",
              render_s, calibrate_s, pick_s, report.timing_ms.match, SecondsSince(start));
  std::printf("wrote %s/: left.png right.png calib.yml truth.json target/ calibrated.yml "
              "objects.json overlay.png heights.png energy.png points.ply\n",
              args.out.c_str());
}

}  // namespace

void AddDemoCommand(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "The main job on the synthetic pick cell: render the default scene and the circle target, "
      "calibrate from the target images, pick the parts, and print detected versus true parts "
      "with their errors.\n"
      "Example:\n"
      "  hnnstereo demo --out out/demo\n"
      "Then look at out/demo/overlay.png, heights.png, energy.png and points.ply.");
  cmd->add_option("--out", args->out, "Output folder")->capture_default_str();
  cmd->add_option("--seed", args->seed, "Scene seed")->capture_default_str();
  cmd->add_option("--objects", args->objects, "Number of parts (1-30)")
      ->check(CLI::Range(1, 30))
      ->capture_default_str();
  cmd->add_option("--engine", args->engine, "opencl (falls back to cpu), cpu or thesis")
      ->capture_default_str();
  cmd->add_option("--device", args->device, "OpenCL device: index or name substring");
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace hnnstereo::app
