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

namespace {

double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// The problem sizes: one sparse case per size, then the dense case when asked for.
std::vector<Case> BuildCases(const ThroughputBenchOptions& options) {
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
  return cases;
}

// (engine, storage) pairs: the opencl engine once per storage asked for.
using Variant = std::pair<hnn::EngineKind, std::optional<hnn::WeightStorage>>;
std::vector<Variant> BuildVariants(const ThroughputBenchOptions& options) {
  std::vector<Variant> variants;
  for (hnn::EngineKind engine : options.engines) {
    if (engine == hnn::EngineKind::kOpenCL && !options.opencl_storages.empty()) {
      for (hnn::WeightStorage storage : options.opencl_storages) variants.push_back({engine, storage});
    } else {
      variants.push_back({engine, std::nullopt});
    }
  }
  return variants;
}

// Counts the bench's runs for options.progress: every case's warm-up and timed matches per
// variant, then StereoSGBM's warm-up and timed runs.
class Progress {
 public:
  Progress(const ThroughputBenchOptions& options, std::size_t n_cases)
      : options_(options), per_run_(options.warmup + options.repeats) {
    const std::size_t n_variants =
        options.engines.size() +
        (std::count(options.engines.begin(), options.engines.end(), hnn::EngineKind::kOpenCL) > 0 &&
                 !options.opencl_storages.empty()
             ? options.opencl_storages.size() - 1
             : 0);
    total_ = static_cast<int>(n_cases * n_variants) * per_run_ + options.repeats + 1;
  }
  void operator()(const std::string& what) {
    ++done_;
    if (options_.progress) options_.progress(done_, total_, what);
  }
  // A case left after `runs_done` of its runs: its remaining runs count as done.
  void Skip(int runs_done) { done_ += per_run_ - runs_done; }
  int per_run() const { return per_run_; }

 private:
  const ThroughputBenchOptions& options_;
  const int per_run_;
  int total_ = 0;
  int done_ = 0;
};

// The bench's description: the pair, the device, the repeats and the bytes-a-second model.
nlohmann::json DescribeBench(const ThroughputBenchOptions& options,
                             const vision::LoadedImage& left, const ocl::Runtime* runtime) {
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
  return json;
}

// The read bandwidths an engine's bytes a second are set against.
struct Rooflines {
  double machine_gbps = 0.0;         ///< the host's memory (cpu and thesis engines)
  double opencl_roofline_gbps = 0.0;  ///< the memory the OpenCL device reads
};

// Measures the host's and the device's read bandwidth (when asked) into `json`. The opencl
// engine's roofline is the memory its device reads: the card's on a GPU (kernels/stream_read.cl),
// on a CPU device the faster of both probes, which read the same memory (neither can be beaten
// by the solve).
Rooflines MeasureRooflines(const ThroughputBenchOptions& options, ocl::Runtime* runtime,
                           nlohmann::json* json) {
  if (options.measure_bandwidth) {
    const ReadBandwidth bandwidth = MeasureReadBandwidth();
    (*json)["machine_read_gbps"] = bandwidth.gbps;
    (*json)["machine_read_gbps_median"] = bandwidth.median_gbps;
    (*json)["machine_read_method"] = bandwidth.method;
  }
  double device_gbps = 0.0;
  if (options.measure_bandwidth && runtime != nullptr) {
    try {
      const ReadBandwidth bandwidth = MeasureDeviceReadBandwidth(*runtime);
      (*json)["device_read_gbps"] = bandwidth.gbps;
      (*json)["device_read_gbps_median"] = bandwidth.median_gbps;
      (*json)["device_read_method"] = bandwidth.method;
      device_gbps = bandwidth.gbps;
    } catch (const std::exception& e) {
      (*json)["device_read_error"] = e.what();
    }
  }
  Rooflines rooflines;
  rooflines.machine_gbps = json->value("machine_read_gbps", 0.0);
  const bool gpu_device = runtime != nullptr && runtime->is_gpu();
  rooflines.opencl_roofline_gbps =
      gpu_device ? device_gbps : std::max(rooflines.machine_gbps, device_gbps);
  if (rooflines.opencl_roofline_gbps > 0) {
    (*json)["opencl_roofline_gbps"] = rooflines.opencl_roofline_gbps;
    (*json)["opencl_roofline_basis"] =
        gpu_device ? "device_read_gbps (the GPU's own memory)"
                   : "max(machine_read_gbps, device_read_gbps) (a CPU device reads host memory)";
  }
  return rooflines;
}

// The matcher of one case and variant: the bench's options on the rectified pair, the case's
// feature count, and for the dense case the thesis's all-pairs feature-vs-feature network.
vision::MatcherOptions MatcherFor(const ThroughputBenchOptions& options, const Case& c,
                                  const Variant& variant) {
  vision::MatcherOptions matcher = options.matcher;
  matcher.engine = variant.first;
  if (variant.second) matcher.opencl.storage = *variant.second;
  matcher.features.max_features = c.max_features;
  matcher.candidates.rectified = true;
  matcher.candidates.max_disparity = options.max_disparity;
  matcher.candidates.dense = c.dense;
  if (c.dense) {
    matcher.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
    matcher.candidates.zncc_peaks = false;
    matcher.candidates.subpixel_peaks = false;
  }
  return matcher;
}

// Each stage's time in every timed match.
struct StageTimes {
  std::vector<double> total_ms, solve_ms, weights_ms, features_ms, candidates_ms, network_ms,
      decode_ms;
  void Add(const vision::MatchReport& report) {
    total_ms.push_back(report.timing_ms.total);
    solve_ms.push_back(report.timing_ms.solve);
    weights_ms.push_back(report.timing_ms.weights);
    features_ms.push_back(report.timing_ms.features);
    candidates_ms.push_back(report.timing_ms.candidates);
    network_ms.push_back(report.timing_ms.network);
    decode_ms.push_back(report.timing_ms.decode);
  }
};

// The thesis engine's limits for this network: throws std::length_error (the case is skipped)
// when its dense N x N weights would exceed thesis_max_neurons, else raises its update budget
// to thesis_max_sweeps sweeps.
void SizeThesisRun(const ThroughputBenchOptions& options, const vision::LoadedImage& left,
                   const vision::LoadedImage& right, vision::MatcherOptions* matcher) {
  vision::MatcherOptions probe = *matcher;
  probe.engine = hnn::EngineKind::kCpu;
  probe.dynamics.max_steps = 0;
  const auto sized = vision::MatchStereo(left.grey, right.grey, nullptr, probe, nullptr);
  if (sized.n_neurons > options.thesis_max_neurons) {
    throw std::length_error(std::to_string(sized.n_neurons) + " neurons > thesis_max_neurons " +
                            std::to_string(options.thesis_max_neurons));
  }
  matcher->dynamics.max_updates =
      std::max(matcher->dynamics.max_updates, options.thesis_max_sweeps * sized.n_neurons);
}

// Where the last timed run's device time went (OpenClEngineOptions::profile): per command and
// phase, and the solve's host gap = its wall time - its device time.
nlohmann::json ProfileJson(const hnn::SolveReport& solve, double steps) {
  nlohmann::json commands = nlohmann::json::array();
  double solve_device_ms = 0.0, build_device_ms = 0.0;
  for (const hnn::KernelTime& t : solve.kernel_times) {
    commands.push_back({{"command", t.command}, {"phase", t.phase}, {"count", t.count},
                        {"device_ms", t.device_ms},
                        {"us_each", t.count > 0 ? 1000.0 * t.device_ms / t.count : 0.0}});
    (t.phase == "solve" ? solve_device_ms : build_device_ms) += t.device_ms;
  }
  return {{"commands", commands},
          {"weights_ms", solve.weights_ms},
          {"build_device_ms", build_device_ms},
          {"solve_ms", solve.solve_ms},
          {"solve_device_ms", solve_device_ms},
          {"solve_host_gap_ms", solve.solve_ms - solve_device_ms},
          {"host_gap_per_step_ms", steps > 0 ? (solve.solve_ms - solve_device_ms) / steps : 0.0}};
}

// A case's figures from its last match and the medians of its timed ones: the network, the
// stages' times, connections and bytes a second and, for the opencl engine, the layout, its
// launches and reads and its profile.
nlohmann::json CaseFigures(const vision::MatchReport& last, const StageTimes& times, bool thesis,
                           double* bytes_out) {
  nlohmann::json run;
  const double solve = Median(times.solve_ms);
  const auto connections = static_cast<double>(last.n_connections);
  const double iterations = last.solve.iterations;
  // Connections visited: every connection per Euler step; n_neurons per thesis update.
  const double visited = thesis ? iterations * static_cast<double>(last.n_neurons)
                                : iterations * connections;
  // Steps run: the energy checks are at steps 0, interval, ..., so `iterations` + 1.
  const double steps = thesis ? iterations : iterations + 1.0;
  const double step_bytes = last.solve.step_bytes > 0
                                ? last.solve.step_bytes
                                : connections * 16.0 + last.n_neurons * 32.0;
  // The thesis engine streams one row of its dense float matrix per update; the activations
  // (n doubles) stay in cache, as the opencl model counts V once per row.
  const double bytes = thesis ? visited * 4.0 : steps * step_bytes;
  *bytes_out = bytes;
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
  run["ms"] = Median(times.total_ms);
  run["total_ms_runs"] = times.total_ms;
  run["solve_ms"] = solve;
  run["weights_ms"] = Median(times.weights_ms);
  // Where the rest of the whole match goes (medians of each stage; they need not add up to
  // the median total).
  run["features_ms"] = Median(times.features_ms);
  run["candidates_ms"] = Median(times.candidates_ms);
  run["network_ms"] = Median(times.network_ms);
  run["decode_ms"] = Median(times.decode_ms);
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
  if (!last.solve.kernel_times.empty()) run["profile"] = ProfileJson(last.solve, steps);
  return run;
}

// The matches of the cases: each variant on each case, warm-up then timed runs.
class CaseRunner {
 public:
  CaseRunner(const ThroughputBenchOptions& options, const vision::LoadedImage& left,
             const vision::LoadedImage& right, const cv::Mat& ground_truth,
             ocl::Runtime* runtime, const Rooflines& rooflines, Progress* progress)
      : options_(options), left_(left), right_(right), ground_truth_(ground_truth),
        runtime_(runtime), rooflines_(rooflines), progress_(progress) {}

  // Every case's run, in order; the first dense run (not skipped) of each engine label and of
  // the opencl engine into *dense_by_engine.
  nlohmann::json RunAll(const std::vector<Case>& cases, nlohmann::json* dense_by_engine) {
    nlohmann::json runs = nlohmann::json::array();
    const std::vector<Variant> variants = BuildVariants(options_);
    for (const Case& c : cases) {
      for (const Variant& variant : variants) {
        std::string label(vision::EngineName(variant.first));
        if (variant.second && options_.opencl_storages.size() > 1) {
          label += ":" + std::string(hnn::WeightStorageName(*variant.second));
        }
        const nlohmann::json run = RunCase(c, variant, label);
        runs.push_back(run);
        if (!c.dense || run.contains("skipped")) continue;
        if (!dense_by_engine->contains(label)) (*dense_by_engine)[label] = run;
        if (variant.first == hnn::EngineKind::kOpenCL && !dense_by_engine->contains("opencl")) {
          (*dense_by_engine)["opencl"] = run;
        }
      }
    }
    return runs;
  }

 private:
  nlohmann::json RunCase(const Case& c, const Variant& variant, const std::string& label) {
    const hnn::EngineKind engine = variant.first;
    const std::string what = label + " " + c.name;
    vision::MatcherOptions matcher = MatcherFor(options_, c, variant);
    nlohmann::json run;
    run["case"] = c.name;
    run["engine"] = label;
    StageTimes times;
    vision::MatchReport last;
    int runs_done = 0;
    try {
      for (int r = 0; r < progress_->per_run(); ++r, ++runs_done) {
        if (engine == hnn::EngineKind::kThesis && r == 0) {
          SizeThesisRun(options_, left_, right_, &matcher);
        }
        last = vision::MatchStereo(left_.grey, right_.grey, nullptr, matcher, runtime_);
        if (r >= options_.warmup) times.Add(last);
        (*progress_)(what);
      }
    } catch (const std::length_error& e) {
      run["skipped"] = e.what();
      progress_->Skip(runs_done);
      return run;
    }
    double bytes = 0.0;
    run.update(CaseFigures(last, times, engine == hnn::EngineKind::kThesis, &bytes));
    const double solve = Median(times.solve_ms);
    // The roofline of the memory this engine reads: the device's for the opencl engine, the
    // host's for the cpu and thesis engines.
    const double roofline_gbps = last.solve.engine == "opencl" ? rooflines_.opencl_roofline_gbps
                                                               : rooflines_.machine_gbps;
    if (roofline_gbps > 0 && solve > 0) {
      run["roofline_gbps"] = roofline_gbps;
      run["roofline_fraction"] = bytes / (solve / 1000.0) / 1e9 / roofline_gbps;
    }
    if (!ground_truth_.empty()) {
      run["precision_1px"] = Precision(last, ground_truth_, options_.ground_truth_scale);
    }
    return run;
  }

  const ThroughputBenchOptions& options_;
  const vision::LoadedImage& left_;
  const vision::LoadedImage& right_;
  const cv::Mat& ground_truth_;
  ocl::Runtime* runtime_;
  const Rooflines rooflines_;
  Progress* progress_;
};

// The batch's networks: horizontal strips of the pair, one sparse network each.
hnn::ProblemBatch BuildStripBatch(const ThroughputBenchOptions& options,
                                  const vision::LoadedImage& left,
                                  const vision::LoadedImage& right,
                                  const vision::MatcherOptions& matcher) {
  hnn::ProblemBatch batch;
  const int strip = left.grey.rows / options.batch_networks;
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
  return batch;
}

// Many independent networks per launch against one by one (null when there is no batch).
nlohmann::json BenchBatch(const ThroughputBenchOptions& options, const vision::LoadedImage& left,
                          const vision::LoadedImage& right, ocl::Runtime& runtime) {
  vision::MatcherOptions matcher = options.matcher;
  matcher.features.max_features = options.batch_features;
  matcher.candidates.rectified = true;
  matcher.candidates.max_disparity = options.max_disparity;
  matcher.candidates.dense = false;
  const hnn::ProblemBatch batch = BuildStripBatch(options, left, right, matcher);
  if (batch.empty()) return nullptr;
  hnn::OpenClEngine engine(runtime);
  std::vector<double> together_ms, apart_ms;
  long long neurons = 0, connections = 0;
  for (int r = 0; r < options.warmup + options.repeats; ++r) {
    auto start = std::chrono::steady_clock::now();
    const auto reports = engine.SolveBatch(batch, matcher.energy, matcher.dynamics,
                                           matcher.memory_budget_bytes);
    const double together = MillisecondsSince(start);
    start = std::chrono::steady_clock::now();
    for (const auto& problem : batch) {
      engine.Solve(problem, matcher.energy, matcher.dynamics, matcher.memory_budget_bytes);
    }
    const double apart = MillisecondsSince(start);
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
  return {{"networks", batch.size()}, {"neurons", neurons}, {"connections", connections},
          {"solve_batch_ms", Median(together_ms)},
          {"solve_one_by_one_ms", Median(apart_ms)},
          {"speedup", Median(together_ms) > 0 ? Median(apart_ms) / Median(together_ms) : 0.0}};
}

// OpenCV StereoSGBM on the same pair, same disparity range, in the same run; every case's whole
// match as a multiple of its time (x_stereo_sgbm).
void BenchStereoSgbm(const ThroughputBenchOptions& options, const vision::LoadedImage& left,
                     const vision::LoadedImage& right, Progress* progress, nlohmann::json* json) {
  const int num_disparities = static_cast<int>(std::ceil((options.max_disparity + 1) / 16.0)) * 16;
  const int block = 5;
  cv::Ptr<cv::StereoSGBM> sgbm =
      cv::StereoSGBM::create(0, num_disparities, block, 8 * block * block, 32 * block * block);
  cv::Mat disparity;
  sgbm->compute(left.grey, right.grey, disparity);  // warm-up
  (*progress)("StereoSGBM");
  std::vector<double> sgbm_ms;
  for (int r = 0; r < options.repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    sgbm->compute(left.grey, right.grey, disparity);
    sgbm_ms.push_back(MillisecondsSince(start));
    (*progress)("StereoSGBM");
  }
  (*json)["stereo_sgbm"] = {{"ms", Median(sgbm_ms)}, {"num_disparities", num_disparities},
                            {"block_size", block}, {"mode", "SGBM"}};
  const double sgbm_median = Median(sgbm_ms);
  for (auto& run : (*json)["runs"]) {
    if (run.contains("ms") && sgbm_median > 0) {
      run["x_stereo_sgbm"] = run["ms"].get<double>() / sgbm_median;
    }
  }
}

// The thesis engine against the opencl engine on the dense case (null unless both ran).
nlohmann::json DenseComparison(nlohmann::json& dense_by_engine) {
  if (!dense_by_engine.contains("thesis") || !dense_by_engine.contains("opencl") ||
      dense_by_engine["thesis"].contains("skipped")) {
    return nullptr;
  }
  const auto& t = dense_by_engine["thesis"];
  const auto& o = dense_by_engine["opencl"];
  const double thesis_ms = t["weights_ms"].get<double>() + t["solve_ms"].get<double>();
  const double opencl_ms = o["weights_ms"].get<double>() + o["solve_ms"].get<double>();
  return {
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

}  // namespace

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
  const std::vector<Case> cases = BuildCases(options);
  Progress progress(options, cases.size());
  nlohmann::json json = DescribeBench(options, left, runtime);
  const Rooflines rooflines = MeasureRooflines(options, runtime, &json);
  nlohmann::json dense_by_engine;
  json["runs"] = CaseRunner(options, left, right, ground_truth, runtime, rooflines, &progress)
                     .RunAll(cases, &dense_by_engine);
  if (options.batch_networks > 0 && runtime != nullptr) {
    nlohmann::json batch = BenchBatch(options, left, right, *runtime);
    if (!batch.is_null()) json["batch"] = std::move(batch);
  }
  BenchStereoSgbm(options, left, right, &progress, &json);
  nlohmann::json comparison = DenseComparison(dense_by_engine);
  if (!comparison.is_null()) json["dense_comparison"] = std::move(comparison);
  return json;
}

}  // namespace hnnstereo::perf
