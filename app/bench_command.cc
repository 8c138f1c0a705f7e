// `hnnstereo bench`: throughput of matching (engines x problem sizes) with StereoSGBM's time on
// the same pair, measured in the same run.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include "app/cli_support.h"
#include "app/commands.h"
#include "common/atomic_file.h"
#include "common/image.h"
#include "perf/camera_size_bench.h"
#include "perf/throughput_bench.h"

namespace hnnstereo::app {
namespace {

struct BenchArgs {
  std::string out;
  std::string sizes = "500,1000,2000,5000,all";
  std::string storages;
  std::string engines = "opencl,cpu,thesis";
  std::string solve_loop = "auto";
  int loop_groups = 0;  // OpenClEngineOptions::resident_groups
  std::string camera_sizes;
  bool quick = false;
  bool profile = false;
  perf::ThroughputBenchOptions bench;
  MatcherFlags flags;
};

std::vector<std::string> SplitCommas(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

void ProgressBar(int done, int total, const std::string& what) {
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  const int width = 30;
  const int filled = total > 0 ? done * width / total : width;
  std::fprintf(stderr, "%s[%.*s%*s] %3d/%d %-28s%s", tty ? "\r" : "", filled,
               "##############################", width - filled, "", done, total, what.c_str(),
               tty ? "" : "\n");
  if (tty && done >= total) std::fputc('\n', stderr);
  std::fflush(stderr);
}

// The bench options from the command line (settings, sizes, engines, storages).
void ResolveBenchOptions(BenchArgs& args) {
  args.flags.Resolve();
  perf::ThroughputBenchOptions& bench = args.bench;
  bench.matcher = args.flags.options;
  bench.matcher.candidates.rectified = true;  // the benchmark pair is rectified
  bench.matcher.opencl.profile = args.profile;
  bench.matcher.opencl.solve_loop = *hnn::ParseSolveLoop(args.solve_loop);  // checked by the flag
  bench.matcher.opencl.resident_groups = args.loop_groups;
  bench.max_disparity = bench.matcher.candidates.max_disparity;
  bench.sparse_sizes.clear();
  for (const std::string& size : SplitCommas(args.sizes)) {
    try {
      bench.sparse_sizes.push_back(size == "all" ? 0 : std::stoi(size));
    } catch (const std::exception&) {
      throw std::invalid_argument("--sizes must be comma-separated feature counts (got '" + args.sizes + "')");
    }
  }
  bench.engines.clear();
  for (const std::string& name : SplitCommas(args.engines)) {
    auto engine = vision::ParseEngine(name);
    if (!engine) throw std::invalid_argument("unknown engine '" + name + "' in --engines");
    bench.engines.push_back(*engine);
  }
  for (const std::string& name : SplitCommas(args.storages)) {
    auto storage = hnn::ParseWeightStorage(name);
    if (!storage) {
      throw std::invalid_argument("unknown weight storage '" + name + "' in --storages (" +
                                  hnn::WeightStorageNames() + ")");
    }
    bench.opencl_storages.push_back(*storage);
  }
  if (args.quick) {
    bench.sparse_sizes = {500, 5000};
    bench.repeats = 3;
  }
}

void PrintBandwidths(const nlohmann::json& json) {
  if (json.contains("machine_read_gbps")) {
    std::printf("machine read bandwidth: %.1f GB/s (%s)\n", json["machine_read_gbps"].get<double>(),
                json["machine_read_method"].get<std::string>().c_str());
  }
  if (json.contains("device_read_gbps")) {
    std::printf("device read bandwidth: %.1f GB/s (%s)\n", json["device_read_gbps"].get<double>(),
                json["device_read_method"].get<std::string>().c_str());
  }
  if (json.contains("opencl_roofline_gbps")) {
    std::printf("opencl roofline: %.1f GB/s = %s\n", json["opencl_roofline_gbps"].get<double>(),
                json["opencl_roofline_basis"].get<std::string>().c_str());
  }
}

// One row per run: case, engine, sizes, times, roofline fraction, energy, precision.
void PrintRunTable(const nlohmann::json& json) {
  std::printf("%-12s %-20s %7s %9s %9s %8s %8s %5s %8s %6s %13s %8s\n", "case", "engine", "neurons",
              "conn", "total ms", "weights", "solve", "steps", "ms/step", "roof", "energy",
              "prec1px");
  for (const auto& run : json["runs"]) {
    if (run.contains("skipped")) {
      std::printf("%-16s %-7s skipped: %s\n", run["case"].get<std::string>().c_str(),
                  run["engine"].get<std::string>().c_str(), run["skipped"].get<std::string>().c_str());
      continue;
    }
    std::string engine = run["engine"].get<std::string>();
    if (run.contains("weight_storage") && engine.find(':') == std::string::npos) {
      engine += ":" + run["weight_storage"].get<std::string>();
    }
    if (run.value("solve_loop", "") == "device") {
      engine += " (1 launch x" + std::to_string(run.value("solve_groups", 1)) + ")";
    }
    if (run["engine_used"].get<std::string>() != run["engine"].get<std::string>().substr(0, run["engine_used"].get<std::string>().size())) {
      engine = run["engine_used"].get<std::string>() + " (fallback)";
    }
    std::printf("%-12s %-20s %7d %9lld %9.1f %8.1f %8.1f %5.0f %8.3f %6s %13.2f %8s\n",
                run["case"].get<std::string>().c_str(), engine.c_str(),
                run["n_neurons"].get<int>(), run["n_connections"].get<long long>(),
                run["ms"].get<double>(), run["weights_ms"].get<double>(),
                run["solve_ms"].get<double>(), run["steps"].get<double>(),
                run["time_per_step_ms"].get<double>(),
                run.contains("roofline_fraction")
                    ? (std::to_string(static_cast<int>(std::lround(100 * run["roofline_fraction"].get<double>()))) + "%").c_str()
                    : "-",
                run["energy_final"].get<double>(),
                run.contains("precision_1px")
                    ? std::to_string(run["precision_1px"].get<double>()).substr(0, 5).c_str()
                    : "-");
  }
}

void PrintProfiles(const nlohmann::json& json) {
  for (const auto& run : json["runs"]) {
    if (!run.contains("profile")) continue;
    const auto& profile = run["profile"];
    std::printf("profile %s %s: weights %.2f ms (device %.2f); solve %.2f ms = device %.2f + host "
                "gap %.2f (%.3f ms a step); %.1f launches and %.1f blocking reads a step\n",
                run["case"].get<std::string>().c_str(), run["engine"].get<std::string>().c_str(),
                profile["weights_ms"].get<double>(), profile["build_device_ms"].get<double>(),
                profile["solve_ms"].get<double>(), profile["solve_device_ms"].get<double>(),
                profile["solve_host_gap_ms"].get<double>(),
                profile["host_gap_per_step_ms"].get<double>(),
                run.value("launches_per_step", 0.0), run.value("blocking_reads_per_step", 0.0));
    for (const auto& command : profile["commands"]) {
      std::printf("  %-5s %-34s %6d x %9.1f us = %8.3f ms\n",
                  command["phase"].get<std::string>().c_str(),
                  command["command"].get<std::string>().c_str(), command["count"].get<int>(),
                  command["us_each"].get<double>(), command["device_ms"].get<double>());
    }
  }
}

// StereoSGBM on the same pair, the batch and the dense comparisons.
void PrintComparisons(const nlohmann::json& json) {
  std::printf("StereoSGBM (same pair, %d disparities): %.1f ms (x_stereo_sgbm in the JSON: each "
              "case's total / this)\n",
              json["stereo_sgbm"]["num_disparities"].get<int>(), json["stereo_sgbm"]["ms"].get<double>());
  if (json.contains("batch")) {
    const auto& b = json["batch"];
    std::printf("batch of %d networks (%lld neurons): one launch per step %.1f ms, one network at "
                "a time %.1f ms (%.2fx)\n",
                b["networks"].get<int>(), b["neurons"].get<long long>(),
                b["solve_batch_ms"].get<double>(), b["solve_one_by_one_ms"].get<double>(),
                b["speedup"].get<double>());
  }
  if (json.contains("dense_comparison")) {
    const auto& d = json["dense_comparison"];
    std::printf("dense %s: opencl %.1fx faster than thesis (weights + solve: %.1f vs %.1f ms); "
                "energy %.3f vs %.3f\n",
                d["case"].get<std::string>().c_str(), d["speedup_weights_plus_solve"].get<double>(),
                d["opencl_weights_plus_solve_ms"].get<double>(),
                d["thesis_weights_plus_solve_ms"].get<double>(), d["opencl_energy_final"].get<double>(),
                d["thesis_energy_final"].get<double>());
  }
}

// --camera-sizes: one row per size - the upsampled pair's whole match against StereoSGBM.
void PrintCameraSizes(const nlohmann::json& json) {
  std::printf("%-11s %6s %6s %8s %8s %8s %8s %8s %8s %8s %7s %9s %6s\n", "size", "MP", "disp",
              "features", "total ms", "coarse", "cand", "network", "solve", "SGBM ms", "x SGBM",
              "ms/1000f", "RSS MB");
  for (const auto& row : json["camera_sizes"]) {
    const auto& stage = row["stage_ms"];
    std::printf("%5dx%-5d %6.2f %6.0f %8d %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %7.2f %9.1f %6.0f\n",
                row["width"].get<int>(), row["height"].get<int>(), row["megapixels"].get<double>(),
                row["max_disparity"].get<double>(), row["n_left"].get<int>(), row["ms"].get<double>(),
                stage["coarse"].get<double>(), stage["candidates"].get<double>(),
                stage["network"].get<double>() + stage["weights"].get<double>(),
                stage["solve"].get<double>(), row["stereo_sgbm_ms"].get<double>(),
                row["x_stereo_sgbm"].get<double>(), row["ms_per_1000_features"].get<double>(),
                row["peak_resident_mb"].get<double>());
  }
  std::printf("ms per 1,000 features: largest / smallest over the sizes = %.2f\n",
              json["ms_per_1000_features_spread"].get<double>());
}

void RunCameraSizes(BenchArgs& args, const vision::LoadedImage& left, const vision::LoadedImage& right) {
  perf::CameraSizeBenchOptions sizes;
  sizes.megapixels.clear();
  for (const std::string& size : SplitCommas(args.camera_sizes)) {
    try {
      std::size_t used = 0;
      sizes.megapixels.push_back(std::stod(size, &used));
      if (used != size.size()) throw std::invalid_argument(size);
    } catch (const std::exception&) {
      throw std::invalid_argument("--camera-sizes must be comma-separated megapixels (got '" +
                                  args.camera_sizes + "')");
    }
  }
  sizes.max_disparity = args.bench.max_disparity;
  sizes.repeats = args.bench.repeats;
  sizes.preset = {args.flags.preset, args.bench.matcher, args.flags.refinement};
  sizes.progress = ProgressBar;
  AsSetupError([&] {
    if (auto error = sizes.Check(); !error.empty()) throw std::invalid_argument(error);
  });
  std::unique_ptr<ocl::Runtime> runtime = OpenRuntimeFor(args.bench.matcher.engine, args.flags.device);
  const nlohmann::json json = perf::RunCameraSizeBench(left.grey, right.grey, sizes, runtime.get());
  calib::WriteFileAtomically(args.out, json.dump(2) + "\n");
  PrintCameraSizes(json);
  std::printf("wrote %s\n", args.out.c_str());
}

void RunBench(BenchArgs& args) {
  CheckOutputsWritable({{"--out", args.out}});
  ResolveBenchOptions(args);
  perf::ThroughputBenchOptions& bench = args.bench;
  // Inputs that cannot be used are a refused setup (exit 2), found before the benchmark runs.
  const vision::LoadedImage left = AsSetupError("--left", [&] { return vision::LoadImage(bench.left); });
  const vision::LoadedImage right =
      AsSetupError("--right", [&] { return vision::LoadImage(bench.right); });
  AsSetupError([&] { vision::CheckSameSize(left, right); });
  if (!bench.ground_truth.empty()) {
    AsSetupError("--ground-truth", [&] { return vision::LoadImage(bench.ground_truth); });
  }
  if (!args.camera_sizes.empty()) return RunCameraSizes(args, left, right);
  bench.progress = ProgressBar;
  const bool wants_opencl = std::find(bench.engines.begin(), bench.engines.end(),
                                      hnn::EngineKind::kOpenCL) != bench.engines.end();
  std::unique_ptr<ocl::Runtime> runtime =
      OpenRuntimeFor(wants_opencl ? hnn::EngineKind::kOpenCL : hnn::EngineKind::kCpu,
                     args.flags.device);
  const nlohmann::json json = perf::RunThroughputBench(bench, runtime.get());
  calib::WriteFileAtomically(args.out, json.dump(2) + "\n");

  PrintBandwidths(json);
  PrintRunTable(json);
  PrintProfiles(json);
  PrintComparisons(json);
  std::printf("wrote %s\n", args.out.c_str());
}

}  // namespace

void AddBenchCommand(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  args->bench.left = HNNSTEREO_DATA_DIR "/middlebury2003_teddy/im2.png";
  args->bench.right = HNNSTEREO_DATA_DIR "/middlebury2003_teddy/im6.png";
  args->bench.ground_truth = HNNSTEREO_DATA_DIR "/middlebury2003_teddy/disp2.png";
  CLI::App* cmd = app.add_subcommand("bench", "Throughput of matching -> BENCH.json");
  cmd->footer(
      "Throughput of matching: engines x problem sizes on a rectified pair (default: the "
      "vendored Middlebury Teddy), medians of warmed-up repeats, with OpenCV StereoSGBM timed "
      "on the same pair in the same run. Progress on stderr, a table on stdout, JSON in --out.");
  cmd->add_option("--out", args->out, "Output BENCH.json")->required();
  cmd->add_option("--left", args->bench.left, "Left image")->capture_default_str();
  cmd->add_option("--right", args->bench.right, "Right image")->capture_default_str();
  cmd->add_option("--ground-truth", args->bench.ground_truth,
                  "Left disparity map for a precision column ('' = none)")
      ->capture_default_str();
  cmd->add_option("--ground-truth-scale", args->bench.ground_truth_scale,
                  "Stored value / scale = disparity")
      ->capture_default_str();
  cmd->add_option("--sizes", args->sizes,
                  "Sparse cases: --max-features values, comma-separated; 'all' = every feature "
                  "(the default match)")
      ->capture_default_str();
  cmd->add_option("--camera-sizes", args->camera_sizes,
                  "Instead of the sparse cases: the pair upsampled to each of these sizes "
                  "(megapixels, comma-separated, e.g. 0.3,1.3,3,5), its whole match (match's "
                  "settings, refinements included) against StereoSGBM on the same pair, stage "
                  "times, peak memory and ms per 1,000 features (docs/benchmark.md)");
  cmd->add_option("--storages", args->storages,
                  "Run the opencl engine once per weight storage listed, comma-separated, of: " +
                      hnn::WeightStorageNames() + " (default: as --weights says)");
  cmd->add_option("--dense-features", args->bench.dense_features,
                  "Features per image of the thesis-sized --dense case (0 = none)")
      ->capture_default_str();
  cmd->add_option("--engines", args->engines, "Engines, comma-separated")->capture_default_str();
  cmd->add_option("--repeats", args->bench.repeats, "Timed runs per case")->capture_default_str();
  cmd->add_option("--warmup", args->bench.warmup, "Untimed runs per case first")->capture_default_str();
  cmd->add_option("--thesis-max-neurons", args->bench.thesis_max_neurons,
                  "Run the thesis engine only up to this many neurons")
      ->capture_default_str();
  cmd->add_option("--batch-networks", args->bench.batch_networks,
                  "Batch case: strips of the pair solved as independent networks (0 = none)")
      ->capture_default_str();
  cmd->add_option("--solve-loop", args->solve_loop,
                  "Where the opencl row-block solve loops: auto (in one launch on a CPU device "
                  "for one network, else a launch per step), host or device "
                  "(docs/engine.md)")
      ->check(CLI::IsMember({"auto", "host", "device"}))
      ->capture_default_str();
  cmd->add_option("--loop-groups", args->loop_groups,
                  "Device solve loop: work-groups (threads) that take the ranges of rows of "
                  "each step (0 = one per compute unit on a CPU device, one on a GPU)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--quick", args->quick, "Sizes 500 and 5000, 3 repeats");
  cmd->add_flag("--profile", args->profile,
                "Time every OpenCL command with profiling events: per kernel device time, the "
                "solve's host gap (wall - device), launches and blocking reads per step (printed, "
                "and 'profile' per run in the JSON). Events add host time to every launch: compare "
                "timings from runs without it");
  args->flags.AddTo(cmd);
  cmd->callback([args] { RunBench(*args); });
}

}  // namespace hnnstereo::app
