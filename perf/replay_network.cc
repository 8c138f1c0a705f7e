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

int Run(int argc, char** argv) {
  CLI::App app{"Replays captured Hopfield networks (hnnstereo match --save-network) on an OpenCL "
               "device: every weight storage timed, the device's read bandwidth as the roofline"};
  std::vector<std::string> files;
  std::vector<std::string> storages = {"csr", "blocked-float", "blocked-half", "on-the-fly"};
  std::string device, out;
  std::string block_step = "auto", solve_loop = "auto";
  int repeats = 5, warmup = 1, rows_per_item = 0, loop_groups = 0;
  double time_step = 0.0;
  bool cpu = false, profile = false;
  app.add_option("networks", files, "Network files (HNNET1)")->required();
  app.add_option("--storages", storages, "Weight storages of the opencl engine, comma-separated")
      ->delimiter(',');
  app.add_option("--repeats", repeats, "Timed solves per case (median reported)")->check(CLI::Range(1, 1000));
  app.add_option("--warmup", warmup, "Untimed solves first (kernel compilation)")->check(CLI::Range(0, 100));
  app.add_flag("--cpu", cpu, "Also the cpu reference engine (one timed solve), the winners' baseline");
  app.add_option("--device", device, "OpenCL device: index or name substring (default: the first GPU)");
  app.add_flag("--profile", profile, "Device time per kernel (OpenCL profiling events)");
  app.add_option("--time-step", time_step,
                 "Override the captured Euler step dt of the opencl runs (0 = as captured); the "
                 "agree column then compares with the first engine's winners at the captured dt")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--rows-per-item", rows_per_item,
                 "Row blocks, per-item step: rows per work-item (0 = the engine's choice)")
      ->check(CLI::Range(0, 1 << 20));
  app.add_option("--block-step", block_step,
                 "Row blocks' step: auto (a work-group per row on a GPU), item (runs of rows per "
                 "work-item) or group (a work-group of lanes per row)")
      ->check(CLI::IsMember({"auto", "item", "group"}));
  app.add_option("--solve-loop", solve_loop,
                 "Row blocks' solve loop: auto (on the device for one small network on a CPU "
                 "device), host (a launch per step) or device (the whole loop in one launch)")
      ->check(CLI::IsMember({"auto", "host", "device"}));
  app.add_option("--loop-groups", loop_groups,
                 "Device solve loop: work-groups (threads) that take the ranges of rows of each "
                 "step (0 = one per compute unit on a CPU device, one on a GPU)")
      ->check(CLI::Range(0, 1024));
  app.add_option("--out", out, "JSON output");
  CLI11_PARSE(app, argc, argv);

  ocl::DeviceSelection selection = ocl::DeviceSelection::FromEnvironment();
  if (!device.empty()) selection.device = device;
  std::string why_not;
  std::unique_ptr<ocl::Runtime> runtime = ocl::Runtime::Create(selection, &why_not);
  if (!runtime) throw std::runtime_error("no OpenCL device: " + why_not);
  std::vector<hnn::WeightStorage> kinds;
  for (const std::string& name : storages) {
    auto storage = hnn::ParseWeightStorage(name);
    if (!storage) throw std::invalid_argument("--storages: unknown storage '" + name + "'");
    kinds.push_back(*storage);
  }

  nlohmann::json json;
  json["device"] = runtime->description();
  json["block_step"] = block_step;
  json["solve_loop"] = solve_loop;
  const perf::ReadBandwidth bandwidth = perf::MeasureDeviceReadBandwidth(*runtime);
  json["device_read_gbps"] = bandwidth.gbps;
  json["device_read_method"] = bandwidth.method;
  std::printf("device: %s\ndevice read bandwidth: %.1f GB/s (%s)\n", runtime->description().c_str(),
              bandwidth.gbps, bandwidth.method.c_str());
  std::printf("%-22s %-14s %8s %10s %9s %9s %5s %9s %8s %6s %14s %8s %7s\n", "network", "engine",
              "neurons", "conn", "weights", "solve", "steps", "ms/step", "GB/s", "roof",
              "energy", "matches", "agree");
  nlohmann::json runs = nlohmann::json::array();
  for (const std::string& file : files) {
    const hnn::CapturedNetwork net = hnn::ParseNetwork(ReadFile(file));
    const std::string name = file.substr(file.find_last_of('/') + 1);
    std::set<std::pair<int, int>> baseline;  // the first engine's winners (left, column)
    auto record = [&](const std::string& engine, std::vector<hnn::SolveReport> reports) {
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
      const auto decoded = hnn::Decode(net.problem, last.activation, hnn::DecodeOptions{},
                                       &last.potential);
      std::set<std::pair<int, int>> winners;
      for (const auto& m : decoded) winners.insert({m.left, m.column});
      if (baseline.empty()) baseline = winners;
      std::size_t same = 0;
      for (const auto& w : winners) same += baseline.count(w);
      const double agree = baseline.empty() ? 1.0
                                            : static_cast<double>(same) /
                                                  static_cast<double>(std::max(winners.size(), baseline.size()));
      const bool on_device = last.engine == "opencl";
      const double roof = on_device && bandwidth.gbps > 0 ? gbps / bandwidth.gbps : 0.0;
      std::printf("%-22s %-14s %8d %10lld %9.2f %9.2f %5.0f %9.3f %8.1f %5.0f%% %14.2f %8zu %6.1f%%\n",
                  name.c_str(), engine.c_str(), last.n_neurons,
                  static_cast<long long>(last.n_connections), Median(weights), solve_ms, steps,
                  solve_ms / steps, gbps, 100.0 * roof, last.energy_final, winners.size(),
                  100.0 * agree);
      nlohmann::json run = {{"network", name},
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
      if (!last.kernel_times.empty()) {
        nlohmann::json commands = nlohmann::json::array();
        for (const hnn::KernelTime& t : last.kernel_times) {
          commands.push_back({{"command", t.command}, {"phase", t.phase}, {"count", t.count},
                              {"device_ms", t.device_ms}});
          std::printf("    %-28s %-6s %5d x %9.1f us = %8.3f ms\n", t.command.c_str(),
                      t.phase.c_str(), t.count, t.count > 0 ? 1000.0 * t.device_ms / t.count : 0.0,
                      t.device_ms);
        }
        run["profile"] = commands;
      }
      runs.push_back(run);
    };
    if (cpu) {
      record("cpu", {hnn::SolveCpu(net.problem, net.energy, net.dynamics)});
    }
    hnn::DynamicsOptions dynamics = net.dynamics;
    if (time_step > 0) dynamics.time_step = time_step;
    for (hnn::WeightStorage storage : kinds) {
      hnn::OpenClEngineOptions options;
      options.storage = storage;
      options.profile = profile;
      options.rows_per_item = rows_per_item;
      options.block_step = block_step == "item"    ? hnn::OpenClEngineOptions::BlockStep::kRowPerItem
                           : block_step == "group" ? hnn::OpenClEngineOptions::BlockStep::kRowPerGroup
                                                   : hnn::OpenClEngineOptions::BlockStep::kAuto;
      options.solve_loop = *hnn::ParseSolveLoop(solve_loop);  // checked by the flag
      options.resident_groups = loop_groups;
      hnn::OpenClEngine engine(*runtime, options);
      std::vector<hnn::SolveReport> reports;
      try {
        for (int r = 0; r < warmup; ++r) engine.Solve(net.problem, net.energy, dynamics);
        for (int r = 0; r < repeats; ++r) {
          reports.push_back(engine.Solve(net.problem, net.energy, dynamics));
        }
      } catch (const std::exception& e) {
        std::printf("%-22s %-14s failed: %s\n", name.c_str(),
                    std::string(hnn::WeightStorageName(storage)).c_str(), e.what());
        runs.push_back({{"network", name}, {"engine", std::string(hnn::WeightStorageName(storage))},
                        {"error", e.what()}});
        continue;
      }
      std::string label(hnn::WeightStorageName(storage));
      if (storage == hnn::WeightStorage::kAuto) label += "=" + reports.back().weight_storage;
      if (reports.back().solve_loop == "device") {
        label += " (device loop x" + std::to_string(reports.back().solve_groups) + ")";
      }
      record(label, std::move(reports));
    }
  }
  json["runs"] = runs;
  if (!out.empty()) {
    std::ofstream file(out);
    file << json.dump(2) << "\n";
    if (!file) throw std::runtime_error("cannot write '" + out + "'");
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
