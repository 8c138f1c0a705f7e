// hnnstereo_replay: replays captured Hopfield networks (`hnnstereo match --save-network`,
// host/network_file.h) on an OpenCL device and times every weight storage, with the device's
// own streaming read bandwidth measured in the same run as the roofline. It needs neither the
// images nor OpenCV: the GPU benchmark of docs/benchmark.md carries this binary and the network
// files to a machine with a GPU.
//
//   hnnstereo_replay NET.hnnet... [--storages csr,blocked-float,blocked-half,on-the-fly]
//       [--repeats 5] [--warmup 1] [--cpu] [--device SEL] [--profile] [--out replay.json]
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <nlohmann/json.hpp>

#include "host/cpu_engines.h"
#include "host/decode.h"
#include "host/network_file.h"
#include "host/opencl_engine.h"
#include "perf/device_bandwidth.h"
#include "perf/statistics.h"

namespace {

using namespace hnnstereo;
using perf::Median;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("cannot read '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// The command line.
struct ReplayFlags {
  std::vector<std::string> files;
  std::vector<std::string> storages = {"csr", "blocked-float", "blocked-half", "on-the-fly"};
  std::string device, out;
  std::string block_step = "auto", solve_loop = "auto";
  int repeats = 5, warmup = 1, rows_per_item = 0, loop_groups = 0;
  double time_step = 0.0;
  bool cpu = false, profile = false;
};

void AddFlags(CLI::App& app, ReplayFlags& f) {
  app.add_option("networks", f.files, "Network files (HNNET1)")->required();
  app.add_option("--storages", f.storages, "Weight storages of the opencl engine, comma-separated")
      ->delimiter(',');
  app.add_option("--repeats", f.repeats, "Timed solves per case (median reported)")->check(CLI::Range(1, 1000));
  app.add_option("--warmup", f.warmup, "Untimed solves first (kernel compilation)")->check(CLI::Range(0, 100));
  app.add_flag("--cpu", f.cpu, "Also the cpu reference engine (one timed solve), the winners' baseline");
  app.add_option("--device", f.device, "OpenCL device: index or name substring (default: the first GPU)");
  app.add_flag("--profile", f.profile, "Device time per kernel (OpenCL profiling events)");
  app.add_option("--time-step", f.time_step,
                 "Override the captured Euler step dt of the opencl runs (0 = as captured); the "
                 "agree column then compares with the first engine's winners at the captured dt")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--rows-per-item", f.rows_per_item,
                 "Row blocks, per-item step: rows per work-item (0 = the engine's choice)")
      ->check(CLI::Range(0, 1 << 20));
  app.add_option("--block-step", f.block_step,
                 "Row blocks' step: auto (a work-group per row on a GPU), item (runs of rows per "
                 "work-item) or group (a work-group of lanes per row)")
      ->check(CLI::IsMember({"auto", "item", "group"}));
  app.add_option("--solve-loop", f.solve_loop,
                 "Row blocks' solve loop: auto (on the device for one small network on a CPU "
                 "device), host (a launch per step) or device (the whole loop in one launch)")
      ->check(CLI::IsMember({"auto", "host", "device"}));
  app.add_option("--loop-groups", f.loop_groups,
                 "Device solve loop: work-groups (threads) that take the ranges of rows of each "
                 "step (0 = one per compute unit on a CPU device, one on a GPU)")
      ->check(CLI::Range(0, 1024));
  app.add_option("--out", f.out, "JSON output");
}

// The --storages names as storages.
std::vector<hnn::WeightStorage> ParseStorages(const std::vector<std::string>& storages) {
  std::vector<hnn::WeightStorage> kinds;
  for (const std::string& name : storages) {
    auto storage = hnn::ParseWeightStorage(name);
    if (!storage) throw std::invalid_argument("--storages: unknown storage '" + name + "'");
    kinds.push_back(*storage);
  }
  return kinds;
}

// The opencl engine's options for one storage under the flags.
hnn::OpenClEngineOptions EngineOptionsFor(const ReplayFlags& f, hnn::WeightStorage storage) {
  hnn::OpenClEngineOptions options;
  options.storage = storage;
  options.profile = f.profile;
  options.rows_per_item = f.rows_per_item;
  options.block_step = f.block_step == "item"    ? hnn::OpenClEngineOptions::BlockStep::kRowPerItem
                       : f.block_step == "group" ? hnn::OpenClEngineOptions::BlockStep::kRowPerGroup
                                                 : hnn::OpenClEngineOptions::BlockStep::kAuto;
  options.solve_loop = *hnn::ParseSolveLoop(f.solve_loop);  // checked by the flag
  options.resident_groups = f.loop_groups;
  return options;
}

// One network's runs: each engine's median times, its bytes a second against the device's
// read bandwidth (the roofline), and its winners against the first engine's; a table row and
// a JSON record each.
class NetworkRuns {
 public:
  NetworkRuns(const hnn::CapturedNetwork& net, std::string name,
              const perf::ReadBandwidth& bandwidth, nlohmann::json* runs)
      : net_(net), name_(std::move(name)), bandwidth_(bandwidth), runs_(runs) {}

  void Record(const std::string& engine, std::vector<hnn::SolveReport> reports) {
    const hnn::SolveReport& last = reports.back();
    std::vector<double> solve, weights;
    for (const auto& r : reports) {
      solve.push_back(r.solve_ms);
      weights.push_back(r.weights_ms);
    }
    const double solve_ms = Median(solve);
    const double steps = last.iterations + 1.0;
    const double step_bytes = last.step_bytes > 0
                                  ? last.step_bytes
                                  : static_cast<double>(last.n_connections) * 16.0 +
                                        last.n_neurons * 32.0;
    const double gbps = solve_ms > 0 ? steps * step_bytes / (solve_ms / 1000.0) / 1e9 : 0.0;
    const std::set<std::pair<int, int>> winners = Winners(last);
    if (baseline_.empty()) baseline_ = winners;
    std::size_t same = 0;
    for (const auto& w : winners) same += baseline_.count(w);
    const double agree = baseline_.empty()
                             ? 1.0
                             : static_cast<double>(same) /
                                   static_cast<double>(std::max(winners.size(), baseline_.size()));
    const bool on_device = last.engine == "opencl";
    const double roof = on_device && bandwidth_.gbps > 0 ? gbps / bandwidth_.gbps : 0.0;
    std::printf("%-22s %-14s %8d %10lld %9.2f %9.2f %5.0f %9.3f %8.1f %5.0f%% %14.2f %8zu %6.1f%%\n",
                name_.c_str(), engine.c_str(), last.n_neurons,
                static_cast<long long>(last.n_connections), Median(weights), solve_ms, steps,
                solve_ms / steps, gbps, 100.0 * roof, last.energy_final, winners.size(),
                100.0 * agree);
    nlohmann::json run = {{"network", name_},
                          {"engine", engine},
                          {"device", last.device},
                          {"n_neurons", last.n_neurons},
                          {"n_connections", last.n_connections},
                          {"weights_ms", Median(weights)},
                          {"solve_ms", solve_ms},
                          {"solve_ms_runs", solve},
                          {"network_ms", last.network_ms},
                          {"steps", steps},
                          {"time_per_step_ms", solve_ms / steps},
                          {"step_bytes", step_bytes},
                          {"bytes_per_second", gbps * 1e9},
                          {"energy_final", last.energy_final},
                          {"n_matches", winners.size()},
                          {"agreement_with_first", agree},
                          {"launches", last.launches},
                          {"blocking_reads", last.blocking_reads}};
    if (on_device) run["roofline_fraction"] = roof;
    if (!last.solve_loop.empty()) run["solve_loop"] = last.solve_loop;
    if (last.solve_groups > 0) run["solve_groups"] = last.solve_groups;
    if (!last.kernel_times.empty()) run["profile"] = Profile(last.kernel_times);
    runs_->push_back(run);
  }

  // `engine`'s warm-up and timed solves with `options`, recorded; a failure is recorded as an
  // error.
  void Replay(ocl::Runtime& runtime, const hnn::OpenClEngineOptions& options,
              const hnn::DynamicsOptions& dynamics, int warmup, int repeats) {
    const hnn::WeightStorage storage = options.storage;
    hnn::OpenClEngine engine(runtime, options);
    std::vector<hnn::SolveReport> reports;
    try {
      for (int r = 0; r < warmup; ++r) engine.Solve(net_.problem, net_.energy, dynamics);
      for (int r = 0; r < repeats; ++r) {
        reports.push_back(engine.Solve(net_.problem, net_.energy, dynamics));
      }
    } catch (const std::exception& e) {
      std::printf("%-22s %-14s failed: %s\n", name_.c_str(),
                  std::string(hnn::WeightStorageName(storage)).c_str(), e.what());
      runs_->push_back({{"network", name_},
                        {"engine", std::string(hnn::WeightStorageName(storage))},
                        {"error", e.what()}});
      return;
    }
    std::string label(hnn::WeightStorageName(storage));
    if (storage == hnn::WeightStorage::kAuto) label += "=" + reports.back().weight_storage;
    if (reports.back().solve_loop == "device") {
      label += " (device loop x" + std::to_string(reports.back().solve_groups) + ")";
    }
    Record(label, std::move(reports));
  }

 private:
  // The decoded winners (left, column) of a solve.
  std::set<std::pair<int, int>> Winners(const hnn::SolveReport& report) const {
    const auto decoded = hnn::Decode(net_.problem, report.activation, hnn::DecodeOptions{},
                                     &report.potential);
    std::set<std::pair<int, int>> winners;
    for (const auto& m : decoded) winners.insert({m.left, m.column});
    return winners;
  }

  // Device time per command, printed under the row and as JSON.
  static nlohmann::json Profile(const std::vector<hnn::KernelTime>& kernel_times) {
    nlohmann::json commands = nlohmann::json::array();
    for (const hnn::KernelTime& t : kernel_times) {
      commands.push_back({{"command", t.command}, {"phase", t.phase}, {"count", t.count},
                          {"device_ms", t.device_ms}});
      std::printf("    %-28s %-6s %5d x %9.1f us = %8.3f ms\n", t.command.c_str(),
                  t.phase.c_str(), t.count, t.count > 0 ? 1000.0 * t.device_ms / t.count : 0.0,
                  t.device_ms);
    }
    return commands;
  }

  const hnn::CapturedNetwork& net_;
  const std::string name_;
  const perf::ReadBandwidth& bandwidth_;
  nlohmann::json* runs_;
  std::set<std::pair<int, int>> baseline_;  // the first engine's winners (left, column)
};

int Run(int argc, char** argv) {
  CLI::App app{"Replays captured Hopfield networks (hnnstereo match --save-network) on an OpenCL "
               "device: every weight storage timed, the device's read bandwidth as the roofline"};
  ReplayFlags flags;
  AddFlags(app, flags);
  CLI11_PARSE(app, argc, argv);

  ocl::DeviceSelection selection = ocl::DeviceSelection::FromEnvironment();
  if (!flags.device.empty()) selection.device = flags.device;
  std::string why_not;
  std::unique_ptr<ocl::Runtime> runtime = ocl::Runtime::Create(selection, &why_not);
  if (!runtime) throw std::runtime_error("no OpenCL device: " + why_not);
  const std::vector<hnn::WeightStorage> kinds = ParseStorages(flags.storages);

  nlohmann::json json;
  json["device"] = runtime->description();
  json["block_step"] = flags.block_step;
  json["solve_loop"] = flags.solve_loop;
  const perf::ReadBandwidth bandwidth = perf::MeasureDeviceReadBandwidth(*runtime);
  json["device_read_gbps"] = bandwidth.gbps;
  json["device_read_method"] = bandwidth.method;
  std::printf("device: %s\ndevice read bandwidth: %.1f GB/s (%s)\n", runtime->description().c_str(),
              bandwidth.gbps, bandwidth.method.c_str());
  std::printf("%-22s %-14s %8s %10s %9s %9s %5s %9s %8s %6s %14s %8s %7s\n", "network", "engine",
              "neurons", "conn", "weights", "solve", "steps", "ms/step", "GB/s", "roof",
              "energy", "matches", "agree");
  nlohmann::json runs = nlohmann::json::array();
  for (const std::string& file : flags.files) {
    const hnn::CapturedNetwork net = hnn::ParseNetwork(ReadFile(file));
    NetworkRuns network_runs(net, file.substr(file.find_last_of('/') + 1), bandwidth, &runs);
    if (flags.cpu) {
      network_runs.Record("cpu", {hnn::SolveCpu(net.problem, net.energy, net.dynamics)});
    }
    hnn::DynamicsOptions dynamics = net.dynamics;
    if (flags.time_step > 0) dynamics.time_step = flags.time_step;
    for (hnn::WeightStorage storage : kinds) {
      network_runs.Replay(*runtime, EngineOptionsFor(flags, storage), dynamics, flags.warmup,
                          flags.repeats);
    }
  }
  json["runs"] = runs;
  if (!flags.out.empty()) {
    std::ofstream file(flags.out);
    file << json.dump(2) << "\n";
    if (!file) throw std::runtime_error("cannot write '" + flags.out + "'");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hnnstereo_replay: error: %s\n", e.what());
    return 2;
  }
}
