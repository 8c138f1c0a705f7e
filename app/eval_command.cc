// `hnnstereo eval`: accuracy on Middlebury pairs with ground truth, the Hopfield matcher against
// baselines at the same left pixels (issue 6; vision/eval/evaluation.h defines every figure).
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
  bool baselines = true;
  bool warped = false;
  bool quiet = false;
  double upsample = 1.0;
  std::vector<std::string> outdoor_names = vision::EvaluationOptions{}.outdoor_names;
  /// The matcher flags of `match`, applied to the first preset (the one under test); the engine,
  /// device and memory budget to every preset.
  MatcherFlags flags;
};

// The presets of --presets; the first resolved through the library with the flags given (its
// own settings as the base), the others as defined with the first's engine and memory budget.
std::vector<vision::MatcherPreset> EvaluatedPresets(EvalArgs& args) {
  std::vector<vision::MatcherPreset> presets;
  std::stringstream names(args.presets);
  for (std::string name; std::getline(names, name, ',');) {
    auto preset = vision::FindPreset(name);
    if (!preset) throw std::invalid_argument("--presets: unknown preset '" + name + "'");
    if (presets.empty()) {
      vision::MatcherOptions base = preset->matcher;
      base.memory_budget_bytes = vision::kEvaluationMemoryBudgetBytes;
      args.flags.preset = name;
      args.flags.options = base;
      args.flags.Resolve();
      preset->matcher = args.flags.options;
      preset->refinement = args.flags.refinement;
      // The Middlebury pairs are rectified: the disparity network runs as given.
      if (preset->matcher.candidates.kind == hnn::NetworkKind::kFeatureVsDisparity) {
        preset->matcher.candidates.rectified = true;
      }
    } else {
      preset->matcher.engine = presets.front().matcher.engine;
      preset->matcher.memory_budget_bytes = presets.front().matcher.memory_budget_bytes;
    }
    presets.push_back(*preset);
  }
  return presets;
}

void RunEval(EvalArgs& args) {
  CheckOutputsWritable({{"--out", args.out}, {"--markdown", args.markdown}, {"--plot", args.plot}});
  vision::EvaluationOptions options;
  options.presets = EvaluatedPresets(args);
  const hnn::EngineKind engine = options.presets.front().matcher.engine;
  options.baselines = args.baselines;
  options.outdoor_names = args.outdoor_names;
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
    for (const std::string& directory : directories) {
      loaded.push_back(vision::UpsampledMiddlebury(vision::LoadMiddlebury(directory), args.upsample));
    }
    return loaded;
  });

  std::unique_ptr<ocl::Runtime> runtime = OpenRuntimeFor(engine, args.flags.device);
  const vision::EvaluationReport report = vision::Evaluate(pairs, options, runtime.get());

  // Everything is computed before anything is written; each file is written atomically.
  nlohmann::json json = vision::EvaluationJson(report);
  json["dataset"] = args.dataset;
  json["engine"] = vision::EngineName(engine);
  json["presets"] = nlohmann::json::array();
  for (const vision::MatcherPreset& preset : options.presets) {
    json["presets"].push_back(
        {{"name", preset.name},
         {"objective", hnn::ObjectiveName(preset.matcher.energy.objective)},
         {"decode", hnn::DecodeMethodName(preset.matcher.decode.method)},
         {"network", hnn::NetworkKindName(preset.matcher.candidates.kind)},
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
  // The confidence calibration next to --out: OUT_STEM.calibration.png.
  cv::Mat calibration = vision::DrawCalibrationPlot(report);
  if (!calibration.empty()) {
    const std::filesystem::path out(args.out);
    pair_plots.emplace_back((out.parent_path() / (out.stem().string() + ".calibration.png")).string(),
                            std::move(calibration));
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
      "pair next to --out: EVAL.<pair>.png. The HNN's confidence calibration (error rate per\n"
      "confidence bin, per pair, per scene type and overall): EVAL.json\n"
      "\"confidence_calibration\", the Markdown, and EVAL.calibration.png.");
  cmd->add_option("--dataset", args->dataset,
                  "A Middlebury set folder, or a folder holding several")->required();
  cmd->add_option("--out", args->out, "Output EVAL.json")->required();
  cmd->add_option("--markdown", args->markdown, "Also write the Markdown table to this file");
  cmd->add_option("--plot", args->plot, "Precision-versus-density PNG (default: --out with .png)");
  cmd->add_option("--presets", args->presets,
                  "Comma-separated matcher presets, the first is the one under test and gives "
                  "the baselines their pixels: hnn-default, hnn-thesis, and the ablations "
                  "hnn-geometry (no refinement), hnn-geometry-lr (left-right check only), "
                  "hnn-disparity (all disparity levels, no peak selection), "
                  "hnn-disparity-subpixel (sub-pixel peaks). The matcher flags below (match's) "
                  "change the first preset; --engine, --device and --memory-budget-mb apply to "
                  "every preset")
      ->capture_default_str();
  AddSwitch(cmd, "baselines", &args->baselines,
            "WTA ZNCC, StereoBM and StereoSGBM at the same pixels");
  AddSwitch(cmd, "warped", &args->warped,
            "Also evaluate the unrectified version: right image warped by a known H, calibration "
            "P2 = H P2, scored after mapping back with H");
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  cmd->add_option("--outdoor-names", args->outdoor_names,
                  "Pairs whose folder name contains one of these are outdoor scenes, the others "
                  "indoor: the confidence calibration is pooled per scene type")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--upsample", args->upsample,
                  "Evaluate each pair at this many times its size (images bicubic, ground truth "
                  "nearest, disparities and range scaled): camera-sized pairs with real ground "
                  "truth")
      ->check(CLI::Range(1.0, 16.0))
      ->capture_default_str();
  // match's matcher flags, over the first preset (for measuring changes, docs/accuracy.md); the
  // help shows hnn-default's values, the default first preset.
  args->flags.options = vision::AccurateDefaultPreset().matcher;
  args->flags.options.memory_budget_bytes = vision::kEvaluationMemoryBudgetBytes;
  args->flags.AddTo(cmd, /*with_preset=*/false);
  cmd->callback([args] { RunEval(*args); });
}

}  // namespace hnnstereo::app
