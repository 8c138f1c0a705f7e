// `hnnstereo pick`: stereo pair -> parts' top-face centroid, height and yaw (OBJECTS.json).
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/cell_sensing.h"
#include "app/cli_support.h"
#include "app/robot_link_flags.h"
#include "app/commands.h"
#include "common/atomic_file.h"
#include "calib/calibration.h"
#include "vision/stereo/overlay.h"
#include "vision/sensing/plots.h"
#include "vision/sensing/ply.h"
#include "vision/sensing/position_sensing.h"
#include "vision/sensing/sensing_hints.h"
#include "vision/stereo/setup_checks.h"
#include "vision/sensing/swapped_cameras.h"

namespace hnnstereo::app {
namespace {

struct PickArgs {
  std::string left, right, calib, out, overlay, ply, histogram, energy_plot;
  bool quiet = false;
  std::string config;  // consumed by ExpandConfigArguments in main
  CellSensingFlags cell;
  RobotLinkFlags link;
};

// No part: were the images given the wrong way round? Swapped cameras put the triangulated
// points behind them, or the images correlate far better the other way round.
// The pair probed along its epipolar lines both ways round (CompareWithSwappedCameras): tells a
// swapped pair and a calibration of another rig.
vision::SwapComparison ProbeEpipolarLines(const SensedPair& pair,
                                          const calib::StereoCalibration& calibration,
                                          const PickArgs& args) {
  const std::pair<double, double> z_range =
      args.cell.sensing.matcher.candidates.z_range_mm.value_or(std::make_pair(-5.0, 200.0));
  const auto [left_grey, right_grey] = GreyInCalibrationPixels(pair, calibration);
  return vision::CompareWithSwappedCameras(left_grey, right_grey, calibration, z_range);
}

void ThrowIfLooksSwapped(const SensedPair& pair, const vision::SwapComparison& swap) {
  const auto& counts = pair.report.triangulation;
  if ((counts.behind_camera > 0 && counts.behind_camera >= counts.accepted) || swap.looks_swapped) {
    throw std::runtime_error(
        "no parts, and --left and --right look swapped: " + std::to_string(counts.behind_camera) +
        " of " + std::to_string(counts.behind_camera + counts.accepted) +
        " triangulated points behind the cameras; median ZNCC along the epipolar lines " +
        std::to_string(swap.as_given_zncc).substr(0, 4) + " as given, " +
        std::to_string(swap.swapped_zncc).substr(0, 4) + " swapped");
  }
}

// Writes every output asked for (each atomically) and returns their paths, in order.
std::vector<std::string> WritePickOutputs(const PickArgs& args, const SensedPair& pair,
                                          const calib::StereoCalibration& calibration,
                                          const std::vector<std::string>& warnings) {
  const vision::PositionSensingReport& report = pair.report;
  nlohmann::json objects = ObjectsFileJson(pair, args.cell, args.left, args.right, args.calib);
  objects["warnings"] = warnings;
  calib::WriteFileAtomically(args.out, objects.dump(2) + "\n");
  if (!args.overlay.empty()) {
    vision::WritePngAtomically(
        args.overlay,
        OverlayInInputPixels(vision::DrawObjectOverlay(OverlayImageOf(pair, calibration), report, calibration.P1),
                             calibration));
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
  std::vector<std::string> written;
  for (const std::string* path :
       {&args.out, &args.overlay, &args.ply, &args.histogram, &args.energy_plot}) {
    if (!path->empty()) written.push_back(*path);
  }
  return written;
}

// One cycle through the link: push transports send at once, polled ones (Modbus server, vision
// server) wait for the robot side's trigger up to --ack-timeout.
void SendOneCycle(robot::RobotLink& link, const robot::RobotFrame& frame, const PickArgs& args,
                  const vision::PositionSensingReport& report) {
  const auto objects = SensedObjectsOf(report);
  const double capture_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  robot::CellLoopOptions loop = args.link.LoopOptions();
  loop.cycles = 1;
  loop.idle_limit = loop.ack_timeout;
  loop.stop_requested = InstallStopSignals();
  if (!args.quiet) {
    std::printf("link: %s\n", link.Describe().c_str());
    std::fflush(stdout);
    loop.on_cycle = PrintCycleLine;
  }
  const robot::CellLoopReport sent = robot::RunCellLoop(
      link, frame, [&] { return robot::SensedCycle{objects, capture_time_s}; }, loop);
  if (sent.idle_timeout) {
    throw std::runtime_error("no trigger from " + link.Describe() + " within --ack-timeout " +
                             "(OBJECTS.json was written; nothing was sent)");
  }
}

void PrintPickSummary(const PickArgs& args, const vision::PositionSensingReport& report,
                      const std::vector<std::string>& written) {
  const auto& t = report.triangulation;
  std::printf(
      "%zu matches -> %d points (%d weak: edge along the epipolar line; rejected: %d behind a "
      "camera, %d residual > %.1f px, %d degenerate) -> %zu parts (%s clustering)\n",
      report.match.matches.size(), t.accepted, t.edge_along_epipolar, t.behind_camera,
      t.large_residual, args.cell.sensing.max_reprojection_error_px, t.degenerate,
      report.objects.size(), args.cell.clustering.c_str());
  std::printf("%3s %9s %9s %9s %8s %7s %7s\n", "id", "x mm", "y mm", "height", "yaw deg", "moments",
              "points");
  int id = 1;
  for (const vision::ObjectPose& pose : report.objects) {
    // A round part has no yaw (null in OBJECTS.json; the link sends 0).
    if (pose.round) {
      std::printf("%3d %9.1f %9.1f %9.1f %8s %7s %7d\n", id++, pose.centroid.x(),
                  pose.centroid.y(), pose.height_mm, "round", "-", pose.points);
      continue;
    }
    std::printf("%3d %9.1f %9.1f %9.1f %8.1f %7.1f %7d\n", id++, pose.centroid.x(),
                pose.centroid.y(), pose.height_mm, pose.yaw_deg, pose.yaw_moments_deg, pose.points);
  }
  std::string list;
  for (const std::string& path : written) list += (list.empty() ? "" : ", ") + path;
  std::printf("time: match %.0f ms (solve %.0f ms, %s), refine %.1f ms, triangulate %.1f ms, "
              "cluster %.1f ms, poses %.1f ms\nwrote %s\n",
              report.timing_ms.match, report.match.timing_ms.solve,
              report.match.solve.engine.c_str(), report.timing_ms.refine,
              report.timing_ms.triangulate, report.timing_ms.cluster, report.timing_ms.pose,
              list.c_str());
}

void RunPick(PickArgs& args) {
  args.cell.Resolve();
  if (!args.link.frame.empty() && args.link.robot.empty()) {
    throw std::invalid_argument("--frame is used with --robot URI (the link to send the picks to)");
  }
  // The whole setup is checked before the slow part: outputs, device, calibration, the link
  // (and FRAME.yml); SenseCellPair checks the pair before matching.
  CheckOutputsWritable({{"--out", args.out},
                        {"--overlay", args.overlay},
                        {"--ply", args.ply},
                        {"--histogram", args.histogram},
                        {"--energy-plot", args.energy_plot}},
                       {{"--left", args.left}, {"--right", args.right}, {"--calib", args.calib}});
  std::unique_ptr<ocl::Runtime> runtime =
      OpenRuntimeFor(args.cell.sensing.matcher.engine, args.cell.flags.device);
  const calib::StereoCalibration calibration =
      AsSetupError([&] { return calib::LoadCalibration(args.calib); });
  if (const std::string problem = vision::TableFrameProblem(calibration); !problem.empty()) {
    throw std::invalid_argument("--calib '" + args.calib + "': " + problem);
  }
  robot::RobotFrame frame;
  std::unique_ptr<robot::RobotLink> link;
  if (!args.link.robot.empty()) link = args.link.Open(&frame);
  const SensedPair pair =
      SenseCellPair(args.left, args.right, calibration, args.calib, args.cell, runtime.get());
  const vision::SwapComparison probe = ProbeEpipolarLines(pair, calibration, args);
  if (pair.report.objects.empty()) ThrowIfLooksSwapped(pair, probe);
  // Never "0 parts" silently, nor parts from a calibration that does not fit the pair: why, on
  // stderr and in OBJECTS.json's "warnings".
  std::vector<std::string> warnings;
  if (std::string fit = vision::CalibrationFitProblem(probe); !fit.empty()) warnings.push_back(fit);
  if (warnings.empty()) warnings = vision::ExplainNoParts(pair.report, args.cell.sensing);
  for (const std::string& warning : warnings) std::cerr << "hnnstereo: warning: " << warning << "\n";
  // Everything is computed before anything is written.
  const std::vector<std::string> written = WritePickOutputs(args, pair, calibration, warnings);
  if (!pair.report.match.engine_notice.empty()) {
    std::cerr << "hnnstereo: notice: " << pair.report.match.engine_notice << "\n";
  }
  if (link) SendOneCycle(*link, frame, args, pair.report);
  if (!args.quiet) PrintPickSummary(args, pair.report, written);
}

}  // namespace

void AddPickCommand(CLI::App& app) {
  auto args = std::make_shared<PickArgs>();
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
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  args->cell.AddTo(cmd);
  args->link.AddTo(cmd,
                   "Also send the picks through this link (one cycle, safety-gated): "
                   "dryrun:FILE.jsonl, modbus-server://HOST:PORT, modbus-client://HOST:PORT, "
                   "vision-server://HOST:PORT, serial:DEVICE?baud=2400 (docs/robot.md)",
                   false);
  cmd->add_option("--config", args->config,
                  "YAML file of options: 'long-option-name: value' per line; the command line "
                  "wins");
  cmd->callback([args] { RunPick(*args); });
}

}  // namespace hnnstereo::app
