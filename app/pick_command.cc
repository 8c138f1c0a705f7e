// `hnnstereo pick`: stereo pair -> parts' top-face centroid, height and yaw (OBJECTS.json).
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "app/cli_support.h"
#include "app/commands.h"
#include "calib/atomic_file.h"
#include "calib/calibration.h"
#include "vision/image.h"
#include "vision/lens_distortion.h"
#include "vision/overlay.h"
#include "vision/plots.h"
#include "vision/ply.h"
#include "vision/position_sensing.h"

namespace hnnstereo::app {
namespace {

struct PickArgs {
  std::string left, right, calib, out, overlay, ply, histogram, energy_plot, robot, frame;
  std::string clustering = "grid";
  std::string yaw = "rectangle";
  bool quiet = false;
  std::string config;  // consumed by ExpandConfigArguments in main
  vision::PositionSensingOptions sensing;
  MatcherFlags flags;
};

void RunPick(PickArgs& args) {
  if (!args.robot.empty() || !args.frame.empty()) {
    throw std::invalid_argument(
        "--robot/--frame are not available in pick yet; use the robot commands for the link");
  }
  args.flags.Resolve();
  args.flags.UseFeatureNetworkUnlessRectified(false);  // pick cells are calibrated, unrectified
  args.sensing.matcher = args.flags.options;
  if (auto method = vision::ParseClusteringMethod(args.clustering)) {
    args.sensing.clustering = *method;
  } else {
    throw std::invalid_argument("unknown --clustering '" + args.clustering + "' (grid or thesis)");
  }
  if (auto method = vision::ParseYawMethod(args.yaw)) {
    args.sensing.pose.yaw_method = *method;
  } else {
    throw std::invalid_argument("unknown --yaw '" + args.yaw + "' (rectangle or moments)");
  }
  if (const std::string problem = args.sensing.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  const vision::LoadedImage left = vision::LoadImage(args.left);
  const vision::LoadedImage right = vision::LoadImage(args.right);
  vision::CheckSameSize(left, right);
  const calib::StereoCalibration calibration = calib::LoadCalibration(args.calib);
  if (calibration.image_width > 0 &&
      (calibration.image_width != left.grey.cols || calibration.image_height != left.grey.rows)) {
    throw std::invalid_argument("calibration '" + args.calib + "' is for " +
                                std::to_string(calibration.image_width) + "x" +
                                std::to_string(calibration.image_height) + " images, the pair is " +
                                std::to_string(left.grey.cols) + "x" +
                                std::to_string(left.grey.rows));
  }
  // A chessboard calibration refers P to undistorted pixels (docs/calibration.md): sense on
  // undistorted images (OBJECTS.json is in world mm; the overlay shows the undistorted left).
  cv::Mat left_grey = left.grey, right_grey = right.grey;
  if (calibration.intrinsics && !calibration.intrinsics->D1.empty()) {
    left_grey = vision::UndistortImage(left.grey, calibration.intrinsics->K1, calibration.intrinsics->D1);
    right_grey = vision::UndistortImage(right.grey, calibration.intrinsics->K2, calibration.intrinsics->D2);
  }
  std::unique_ptr<ocl::Runtime> runtime =
      OpenRuntimeFor(args.sensing.matcher.engine, args.flags.device);
  const vision::PositionSensingReport report =
      vision::SensePositions(left_grey, right_grey, calibration, args.sensing, runtime.get());

  // Everything is computed before anything is written; each file is written atomically.
  nlohmann::json json = vision::ObjectsJson(report, args.sensing);
  json["left"] = args.left;
  json["right"] = args.right;
  json["calib"] = args.calib;
  calib::WriteFileAtomically(args.out, json.dump(2) + "\n");
  if (!args.overlay.empty()) {
    vision::WritePngAtomically(args.overlay,
                               vision::DrawObjectOverlay(
                                   left_grey.data == left.grey.data ? left.original : left_grey,
                                   report, calibration.P1));
  }
  if (!args.ply.empty()) {
    std::vector<int> labels(report.points_in_world.size(), -1);
    for (std::size_t o = 0; o < report.objects.size(); ++o) {
      for (int i : report.objects[o].point_indices) {
        labels[static_cast<std::size_t>(i)] = static_cast<int>(o);
      }
    }
    vision::WritePly(args.ply, report.points_in_world, labels);
  }
  if (!args.histogram.empty()) {
    vision::WritePngAtomically(args.histogram, vision::PlotHeightHistogram(report));
  }
  if (!args.energy_plot.empty()) {
    vision::WritePngAtomically(args.energy_plot, vision::PlotEnergyTrace(report.match.solve));
  }
  if (!report.match.engine_notice.empty()) {
    std::cerr << "hnnstereo: notice: " << report.match.engine_notice << "\n";
  }
  if (args.quiet) return;
  const auto& t = report.triangulation;
  std::printf(
      "%zu matches -> %d points (%d weak: edge along the epipolar line; rejected: %d behind a "
      "camera, %d residual > %.1f px, %d degenerate) -> %zu parts (%s clustering)\n",
      report.match.matches.size(), t.accepted, t.edge_along_epipolar, t.behind_camera,
      t.large_residual,
      args.sensing.max_reprojection_error_px, t.degenerate, report.objects.size(),
      args.clustering.c_str());
  std::printf("%3s %9s %9s %9s %8s %7s %7s\n", "id", "x mm", "y mm", "height", "yaw deg", "moments",
              "points");
  int id = 1;
  for (const vision::ObjectPose& pose : report.objects) {
    std::printf("%3d %9.1f %9.1f %9.1f %8.1f %7.1f %7d\n", id++, pose.centroid.x(),
                pose.centroid.y(), pose.height_mm, pose.yaw_deg, pose.yaw_moments_deg, pose.points);
  }
  std::printf("time: match %.0f ms (solve %.0f ms, %s), triangulate %.1f ms, cluster %.1f ms, "
              "poses %.1f ms\nwrote %s\n",
              report.timing_ms.match, report.match.timing_ms.solve,
              report.match.solve.engine.c_str(), report.timing_ms.triangulate,
              report.timing_ms.cluster, report.timing_ms.pose, args.out.c_str());
}

}  // namespace

void AddPickCommand(CLI::App& app) {
  auto args = std::make_shared<PickArgs>();
  args->flags.options = vision::PickCellMatcherOptions();
  args->flags.zrange = "-5,200";
  args->flags.options.candidates.z_range_mm.reset();  // set from --zrange by Resolve
  CLI::App* cmd = app.add_subcommand(
      "pick",
      "Find the parts on the table: match the pair with the Hopfield network, triangulate with "
      "both P, cluster the points into parts and estimate each part's pick pose.\n"
      "Example (a rendered scene):\n"
      "  hnnstereo render --seed 3 --out s3\n"
      "  hnnstereo pick --left s3/left.png --right s3/right.png --calib s3/calib.yml \\\n"
      "      --out s3/objects.json --overlay s3/overlay.png --ply s3/points.ply\n"
      "OBJECTS.json: units mm, objects [{id, centroid [x,y,z] = centre of the top face, height "
      "above the table, yaw_deg in (-90, 90], points}], tallest first, world frame of CAL.yml "
      "(table z = 0, z up).");
  cmd->add_option("--left", args->left, "Left image")->required();
  cmd->add_option("--right", args->right, "Right image, same size")->required();
  cmd->add_option("--calib", args->calib, "CAL.yml of the cell (P1, P2, F; table at z = 0)")
      ->required();
  cmd->add_option("--out", args->out, "Output OBJECTS.json")->required();
  cmd->add_option("--overlay", args->overlay,
                  "Output PNG: features, matched features coloured by part, centroids and "
                  "orientation lines projected with P1");
  cmd->add_option("--ply", args->ply, "Output PLY point cloud (mm) coloured by part");
  cmd->add_option("--histogram", args->histogram,
                  "Output PNG: histogram of point heights with the parts' heights");
  cmd->add_option("--energy-plot", args->energy_plot, "Output PNG: the network's energy trace");
  cmd->add_option("--robot", args->robot, "Robot URI (reserved; see the robot commands)");
  cmd->add_option("--frame", args->frame, "FRAME.yml (reserved; see the robot commands)");
  cmd->add_option("--clustering", args->clustering,
                  "grid (default: 3D density clustering, separates parts of equal height) or "
                  "thesis (leader clustering on height, thresholds of the thesis code)")
      ->capture_default_str();
  cmd->add_option("--yaw", args->yaw,
                  "rectangle (long side of the top face's minimum-area rectangle) or moments "
                  "(thesis: 0.5 atan2(2 mu11, mu20 - mu02))")
      ->capture_default_str();
  cmd->add_option("--max-residual", args->sensing.max_reprojection_error_px,
                  "Reject points whose reprojection residual exceeds this (px)")
      ->capture_default_str();
  cmd->add_option("--min-edge-angle", args->sensing.min_edge_epipolar_angle_deg,
                  "Reject matches on edges within this angle of their epipolar line (deg)")
      ->capture_default_str();
  cmd->add_option("--cell", args->sensing.grid.cell_mm, "Grid clustering cell edge (mm)")
      ->capture_default_str();
  cmd->add_option("--min-points", args->sensing.grid.min_points,
                  "Grid clustering: smallest part, in points")
      ->capture_default_str();
  cmd->add_option("--min-height", args->sensing.grid.min_height_mm,
                  "Grid clustering: points below this height are the table (mm)")
      ->capture_default_str();
  cmd->add_option("--leader-threshold", args->sensing.leader.threshold_mm,
                  "Thesis clustering: join/merge distance of heights (mm)")
      ->capture_default_str();
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  args->flags.AddTo(cmd);
  cmd->add_option("--config", args->config,
                  "YAML file of options: 'long-option-name: value' per line; the command line "
                  "wins");
  cmd->callback([args] { RunPick(*args); });
}

}  // namespace hnnstereo::app
