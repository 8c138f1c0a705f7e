// `hnnstereo eval`: accuracy on Middlebury pairs with ground truth, the Hopfield matcher against
// baselines at the same left pixels (issue 6; vision/evaluation.h defines every figure).
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "app/cli_support.h"
#include "app/commands.h"
#include "common/atomic_file.h"
#include "host/decode.h"
#include "vision/eval/eval_plot.h"
#include "vision/eval/evaluation.h"
#include "vision/stereo/match_io.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/eval/middlebury.h"
#include "vision/stereo/overlay.h"

namespace hnnstereo::app {
namespace {

struct EvalArgs {
  std::string dataset, out, markdown, plot;
  std::string presets = "hnn-default,hnn-thesis";
  std::string engine = "opencl";
  std::string device;
  bool no_baselines = false;
  bool warped = false;
  bool quiet = false;
  // Overrides of the first preset (the one under test); applied only when given.
  std::string objective, decode, network;
  int top_k = 8, max_features = 0, zncc_window = 7, max_steps = 300;
  double memory_budget_mb = 6144.0;
  double support_radius = 8.0, threshold = 0.5, max_epipolar = 1.5, min_correlation = -1.0;
  bool left_right_check = false, subpixel = false, zncc_peaks = false, subpixel_peaks = false;
  bool epipolar_snap = false, epipolar_subpixel = false;
  double lr_tolerance = 1.0;
  std::string data_term;
  int census_window = 5, aggregation_window = 13;
  double support_gamma = 20.0, subpixel_min_offset = 0.1;
  double energy_a = 2.0, energy_t = 1.5;
  CLI::App* cmd = nullptr;
};

bool Given(const EvalArgs& args, const std::string& name) { return args.cmd->count(name) > 0; }

vision::MatcherPreset ApplyOverrides(vision::MatcherPreset preset, const EvalArgs& args) {
  vision::MatcherOptions& o = preset.matcher;
  if (Given(args, "--objective")) {
    const auto objective = hnn::ParseObjective(args.objective);
    if (!objective) throw std::invalid_argument("--objective: unknown '" + args.objective + "'");
    o.energy.objective = *objective;
  }
  if (Given(args, "--decode")) {
    const auto method = hnn::ParseDecodeMethod(args.decode);
    if (!method) throw std::invalid_argument("--decode: unknown '" + args.decode + "'");
    o.decode.method = *method;
  }
  if (Given(args, "--network")) {
    if (args.network == "feature") {
      o.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
    } else if (args.network == "disparity") {
      o.candidates.kind = hnn::NetworkKind::kFeatureVsDisparity;
      o.candidates.rectified = true;  // the Middlebury pairs are rectified
    } else {
      throw std::invalid_argument("--network: unknown '" + args.network + "'");
    }
  }
  if (Given(args, "--top-k")) o.candidates.top_k = args.top_k;
  if (Given(args, "--max-features")) o.features.max_features = args.max_features;
  if (Given(args, "--zncc-window")) o.zncc_window = args.zncc_window;
  if (Given(args, "--max-steps")) o.dynamics.max_steps = args.max_steps;
  if (Given(args, "--support-radius")) o.energy.support_radius_px = args.support_radius;
  if (Given(args, "--threshold")) o.decode.threshold = args.threshold;
  if (Given(args, "--max-epipolar")) o.candidates.max_epipolar_distance_px = args.max_epipolar;
  if (Given(args, "--min-correlation")) o.candidates.min_correlation = args.min_correlation;
  if (Given(args, "--lr-check")) preset.refinement.left_right_check = args.left_right_check;
  if (Given(args, "--subpixel")) preset.refinement.subpixel = args.subpixel;
  if (Given(args, "--subpixel-min-offset")) {
    preset.refinement.subpixel_min_offset_px = args.subpixel_min_offset;
  }
  if (Given(args, "--epipolar-snap")) preset.refinement.epipolar_snap = args.epipolar_snap;
  if (Given(args, "--epipolar-subpixel")) {
    preset.refinement.epipolar_subpixel = args.epipolar_subpixel;
  }
  if (Given(args, "--lr-tolerance")) preset.refinement.left_right_tolerance_px = args.lr_tolerance;
  if (Given(args, "--zncc-peaks")) o.candidates.zncc_peaks = args.zncc_peaks;
  if (Given(args, "--subpixel-peaks")) o.candidates.subpixel_peaks = args.subpixel_peaks;
  if (Given(args, "--data-term")) {
    if (args.data_term == "zncc") {
      o.data_term.kind = vision::DataTermOptions::Kind::kZncc;
    } else if (args.data_term == "census") {
      o.data_term.kind = vision::DataTermOptions::Kind::kCensus;
    } else {
      throw std::invalid_argument("--data-term: unknown '" + args.data_term + "' (zncc or census)");
    }
  }
  if (Given(args, "--data-term")) o.confidence = vision::ConfidenceOptionsFor(o.data_term);
  if (Given(args, "--census-window")) o.data_term.census_window = args.census_window;
  if (Given(args, "--aggregation-window")) o.data_term.aggregation_window = args.aggregation_window;
  if (Given(args, "--support-gamma")) o.data_term.support_gamma = args.support_gamma;
  if (Given(args, "--A")) o.energy.A = args.energy_a;
  if (Given(args, "--T")) o.energy.T = args.energy_t;
  return preset;
}

void RunEval(EvalArgs& args) {
  CheckOutputsWritable({{"--out", args.out}, {"--markdown", args.markdown}, {"--plot", args.plot}});
  const auto engine = vision::ParseEngine(args.engine);
  if (!engine) throw std::invalid_argument("--engine: unknown '" + args.engine + "'");
  // Bounded so that the conversion to bytes below is defined (inf, NaN or 1e300 do not fit a
  // size_t); 2^40 MB is beyond any machine.
  if (!(args.memory_budget_mb > 0.0) || !(args.memory_budget_mb <= 1099511627776.0)) {
    throw std::invalid_argument("--memory-budget-mb must be a number in (0, 1099511627776] (is " +
                                std::to_string(args.memory_budget_mb) + ")");
  }
  vision::EvaluationOptions options;
  options.presets.clear();
  std::stringstream names(args.presets);
  for (std::string name; std::getline(names, name, ',');) {
    auto preset = vision::FindPreset(name);
    if (!preset) throw std::invalid_argument("--presets: unknown preset '" + name + "'");
    preset->matcher.engine = *engine;
    preset->matcher.memory_budget_bytes =
        static_cast<std::size_t>(args.memory_budget_mb * 1024.0 * 1024.0);
    options.presets.push_back(options.presets.empty() ? ApplyOverrides(*preset, args) : *preset);
  }
  options.baselines = !args.no_baselines;
  options.warped = args.warped;
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);

  // A dataset that cannot be used is a refused setup (exit 2), found before any matching.
  const std::vector<vision::MiddleburyPair> pairs = AsSetupError("--dataset", [&] {
    const std::vector<std::string> directories = vision::FindMiddleburyDatasets(args.dataset);
    if (directories.empty()) {
      throw std::runtime_error("no Middlebury set found in '" + args.dataset +
                               "' (nor in its immediate subfolders)");
    }
    std::vector<vision::MiddleburyPair> loaded;
    for (const std::string& directory : directories) loaded.push_back(vision::LoadMiddlebury(directory));
    return loaded;
  });

  std::unique_ptr<ocl::Runtime> runtime = OpenRuntimeFor(*engine, args.device);
  const vision::EvaluationReport report = vision::Evaluate(pairs, options, runtime.get());

  // Everything is computed before anything is written; each file is written atomically.
  nlohmann::json json = vision::EvaluationJson(report);
  json["dataset"] = args.dataset;
  json["engine"] = args.engine;
  json["presets"] = nlohmann::json::array();
  for (const vision::MatcherPreset& preset : options.presets) {
    json["presets"].push_back(
        {{"name", preset.name},
         {"objective", hnn::ObjectiveName(preset.matcher.energy.objective)},
         {"decode", hnn::DecodeMethodName(preset.matcher.decode.method)},
         {"network", preset.matcher.candidates.kind == hnn::NetworkKind::kFeatureVsDisparity
                         ? "disparity"
                         : "feature"},
         {"top_k", preset.matcher.candidates.top_k},
         {"support_radius_px", preset.matcher.energy.support_radius_px},
         {"data_term", vision::DataTermJson(preset.matcher)},
         {"A", preset.matcher.energy.A},
         {"T", preset.matcher.energy.T},
         {"threshold", preset.matcher.decode.threshold},
         {"max_features", preset.matcher.features.max_features},
         {"left_right_check", preset.refinement.left_right_check},
         {"subpixel", preset.refinement.subpixel},
         {"epipolar_snap", preset.refinement.epipolar_snap},
         {"epipolar_subpixel", preset.refinement.epipolar_subpixel}});
  }
  const std::string markdown = vision::EvaluationMarkdown(report);
  const std::string plot_path =
      args.plot.empty() ? std::filesystem::path(args.out).replace_extension(".png").string() : args.plot;
  // One ranked plot per pair next to --out: OUT_STEM.<pair>.png.
  std::vector<std::pair<std::string, cv::Mat>> pair_plots;
  for (const vision::PairEvaluation& pair : report.pairs) {
    cv::Mat ranked = vision::DrawRankedPlot(pair);
    if (ranked.empty()) continue;
    const std::filesystem::path out(args.out);
    pair_plots.emplace_back(
        (out.parent_path() / (out.stem().string() + "." + pair.name + ".png")).string(),
        std::move(ranked));
  }
  calib::WriteFileAtomically(args.out, json.dump(2) + "\n");
  if (!args.markdown.empty()) calib::WriteFileAtomically(args.markdown, markdown);
  vision::WritePngAtomically(plot_path, vision::DrawPrecisionDensityPlot(report));
  for (const auto& [path, image] : pair_plots) vision::WritePngAtomically(path, image);
  for (const vision::PairEvaluation& pair : report.pairs) {
    for (const std::string& notice : pair.notices) {
      std::cerr << "hnnstereo: notice: " << pair.name << ": " << notice << "\n";
    }
  }
  if (!args.quiet) {
    std::printf("%s\nwrote %s, %s%s%s (%zu pairs, %.1f s)\n", markdown.c_str(), args.out.c_str(),
                plot_path.c_str(), args.markdown.empty() ? "" : ", ", args.markdown.c_str(),
                report.pairs.size(), report.time_ms / 1000.0);
    for (const auto& pair_plot : pair_plots) std::printf("wrote %s\n", pair_plot.first.c_str());
  }
}

}  // namespace

void AddEvalCommand(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval",
      "Accuracy on Middlebury pairs with ground truth: the Hopfield matcher presets and the\n"
      "baselines (winner-take-all ZNCC, OpenCV StereoBM, StereoSGBM) at the same left pixels.\n"
      "Layouts: 2001 (Tsukuba scene1.row3.col3/col4 + truedisp/16 + nonocc.png; im2/im6 +\n"
      "disp2.pgm/8), 2003 (im2/im6 + disp2.png/4), 2005/2006 (view1/view5 + disp1.png/3 at\n"
      "third size), 2014 (im0/im1 + disp0GT.pfm (PFM, +inf unknown) + calib.txt + mask0nocc.png).\n"
      "Example:\n"
      "  hnnstereo eval --dataset ../shared/datasets --out eval.json --markdown eval.md\n"
      "Outputs: EVAL.json (per pair and overall: precision within 1/2 px at non-occluded pixels,\n"
      "occluded matches apart, density over Canny edge pixels with ground truth, time), a\n"
      "Markdown table on stdout (and --markdown), a precision-versus-density PNG (--plot).\n"
      "Ranked by confidence (with the baselines): every method over all edge pixels, ranked by\n"
      "its own confidence (HNN: its confidence; WTA ZNCC: its margin; StereoSGBM / StereoBM:\n"
      "swept over the uniqueness ratio 0-60 with a left-right check); error rates at 25/50/75 %\n"
      "and full density in the Markdown and under \"ranked\" in EVAL.json, and one plot per\n"
      "pair next to --out: EVAL.<pair>.png.");
  args->cmd = cmd;
  cmd->add_option("--dataset", args->dataset,
                  "A Middlebury set folder, or a folder holding several")->required();
  cmd->add_option("--out", args->out, "Output EVAL.json")->required();
  cmd->add_option("--markdown", args->markdown, "Also write the Markdown table to this file");
  cmd->add_option("--plot", args->plot, "Precision-versus-density PNG (default: --out with .png)");
  cmd->add_option("--presets", args->presets,
                  "Comma-separated matcher presets, the first is the one under test and gives "
                  "the baselines their pixels: hnn-default, hnn-thesis, and the ablations "
                  "hnn-geometry (no refinement), hnn-geometry-lr (left-right check only; the "
                  "previous default), hnn-disparity (all disparity levels, no peak selection), "
                  "hnn-disparity-subpixel (sub-pixel peaks)")
      ->capture_default_str();
  cmd->add_option("--engine", args->engine, "opencl (falls back to cpu with a notice), cpu, thesis")
      ->capture_default_str();
  cmd->add_option("--device", args->device, "OpenCL device: index or name substring");
  cmd->add_option("--memory-budget-mb", args->memory_budget_mb,
                  "Memory budget of every preset's network (MB); textured sets need ~2.4 GB")
      ->capture_default_str();
  cmd->add_flag("--no-baselines", args->no_baselines, "Skip WTA ZNCC, StereoBM and StereoSGBM");
  cmd->add_flag("--warped", args->warped,
                "Also evaluate the unrectified version: right image warped by a known H, "
                "calibration P2 = H P2, scored after mapping back with H");
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  // Overrides of the first preset, for measuring changes (docs/accuracy.md).
  cmd->add_option("--objective", args->objective,
                  "First preset: thesis, printed0, printed1, printed2, geometry-similarity");
  cmd->add_option("--decode", args->decode, "First preset: thesis or one-to-one");
  cmd->add_option("--network", args->network, "First preset: feature or disparity");
  cmd->add_option("--top-k", args->top_k, "First preset: candidates per left feature");
  cmd->add_option("--max-features", args->max_features, "First preset: feature cap (0 = none)");
  cmd->add_option("--zncc-window", args->zncc_window, "First preset: ZNCC window side");
  cmd->add_option("--max-steps", args->max_steps, "First preset: Euler step limit");
  cmd->add_option("--support-radius", args->support_radius, "First preset: support radius (px)");
  cmd->add_option("--threshold", args->threshold, "First preset: decode threshold");
  cmd->add_option("--max-epipolar", args->max_epipolar, "First preset: epipolar gate (px)");
  cmd->add_option("--min-correlation", args->min_correlation, "First preset: ZNCC gate");
  cmd->add_option("--lr-check", args->left_right_check, "First preset: left-right check (0/1)");
  cmd->add_option("--subpixel", args->subpixel, "First preset: sub-pixel parabola fit (0/1)");
  cmd->add_option("--subpixel-min-offset", args->subpixel_min_offset,
                  "First preset: the sub-pixel fit leaves a match whose vertex lies closer than "
                  "this (px) to its whole pixel (hnn-default 0.1)");
  cmd->add_option("--epipolar-snap", args->epipolar_snap,
                  "First preset, unrectified (--warped) runs: move right points onto the epipolar "
                  "line (0/1)");
  cmd->add_option("--epipolar-subpixel", args->epipolar_subpixel,
                  "First preset, unrectified (--warped) runs: sub-pixel parabola fit along the "
                  "epipolar line (0/1)");
  cmd->add_option("--lr-tolerance", args->lr_tolerance, "First preset: left-right tolerance (px)");
  cmd->add_option("--zncc-peaks", args->zncc_peaks,
                  "First preset, disparity network: candidates only at ZNCC peaks (0/1)");
  cmd->add_option(
      "--data-term", args->data_term,
      "First preset: the similarity of windows, zncc (thesis eq. 6.9, --zncc-window) or "
      "census (hnn-default)");
  cmd->add_option("--census-window", args->census_window,
                  "First preset, census data term: census transform side, 3 or 5 (hnn-default 5)");
  cmd->add_option("--aggregation-window", args->aggregation_window,
                  "First preset, census data term: side of the square the Hamming costs are summed "
                  "over, odd 1..31 (hnn-default 13)");
  cmd->add_option("--support-gamma", args->support_gamma,
                  "First preset, census data term: adaptive support weight exp(-|dI| / gamma), "
                  "grey levels; 0 = box (hnn-default 20)");
  cmd->add_option("--subpixel-peaks", args->subpixel_peaks,
                  "First preset, disparity network: parabola sub-pixel candidate disparities (0/1)");
  cmd->add_option("--A", args->energy_a,
                  "First preset: energy weight of the compatibility term (eq. 6.5; hnn-default 2)");
  cmd->add_option("--T", args->energy_t,
                  "First preset: disparity-gradient scale of the compatibility, g = 2 exp(-DG / T) "
                  "- 1 (eq. 6.8; hnn-default 1.5)");
  cmd->callback([args] { RunEval(*args); });
}

}  // namespace hnnstereo::app
