#include "perf/throughput_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <stdexcept>

#include "host/opencl_engine.h"
#include "perf/device_bandwidth.h"
#include "perf/memory_bandwidth.h"
#include "perf/statistics.h"
#include "vision/stereo/candidates.h"
#include "vision/stereo/correlation.h"
#include "vision/features/features.h"
#include "common/image.h"

namespace hnnstereo::perf {
namespace {

struct Case {
  std::string name;
  int max_features;
  bool dense;
};

// Share of matches within 1 px of the ground truth (where it is known).
double Precision(const vision::MatchReport& report, const cv::Mat& disparity, double scale) {
  int known = 0, good = 0;
  for (const auto& m : report.matches) {
    const int x = static_cast<int>(std::lround(m.left.x()));
    const int y = static_cast<int>(std::lround(m.left.y()));
    if (x < 0 || y < 0 || x >= disparity.cols || y >= disparity.rows) continue;
    const double truth = disparity.at<std::uint8_t>(y, x) / scale;
    if (truth <= 0) continue;
    ++known;
    if (std::abs((m.left.x() - m.right.x()) - truth) <= 1.0) ++good;
  }
  return known ? static_cast<double>(good) / known : 0.0;
}

}  // namespace

std::string ThroughputBenchOptions::Check() const {
  if (left.empty() || right.empty()) return "bench needs a left and a right image";
  if (repeats < 1) return "repeats must be >= 1";
  if (warmup < 0) return "warmup must be >= 0";
  if (!(max_disparity > 0)) return "max_disparity must be positive";
  for (int size : sparse_sizes) {
    if (size < 0) return "problem sizes must be feature counts (0 = every feature)";
  }
  if (dense_features < 0) return "dense_features must be >= 0";
  if (engines.empty()) return "no engines to benchmark";
  return matcher.Check();
}

nlohmann::json RunThroughputBench(const ThroughputBenchOptions& options, ocl::Runtime* runtime) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  const vision::LoadedImage left = vision::LoadImage(options.left);
  const vision::LoadedImage right = vision::LoadImage(options.right);
  vision::CheckSameSize(left, right);
  cv::Mat ground_truth;
  if (!options.ground_truth.empty()) {
    ground_truth = cv::imread(options.ground_truth, cv::IMREAD_GRAYSCALE);
    if (ground_truth.empty()) {
      throw std::runtime_error("cannot read ground truth '" + options.ground_truth + "'");
    }
  }

  std::vector<Case> cases;
  for (int size : options.sparse_sizes) {
    cases.push_back({size > 0 ? "sparse-" + std::to_string(size) : std::string("sparse-all"), size,
                     false});
  }
  if (options.dense_features > 0) {
    cases.push_back({"dense-" + std::to_string(options.dense_features) + "x" +
                         std::to_string(options.dense_features),
                     options.dense_features, true});
  }
  const int per_run = options.warmup + options.repeats;
  const std::size_t n_variants =
      options.engines.size() +
      (std::count(options.engines.begin(), options.engines.end(), hnn::EngineKind::kOpenCL) > 0 &&
               !options.opencl_storages.empty()
           ? options.opencl_storages.size() - 1
           : 0);
  const int total = static_cast<int>(cases.size() * n_variants) * per_run + options.repeats + 1;
  int done = 0;
  auto progress = [&](const std::string& what) {
    ++done;
    if (options.progress) options.progress(done, total, what);
  };

  nlohmann::json json;
  json["left"] = options.left;
  json["right"] = options.right;
  json["image_size"] = {left.grey.cols, left.grey.rows};
  json["device"] = runtime ? runtime->description() : "none (opencl engine falls back to cpu)";
  json["repeats"] = options.repeats;
  json["warmup"] = options.warmup;
  json["bytes_per_second_model"] =
      "opencl: SolveReport::step_bytes per Euler step (the bytes the weight layout must read: "
      "csr 4 B a connection + 20 B a neuron; row blocks 4 or 2 B a slot pair + 4 B a block + "
      "20 B a slot + 12 B a row; on the fly 4 B a block + 32 B a slot + 12 B a row), cpu: 8 B "
      "weight + 8 B activation per "
      "connection (double), thesis engine: 4 B weight per connection visited (its row of the "
      "dense float matrix; the activation vector it multiplies stays in cache)";
  if (options.measure_bandwidth) {
    const ReadBandwidth bandwidth = MeasureReadBandwidth();
    json["machine_read_gbps"] = bandwidth.gbps;
    json["machine_read_gbps_median"] = bandwidth.median_gbps;
    json["machine_read_method"] = bandwidth.method;
  }
  // The opencl engine's roofline is the bandwidth of the memory its device reads: measured on
  // the device itself (kernels/stream_read.cl). On a GPU that is the card's memory and the
  // host probe says nothing about it; on a CPU device both probes read the same memory, and
  // the faster one is the truer limit (neither can be beaten by the solve).
  double device_gbps = 0.0;
  if (options.measure_bandwidth && runtime != nullptr) {
    try {
      const ReadBandwidth bandwidth = MeasureDeviceReadBandwidth(*runtime);
      json["device_read_gbps"] = bandwidth.gbps;
      json["device_read_gbps_median"] = bandwidth.median_gbps;
      json["device_read_method"] = bandwidth.method;
      device_gbps = bandwidth.gbps;
    } catch (const std::exception& e) {
      json["device_read_error"] = e.what();
    }
  }
  const double machine_gbps = json.value("machine_read_gbps", 0.0);
  const bool gpu_device = runtime != nullptr && runtime->is_gpu();
  const double opencl_roofline_gbps =
      gpu_device ? device_gbps : std::max(machine_gbps, device_gbps);
  if (opencl_roofline_gbps > 0) {
    json["opencl_roofline_gbps"] = opencl_roofline_gbps;
    json["opencl_roofline_basis"] =
        gpu_device ? "device_read_gbps (the GPU's own memory)"
                   : "max(machine_read_gbps, device_read_gbps) (a CPU device reads host memory)";
  }
  nlohmann::json runs = nlohmann::json::array();
  nlohmann::json dense_by_engine;

  // (engine, storage) pairs: the opencl engine once per storage asked for.
  std::vector<std::pair<hnn::EngineKind, std::optional<hnn::WeightStorage>>> variants;
  for (hnn::EngineKind engine : options.engines) {
    if (engine == hnn::EngineKind::kOpenCL && !options.opencl_storages.empty()) {
      for (hnn::WeightStorage storage : options.opencl_storages) variants.push_back({engine, storage});
    } else {
      variants.push_back({engine, std::nullopt});
    }
  }
  for (const Case& c : cases) {
    for (const auto& [engine, storage] : variants) {
      std::string label(vision::EngineName(engine));
      if (storage && options.opencl_storages.size() > 1) {
        label += ":" + std::string(hnn::WeightStorageName(*storage));
      }
      const std::string what = label + " " + c.name;
      vision::MatcherOptions matcher = options.matcher;
      matcher.engine = engine;
      if (storage) matcher.opencl.storage = *storage;
      matcher.features.max_features = c.max_features;
      matcher.candidates.rectified = true;
      matcher.candidates.max_disparity = options.max_disparity;
      matcher.candidates.dense = c.dense;
      if (c.dense) {  // the thesis's all-pairs feature-vs-feature network
        matcher.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
        matcher.candidates.zncc_peaks = false;
        matcher.candidates.subpixel_peaks = false;
      }
      nlohmann::json run;
      run["case"] = c.name;
      run["engine"] = label;
      std::vector<double> total_ms, solve_ms, weights_ms, features_ms, candidates_ms, network_ms,
          decode_ms;
      vision::MatchReport last;
      int runs_done = 0;
      try {
        for (int r = 0; r < per_run; ++r, ++runs_done) {
          if (engine == hnn::EngineKind::kThesis && r == 0) {
            // Skip the thesis engine on networks too big for its dense N x N weights.
            vision::MatcherOptions probe = matcher;
            probe.engine = hnn::EngineKind::kCpu;
            probe.dynamics.max_steps = 0;
            const auto sized = vision::MatchStereo(left.grey, right.grey, nullptr, probe, nullptr);
            if (sized.n_neurons > options.thesis_max_neurons) {
              throw std::length_error(std::to_string(sized.n_neurons) + " neurons > thesis_max_neurons " +
                                      std::to_string(options.thesis_max_neurons));
            }
            matcher.dynamics.max_updates =
                std::max(matcher.dynamics.max_updates, options.thesis_max_sweeps * sized.n_neurons);
          }
          last = vision::MatchStereo(left.grey, right.grey, nullptr, matcher, runtime);
          if (r >= options.warmup) {
            total_ms.push_back(last.timing_ms.total);
            solve_ms.push_back(last.timing_ms.solve);
            weights_ms.push_back(last.timing_ms.weights);
            features_ms.push_back(last.timing_ms.features);
            candidates_ms.push_back(last.timing_ms.candidates);
            network_ms.push_back(last.timing_ms.network);
            decode_ms.push_back(last.timing_ms.decode);
          }
          progress(what);
        }
      } catch (const std::length_error& e) {
        run["skipped"] = e.what();
        done += per_run - runs_done;
        runs.push_back(run);
        continue;
      }
      const double solve = Median(solve_ms);
      const auto connections = static_cast<double>(last.n_connections);
      const double iterations = last.solve.iterations;
      const bool thesis = engine == hnn::EngineKind::kThesis;
      // Connections visited: every connection per Euler step; n_neurons per thesis update.
      const double visited = thesis ? iterations * static_cast<double>(last.n_neurons)
                                    : iterations * connections;
      // Steps run: the energy checks are at steps 0, interval, ..., so `iterations` + 1.
      const double steps = thesis ? iterations : iterations + 1.0;
      const double step_bytes = last.solve.step_bytes > 0
                                    ? last.solve.step_bytes
                                    : connections * 16.0 + last.n_neurons * 32.0;
      // The thesis engine streams one row of its dense float matrix per update; the activations
      // (n doubles) stay in cache, as the opencl model counts V once per row. Counting 8 B of
      // activation per connection as well made it read 136-145 % of the machine's bandwidth.
      const double bytes = thesis ? visited * 4.0 : steps * step_bytes;
      run["engine_used"] = last.solve.engine;
      run["n_left"] = last.n_left;
      run["n_right"] = last.n_right;
      run["n_neurons"] = last.n_neurons;
      run["n_connections"] = last.n_connections;
      run["n_matches"] = last.matches.size();
      run["iterations"] = last.solve.iterations;
      run["converged"] = last.solve.converged;
      run["energy_initial"] = last.solve.energy_initial;
      run["energy_final"] = last.solve.energy_final;
      run["ms"] = Median(total_ms);
      run["total_ms_runs"] = total_ms;
      run["solve_ms"] = solve;
      run["weights_ms"] = Median(weights_ms);
      // Where the rest of the whole match goes (medians of each stage; they need not add up to
      // the median total).
      run["features_ms"] = Median(features_ms);
      run["candidates_ms"] = Median(candidates_ms);
      run["network_ms"] = Median(network_ms);
      run["decode_ms"] = Median(decode_ms);
      run["connections_per_second"] = solve > 0 ? visited / (solve / 1000.0) : 0.0;
      run["bytes_per_second"] = solve > 0 ? bytes / (solve / 1000.0) : 0.0;
      run["steps"] = steps;
      run["time_per_step_ms"] = steps > 0 ? solve / steps : 0.0;
      if (!thesis) run["step_bytes"] = step_bytes;
      if (!last.solve.weight_storage.empty()) {
        run["weight_storage"] = last.solve.weight_storage;
        if (!last.solve.solve_loop.empty()) run["solve_loop"] = last.solve.solve_loop;
        if (last.solve.solve_groups > 0) run["solve_groups"] = last.solve.solve_groups;
        run["launches"] = last.solve.launches;
        run["blocking_reads"] = last.solve.blocking_reads;
        run["launches_per_step"] = steps > 0 ? last.solve.launches / steps : 0.0;
        run["blocking_reads_per_step"] = steps > 0 ? last.solve.blocking_reads / steps : 0.0;
      }
      if (!last.solve.kernel_times.empty()) {
        // Where the last timed run's device time went (OpenClEngineOptions::profile): per
        // command and phase, and the solve's host gap = its wall time - its device time.
        nlohmann::json commands = nlohmann::json::array();
        double solve_device_ms = 0.0, build_device_ms = 0.0;
        for (const hnn::KernelTime& t : last.solve.kernel_times) {
          commands.push_back({{"command", t.command}, {"phase", t.phase}, {"count", t.count},
                              {"device_ms", t.device_ms},
                              {"us_each", t.count > 0 ? 1000.0 * t.device_ms / t.count : 0.0}});
          (t.phase == "solve" ? solve_device_ms : build_device_ms) += t.device_ms;
        }
        run["profile"] = {{"commands", commands},
                          {"weights_ms", last.solve.weights_ms},
                          {"build_device_ms", build_device_ms},
                          {"solve_ms", last.solve.solve_ms},
                          {"solve_device_ms", solve_device_ms},
                          {"solve_host_gap_ms", last.solve.solve_ms - solve_device_ms},
                          {"host_gap_per_step_ms",
                           steps > 0 ? (last.solve.solve_ms - solve_device_ms) / steps : 0.0}};
      }
      // The roofline of the memory this engine reads: the device's for the opencl engine, the
      // host's for the cpu and thesis engines.
      const double roofline_gbps = last.solve.engine == "opencl" ? opencl_roofline_gbps : machine_gbps;
      if (roofline_gbps > 0 && solve > 0) {
        run["roofline_gbps"] = roofline_gbps;
        run["roofline_fraction"] = bytes / (solve / 1000.0) / 1e9 / roofline_gbps;
      }
      if (!ground_truth.empty()) {
        run["precision_1px"] = Precision(last, ground_truth, options.ground_truth_scale);
      }
      if (c.dense && !dense_by_engine.contains(label)) dense_by_engine[label] = run;
      if (c.dense && engine == hnn::EngineKind::kOpenCL && !dense_by_engine.contains("opencl")) {
        dense_by_engine["opencl"] = run;
      }
      runs.push_back(run);
    }
  }
  json["runs"] = runs;

  // Many independent networks per launch: horizontal strips of the pair, one network each.
  if (options.batch_networks > 0 && runtime != nullptr) {
    hnn::ProblemBatch batch;
    const int strip = left.grey.rows / options.batch_networks;
    vision::MatcherOptions matcher = options.matcher;
    matcher.features.max_features = options.batch_features;
    matcher.candidates.rectified = true;
    matcher.candidates.max_disparity = options.max_disparity;
    matcher.candidates.dense = false;
    for (int b = 0; b < options.batch_networks && strip > 2 * options.matcher.zncc_window; ++b) {
      const cv::Rect band(0, b * strip, left.grey.cols, strip);
      const cv::Mat l = left.grey(band).clone(), r = right.grey(band).clone();
      const auto lf = vision::DetectFeatures(l, matcher.features);
      const auto rf = vision::DetectFeatures(r, matcher.features);
      if (lf.points.empty() || rf.points.empty()) continue;
      const vision::ZnccMatcher zncc(l, r, matcher.zncc_window);
      auto problem = vision::BuildCandidates(lf.points, rf.points, zncc, nullptr, matcher.candidates).problem;
      if (!problem.candidates.empty()) batch.push_back(std::move(problem));
    }
    if (!batch.empty()) {
      hnn::OpenClEngine engine(*runtime);
      std::vector<double> together_ms, apart_ms;
      long long neurons = 0, connections = 0;
      for (int r = 0; r < options.warmup + options.repeats; ++r) {
        auto start = std::chrono::steady_clock::now();
        const auto reports = engine.SolveBatch(batch, matcher.energy, matcher.dynamics,
                                               matcher.memory_budget_bytes);
        const double together =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        start = std::chrono::steady_clock::now();
        for (const auto& problem : batch) {
          engine.Solve(problem, matcher.energy, matcher.dynamics, matcher.memory_budget_bytes);
        }
        const double apart =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        if (r >= options.warmup) {
          together_ms.push_back(together);
          apart_ms.push_back(apart);
        }
        neurons = connections = 0;
        for (const auto& report : reports) {
          neurons += report.n_neurons;
          connections += report.n_connections;
        }
      }
      json["batch"] = {{"networks", batch.size()}, {"neurons", neurons}, {"connections", connections},
                       {"solve_batch_ms", Median(together_ms)},
                       {"solve_one_by_one_ms", Median(apart_ms)},
                       {"speedup", Median(together_ms) > 0 ? Median(apart_ms) / Median(together_ms) : 0.0}};
    }
  }

  // OpenCV StereoSGBM on the same pair, same disparity range, in the same run.
  {
    const int num_disparities = static_cast<int>(std::ceil((options.max_disparity + 1) / 16.0)) * 16;
    const int block = 5;
    cv::Ptr<cv::StereoSGBM> sgbm =
        cv::StereoSGBM::create(0, num_disparities, block, 8 * block * block, 32 * block * block);
    cv::Mat disparity;
    sgbm->compute(left.grey, right.grey, disparity);  // warm-up
    progress("StereoSGBM");
    std::vector<double> sgbm_ms;
    for (int r = 0; r < options.repeats; ++r) {
      const auto start = std::chrono::steady_clock::now();
      sgbm->compute(left.grey, right.grey, disparity);
      sgbm_ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
      progress("StereoSGBM");
    }
    json["stereo_sgbm"] = {{"ms", Median(sgbm_ms)}, {"num_disparities", num_disparities},
                           {"block_size", block}, {"mode", "SGBM"}};
    // Every case's whole match as a multiple of StereoSGBM's time on the same pair, same run.
    const double sgbm_median = Median(sgbm_ms);
    for (auto& run : json["runs"]) {
      if (run.contains("ms") && sgbm_median > 0) {
        run["x_stereo_sgbm"] = run["ms"].get<double>() / sgbm_median;
      }
    }
  }

  if (dense_by_engine.contains("thesis") && dense_by_engine.contains("opencl") &&
      !dense_by_engine["thesis"].contains("skipped")) {
    const auto& t = dense_by_engine["thesis"];
    const auto& o = dense_by_engine["opencl"];
    const double thesis_ms = t["weights_ms"].get<double>() + t["solve_ms"].get<double>();
    const double opencl_ms = o["weights_ms"].get<double>() + o["solve_ms"].get<double>();
    json["dense_comparison"] = {
        {"case", t["case"]},
        {"thesis_weights_plus_solve_ms", thesis_ms},
        {"opencl_weights_plus_solve_ms", opencl_ms},
        {"speedup_weights_plus_solve", opencl_ms > 0 ? thesis_ms / opencl_ms : 0.0},
        {"speedup_solve", o["solve_ms"].get<double>() > 0
                              ? t["solve_ms"].get<double>() / o["solve_ms"].get<double>() : 0.0},
        {"speedup_total", o["ms"].get<double>() > 0 ? t["ms"].get<double>() / o["ms"].get<double>() : 0.0},
        {"thesis_energy_final", t["energy_final"]},
        {"opencl_energy_final", o["energy_final"]},
        {"thesis_converged", t["converged"]},
        {"opencl_energy_not_higher",
         o["energy_final"].get<double>() <= t["energy_final"].get<double>() + 1e-6 * std::abs(t["energy_final"].get<double>())}};
  }
  return json;
}

}  // namespace hnnstereo::perf
