// `hnnstereo match`: features -> candidates -> Hopfield network -> matches.
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "api/match_pipeline.h"
#include "app/cli_support.h"
#include "app/commands.h"
#include "common/atomic_file.h"
#include "calib/calibration.h"
#include "host/network_file.h"
#include "common/image.h"
#include "vision/sensing/ply.h"
#include "vision/sensing/position_sensing.h"
#include "vision/sensing/triangulation.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/match_io.h"
#include "vision/stereo/overlay.h"
#include "vision/stereo/setup_checks.h"
#include "vision/stereo/stereo_matcher.h"
#include "vision/stereo/uncalibrated.h"

namespace hnnstereo::app {
namespace {

struct MatchArgs {
  std::string left, right, calib, out, report, overlay, save_network, disparity, ply;
  bool rectified = false;
  bool report_matches = false;
  bool quiet = false;
  std::string config;  // consumed by ExpandConfigArguments in main
  MatcherFlags flags;
};

// The pair and its geometry, checked before any work.
struct MatchInputs {
  vision::LoadedImage left, right;
  std::unique_ptr<calib::StereoCalibration> calibration;  ///< null for a rectified pair
  vision::PairComparison comparison;
};

// Loads and checks the pair and the calibration (a missing or unreadable image, or a calibration
// that does not load, is a refused setup), and settles whether the pair is rectified.
MatchInputs LoadMatchInputs(const MatchArgs& args, vision::MatcherOptions* options) {
  MatchInputs inputs = AsSetupError([&] {
    MatchInputs loaded;
    if (!args.calib.empty()) {
      loaded.calibration =
          std::make_unique<calib::StereoCalibration>(calib::LoadCalibration(args.calib));
    }
    loaded.left = vision::LoadImage(args.left);
    loaded.right = vision::LoadImage(args.right);
    return loaded;
  });
  if (inputs.calibration ? inputs.calibration->rectified : args.rectified) {
    options->candidates.rectified = true;
  }
  inputs.comparison = api::CheckMatchSetup(inputs.left.grey, inputs.right.grey,
                                           inputs.calibration.get(), *options, "--left and --right");
  if (!args.ply.empty() && !inputs.calibration) {
    throw std::invalid_argument("--ply needs --calib (CAL.yml, or a Middlebury calib.txt for a "
                                "rectified pair): without it the matches have no metric 3D "
                                "position");
  }
  if (!args.disparity.empty() && !options->candidates.rectified) {
    throw std::invalid_argument("--disparity needs a rectified pair (--rectified, or a rectified "
                                "--calib): only there is x_l - x_r a disparity");
  }
  return inputs;
}

// Neither --calib nor --rectified: F estimated from confident correlation matches, then matched
// with the soft epipolar term (projective cameras; no heights).
std::unique_ptr<calib::StereoCalibration> EstimatedCalibration(const MatchInputs& inputs,
                                                               bool quiet) {
  const vision::UncalibratedReport estimate =
      vision::EstimateEpipolarGeometry(inputs.left.grey, inputs.right.grey);
  if (!quiet) {
    std::printf("estimated F from %d putative matches: %d inliers, mean epipolar distance "
                "%.2f px (%.0f ms)\n",
                estimate.n_putative, estimate.fundamental.num_inliers,
                estimate.fundamental.mean_epipolar_distance_px, estimate.time_ms);
  }
  return std::make_unique<calib::StereoCalibration>(estimate.calibration);
}

void WarnIfSwapped(const vision::PairComparison& comparison) {
  std::cerr << "hnnstereo: warning: --left and --right look swapped: "
            << static_cast<int>(100.0 * comparison.negative_shift_fraction + 0.5)
            << "% of the textured blocks that moved lie at negative disparity (x_left - x_right "
               "< 0); swap the two images\n";
}

// Writes every output asked for (each atomically) and returns their paths, in order.
std::vector<std::string> WriteMatchOutputs(const MatchArgs& args, const MatchInputs& inputs,
                                           const vision::MatchReport& report,
                                           const vision::MatcherOptions& options,
                                           const std::string& network_bytes) {
  calib::WriteFileAtomically(args.out, vision::MatchesCsv(report));
  if (!args.report.empty()) {
    nlohmann::json json =
        api::MatchReportJson(report, options, args.flags.preset, args.flags.refinement);
    json["left"] = args.left;
    json["right"] = args.right;
    if (args.report_matches) json["matches"] = vision::MatchFeaturesJson(report);
    calib::WriteFileAtomically(args.report, json.dump(2) + "\n");
  }
  if (!args.save_network.empty()) calib::WriteFileAtomically(args.save_network, network_bytes);
  if (!args.disparity.empty()) {
    vision::WriteDisparityMap(args.disparity, vision::SparseDisparityMap(
                                                  report, inputs.left.grey.rows,
                                                  inputs.left.grey.cols));
  }
  if (!args.ply.empty()) {
    // In the world frame of the calibration (mm); points as pick keeps them (2 px residual).
    const std::vector<Eigen::Vector3d> points = vision::MatchesInWorld(
        *inputs.calibration, report.matches,
        vision::PositionSensingOptions{}.max_reprojection_error_px);
    vision::WritePly(args.ply, points, std::vector<int>(points.size(), -1));
  }
  if (!args.overlay.empty()) {
    vision::WritePngAtomically(
        args.overlay, vision::DrawMatchOverlay(inputs.left.original, inputs.right.original, report));
  }
  std::vector<std::string> written;
  for (const std::string* path :
       {&args.out, &args.report, &args.save_network, &args.disparity, &args.ply, &args.overlay}) {
    if (!path->empty()) written.push_back(*path);
  }
  return written;
}

void PrintMatchSummary(const vision::MatchReport& report, const std::vector<std::string>& written) {
  const vision::TimingMs& t = report.timing_ms;
  std::printf(
      "%zu matches from %d left / %d right features (%d neurons, %lld connections)\n"
      "engine %s on %s: %d iterations, %s, energy %.3f -> %.3f\n"
      "time: features %.1f ms, candidates %.1f ms, network %.1f ms, weights %.1f ms, solve %.1f "
      "ms, decode %.1f ms, total %.1f ms\n",
      report.matches.size(), report.n_left, report.n_right, report.n_neurons,
      static_cast<long long>(report.n_connections), report.solve.engine.c_str(),
      report.solve.device.c_str(), report.solve.iterations, report.solve.termination.c_str(),
      report.solve.energy_initial, report.solve.energy_final, t.features, t.candidates, t.network,
      t.weights, t.solve, t.decode, t.total);
  if (const vision::CoarseToFineReport& c = report.coarse_to_fine; c.applied) {
    std::printf("coarse-to-fine: %d half-size level%s (%dx%d: %d matches, %.1f ms), then %.1f "
                "disparity levels a feature (%d features searched the whole range)\n",
                c.levels, c.levels == 1 ? "" : "s", c.coarse_size.width, c.coarse_size.height,
                c.coarse_matches, t.coarse, c.mean_band_levels, c.features_whole_range);
  }
  if (report.memory_fit.applied) {
    std::printf("memory budget: the network over all %d left features needed %.0f MB; it matched "
                "an evenly spread %d of them (raise --memory-budget-mb to match all)\n",
                report.n_left, static_cast<double>(report.memory_fit.needed_bytes) / (1 << 20),
                report.memory_fit.left_features_matched);
  }
  std::string list;
  for (const std::string& path : written) list += (list.empty() ? "" : ", ") + path;
  std::printf("wrote %s\n", list.c_str());
}

void RunMatch(MatchArgs& args) {
  args.flags.Resolve();
  vision::MatcherOptions& options = args.flags.options;
  // The whole setup is checked before any work (each check is milliseconds): the outputs, the
  // pair, the disparity range, the device.
  CheckOutputsWritable({{"--out", args.out}, {"--report", args.report}, {"--overlay", args.overlay},
                        {"--save-network", args.save_network}, {"--disparity", args.disparity},
                        {"--ply", args.ply}},
                       {{"--left", args.left}, {"--right", args.right}, {"--calib", args.calib}});
  MatchInputs inputs = LoadMatchInputs(args, &options);
  std::unique_ptr<ocl::Runtime> runtime = OpenRuntimeFor(options.engine, args.flags.device);
  // (The pair was checked above: one image twice would "estimate" F from perfect matches.)
  if (!inputs.calibration && !args.rectified) {
    inputs.calibration = EstimatedCalibration(inputs, args.quiet);
  }
  args.flags.UseFeatureNetworkUnlessRectified(options.candidates.rectified);
  if (auto error = options.Check(); !error.empty()) {
    throw std::invalid_argument(api::InOptionNames(error, api::MatcherOptionNameTable()));
  }
  if (options.candidates.rectified && inputs.comparison.looks_swapped) {
    WarnIfSwapped(inputs.comparison);
  }
  if (options.candidates.z_range_mm && !inputs.calibration) {
    throw std::invalid_argument("--zrange needs --calib (heights come from P1 and P2)");
  }

  // The network as solved (host/network_file.h), kept in memory and written with the outputs.
  std::string network_bytes;
  if (!args.save_network.empty()) {
    options.network_observer = [&network_bytes](const hnn::MatchingProblem& problem,
                                                const hnn::EnergyOptions& energy,
                                                const hnn::DynamicsOptions& dynamics) {
      network_bytes = hnn::SerializeNetwork(problem, energy, dynamics);
    };
  }
  // The library facade's pipeline (undistort, match, refine, back to the pixels as given).
  const vision::MatchReport report =
      api::RunMatchPipeline(inputs.left.grey, inputs.right.grey, inputs.calibration.get(), options,
                            args.flags.refinement, runtime.get());
  // Everything is computed before anything is written.
  const std::vector<std::string> written =
      WriteMatchOutputs(args, inputs, report, options, network_bytes);
  if (!report.engine_notice.empty()) {
    std::cerr << "hnnstereo: notice: " << report.engine_notice << "\n";
  }
  if (!args.quiet) PrintMatchSummary(report, written);
}

}  // namespace

void AddMatchCommand(CLI::App& app) {
  auto args = std::make_shared<MatchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "match", "Match edge features of a stereo pair with the Hopfield network -> MATCHES.csv");
  cmd->footer(
      "Example (rectified Middlebury pair):\n"
      "  hnnstereo match --left im2.png --right im6.png --rectified --max-disparity 64 \\\n"
      "      --out matches.csv --report report.json --overlay overlay.png\n"
      "Outputs: MATCHES.csv (xl,yl,xr,yr,activation,confidence; 0-based pixels), REPORT.json (engine, "
      "sizes, iterations, energies, timing_ms).\n"
      "Example (calibrated cell, matches as 3D points):\n"
      "  hnnstereo match --left s7/left.png --right s7/right.png --calib s7/calib.yml \\\n"
      "      --out matches.csv --ply points.ply");
  cmd->add_option("--left", args->left, "Left image (8/16-bit, grey or colour)")->required();
  cmd->add_option("--right", args->right, "Right image, same size")->required();
  auto* calib_opt = cmd->add_option(
      "--calib", args->calib,
      "Calibration: CAL.yml (P1, P2, F) or a Middlebury calib.txt. Without --calib and "
      "--rectified, F is estimated from ORB matches (normalised 8-point + RANSAC) and used "
      "for gating and the soft epipolar term");
  auto* rect_opt = cmd->add_flag("--rectified", args->rectified,
                                 "The pair is rectified: epipolar lines are image rows");
  calib_opt->excludes(rect_opt);
  cmd->add_option("--out", args->out, "Output MATCHES.csv")->required();
  cmd->add_option("--report", args->report, "Output REPORT.json");
  cmd->add_flag("--report-matches", args->report_matches,
                "REPORT.json also lists every match with its confidence features (potential "
                "margin, correlation, neighbour agreement; scripts/fit_confidence.py reads them)");
  cmd->add_option("--overlay", args->overlay, "Output PNG: features and matched features");
  cmd->add_option("--disparity", args->disparity,
                  "Output sparse disparity map of a rectified pair, d = x_l - x_r at each match's "
                  "left pixel: .pfm float32 with NaN where nothing matched, or .png uint16 in the "
                  "KITTI scaling (256 d, 0 = no match)");
  cmd->add_option("--ply", args->ply,
                  "Output PLY point cloud of the triangulated matches (ASCII, x y z in mm, the "
                  "world frame of --calib; a Middlebury calib.txt: the left camera's frame). "
                  "Needs --calib; matches reprojecting worse than 2 px are left out");
  cmd->add_option("--save-network", args->save_network,
                  "Output: the Hopfield network as solved (problem, energy and dynamics; binary "
                  "HNNET1) - replay and time it on any OpenCL device with hnnstereo_replay "
                  "(docs/benchmark.md)");
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  args->flags.AddTo(cmd);
  cmd->add_option("--config", args->config,
                  "YAML file of options: 'long-option-name: value' per line (e.g. "
                  "'max-disparity: 64', 'rectified: true'); the command line wins");
  cmd->callback([args] { RunMatch(*args); });
}

}  // namespace hnnstereo::app
