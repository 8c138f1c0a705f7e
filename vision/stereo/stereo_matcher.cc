#include "vision/stereo/stereo_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <initializer_list>
#include <stdexcept>


#include "host/cpu_engines.h"
#include "host/opencl_engine.h"
#include "vision/stereo/correlation.h"
#include "common/timing.h"

namespace hnnstereo::vision {
namespace {

using Clock = std::chrono::steady_clock;
using common::MillisecondsSince;

}  // namespace

std::string_view EngineName(hnn::EngineKind engine) {
  switch (engine) {
    case hnn::EngineKind::kThesis: return "thesis";
    case hnn::EngineKind::kCpu: return "cpu";
    case hnn::EngineKind::kOpenCL: return "opencl";
  }
  return "unknown";
}

std::optional<hnn::EngineKind> ParseEngine(std::string_view name) {
  if (name == "thesis") return hnn::EngineKind::kThesis;
  if (name == "cpu") return hnn::EngineKind::kCpu;
  if (name == "opencl") return hnn::EngineKind::kOpenCL;
  return std::nullopt;
}

std::string ConfidenceOptions::Check() const {
  for (double v : {bias, w_potential_margin, w_correlation, w_correlation_margin, w_surface_residual}) {
    if (!std::isfinite(v)) return "confidence weights must be finite";
  }
  for (std::size_t r = 0; r < kAgreementRadiiPx.size(); ++r) {
    if (!std::isfinite(w_agreement[r]) || !std::isfinite(w_neighbours[r])) {
      return "confidence weights must be finite";
    }
  }
  if (!(potential_margin_cap > 0.0 && std::isfinite(potential_margin_cap))) {
    return "confidence potential_margin_cap must be > 0";
  }
  return {};
}

ConfidenceOptions CensusConfidenceOptions() {
  // scripts/fit_confidence.py on hnn-default's matches (census 5 x 5 / 13 x 13 / gamma 20,
  // K = 3, 14 px support), pooled over the tuning part of the development set (scripts/dev_set.py:
  // real pairs, their variants and rendered scenes; docs/accuracy.md, "Confidence"). The
  // neighbour counts at 12 and 24 px weigh 0: they measure how textured the scene is, not
  // whether a match is right (a repeated facade is dense and wrong); the counts at 3 and 6 px
  // (edge continuity) stay. The agreement at 3 and 6 px weighs 0: it adds nothing to the wider
  // rings' once those are in the fit.
  ConfidenceOptions o;
  o.bias = -3.53623;
  o.w_potential_margin = 0.0;
  o.w_correlation = 1.01829;
  o.w_correlation_margin = 5.5536;
  o.w_agreement = {0.0, 0.0, 1.23892, 2.11234};
  o.w_neighbours = {0.0676583, 0.0322522, 0.0, 0.0};
  o.w_surface_residual = 0.0;
  return o;
}

ConfidenceOptions ConfidenceOptionsFor(const DataTermOptions& data_term) {
  return data_term.kind == DataTermOptions::Kind::kCensus ? CensusConfidenceOptions()
                                                          : ConfidenceOptions{};
}

float MatchConfidence(const StereoMatch& match, const ConfidenceOptions& options) {
  const double margin = std::min<double>(match.potential_margin, options.potential_margin_cap);
  double z = options.bias + options.w_potential_margin * margin +
             options.w_correlation * match.correlation +
             options.w_correlation_margin * match.correlation_margin;
  for (std::size_t r = 0; r < kAgreementRadiiPx.size(); ++r) {
    const double agreement =
        match.neighbours[r] > 0 ? static_cast<double>(match.agreeing[r]) / match.neighbours[r] : 0.0;
    z += options.w_agreement[r] * agreement + options.w_neighbours[r] * match.neighbours[r];
  }
  z += options.w_surface_residual * match.surface_residual;
  return static_cast<float>(1.0 / (1.0 + std::exp(-z)));
}

std::string MatcherOptions::Check() const {
  if (auto e = confidence.Check(); !e.empty()) return e;
  if (!(min_confidence >= 0.0 && min_confidence <= 1.0)) {
    return "min_confidence must be in [0, 1] (got " + std::to_string(min_confidence) + ")";
  }
  if (auto e = features.Check(); !e.empty()) return e;
  if (auto e = candidates.Check(); !e.empty()) return e;
  if (auto e = energy.Check(); !e.empty()) return e;
  if (auto e = dynamics.Check(); !e.empty()) return e;
  if (zncc_window < 3 || zncc_window > 15 || zncc_window % 2 == 0) {
    return "zncc_window must be odd, 3..15 (got " + std::to_string(zncc_window) + ")";
  }
  if (auto e = data_term.Check(); !e.empty()) return e;
  if (auto e = coarse_to_fine.Check(); !e.empty()) return e;
  if (!(decode.threshold >= 0.0 && decode.threshold <= 1.0)) return "decode threshold must be in [0, 1]";
  return {};
}

namespace {

// The two images' features, detected side by side on OpenCV's thread pool (a detector's own
// parallel loops then run serially inside). An exception in either is carried out of the pool
// and rethrown here, left image first.
void DetectBothFeatures(const cv::Mat& left_grey, const cv::Mat& right_grey,
                        const FeatureOptions& options, FeatureReport* left, FeatureReport* right) {
  std::exception_ptr failed[2];
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& range) {
    for (int side = range.start; side < range.end; ++side) {
      try {
        *(side == 0 ? left : right) = DetectFeatures(side == 0 ? left_grey : right_grey, options);
      } catch (...) {
        failed[side] = std::current_exception();
      }
    }
  });
  for (const std::exception_ptr& error : failed) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace

hnn::SolveReport SolveMatchingNetwork(const hnn::MatchingProblem& problem, const MatcherOptions& options,
                              ocl::Runtime* runtime, std::string* engine_notice) {
  hnn::EngineKind engine = options.engine;
  if (engine == hnn::EngineKind::kOpenCL && runtime == nullptr) {
    engine = hnn::EngineKind::kCpu;
    *engine_notice = "no OpenCL device available: using the cpu engine";
  }
  switch (engine) {
    case hnn::EngineKind::kThesis:
      return hnn::SolveThesis(problem, options.energy, options.dynamics, options.memory_budget_bytes);
    case hnn::EngineKind::kCpu:
      return hnn::SolveCpu(problem, options.energy, options.dynamics, options.memory_budget_bytes);
    case hnn::EngineKind::kOpenCL: {
      hnn::OpenClEngine opencl(*runtime, options.opencl);
      return opencl.Solve(problem, options.energy, options.dynamics, options.memory_budget_bytes);
    }
  }
  return {};
}

namespace {

// Keeps about `share` of the left features (and their bands), evenly spread: the detectors
// list features in raster order, so every k-th of the list is spread over the image.
void KeepEvenlySpread(double share, std::vector<Eigen::Vector2f>* points,
                      std::initializer_list<std::vector<DisparityBand>*> band_lists) {
  share = std::clamp(share, 0.0, 1.0);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < points->size(); ++i) {
    if (std::floor(static_cast<double>(i + 1) * share) == std::floor(static_cast<double>(i) * share)) {
      continue;
    }
    (*points)[kept] = (*points)[i];
    for (std::vector<DisparityBand>* bands : band_lists) {
      if (!bands->empty()) (*bands)[kept] = (*bands)[i];
    }
    ++kept;
  }
  points->resize(kept);
  for (std::vector<DisparityBand>* bands : band_lists) {
    if (!bands->empty()) bands->resize(kept);
  }
}

}  // namespace

// A winner alone in its row is measured against a neuron held off by its inhibition (u = -2B)
// and a correlation of -1.
std::vector<StereoMatch> MatchesWithMargins(const hnn::MatchingProblem& problem,
                                            const std::vector<hnn::DecodedMatch>& decoded,
                                            const std::vector<double>& u, double B) {
  std::vector<StereoMatch> matches;
  matches.reserve(decoded.size());
  // Row ranges of the candidates (sorted by left feature).
  std::vector<int> row_start(static_cast<std::size_t>(problem.n_left()) + 1, 0);
  for (const hnn::Candidate& c : problem.candidates) ++row_start[static_cast<std::size_t>(c.left) + 1];
  for (std::size_t i = 1; i < row_start.size(); ++i) row_start[i] += row_start[i - 1];
  const double lone_potential = -2.0 * B;
  for (const hnn::DecodedMatch& m : decoded) {
    const hnn::Candidate& c = problem.candidates[static_cast<std::size_t>(m.neuron)];
    StereoMatch match{problem.left_points[static_cast<std::size_t>(c.left)], c.right_point,
                      static_cast<float>(m.activation), c.left, c.column};
    double other_u = lone_potential;
    float other_correlation = -1.0f;
    bool has_other = false;
    for (int b = row_start[static_cast<std::size_t>(c.left)];
         b < row_start[static_cast<std::size_t>(c.left) + 1]; ++b) {
      if (b == m.neuron) continue;
      const auto ub = static_cast<std::size_t>(b);
      other_u = has_other ? std::max(other_u, u.empty() ? 0.0 : u[ub])
                          : (u.empty() ? 0.0 : u[ub]);
      other_correlation = std::max(other_correlation, problem.candidates[ub].correlation);
      has_other = true;
    }
    const double own_u = u.empty() ? 0.0 : u[static_cast<std::size_t>(m.neuron)];
    match.potential_margin = static_cast<float>(own_u - other_u);
    match.correlation = c.correlation;
    match.correlation_margin = c.correlation - other_correlation;
    matches.push_back(match);
  }
  return matches;
}

MatchReport MatchStereo(const cv::Mat& left_grey, const cv::Mat& right_grey,
                        const calib::StereoCalibration* calibration, const MatcherOptions& options,
                        ocl::Runtime* runtime) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  if (left_grey.size() != right_grey.size()) {
    throw std::invalid_argument("left and right images differ in size");
  }
  MatchReport report;
  const auto total_start = Clock::now();

  auto start = Clock::now();
  FeatureReport left, right;
  DetectBothFeatures(left_grey, right_grey, options.features, &left, &right);
  report.timing_ms.features = MillisecondsSince(start);
  report.left_features = left.points;
  report.right_features = right.points;
  report.n_left = static_cast<int>(left.points.size());
  report.n_right = static_cast<int>(right.points.size());
  if (left.points.empty() || right.points.empty()) {
    throw std::runtime_error("no features found (" + std::to_string(report.n_left) + " left, " +
                             std::to_string(report.n_right) +
                             " right); lower the detector thresholds or use another --features");
  }

  start = Clock::now();
  if (CoarseToFineApplies(options, left_grey.size())) {
    CoarseBands bands = CoarseDisparityBands(left_grey, right_grey, left.points, options, runtime,
                                             &report.coarse_to_fine);
    report.disparity_bands = std::move(bands.search);
    report.check_bands = std::move(bands.check);
    report.timing_ms.coarse = report.coarse_to_fine.ms;
  }
  report.similarity = std::make_shared<const ZnccMatcher>(left_grey, right_grey,
                                                          options.zncc_window, options.data_term);
  // The network over every left feature; over an evenly spread share of them when it would not
  // fit the memory budget (fit_memory_budget).
  std::vector<Eigen::Vector2f> network_left = left.points;
  CandidateReport candidates;
  for (int attempt = 0;; ++attempt) {
    const auto candidates_start = Clock::now();
    candidates = BuildCandidates(network_left, right.points, *report.similarity, calibration,
                                 options.candidates, report.disparity_bands);
    report.timing_ms.candidates += MillisecondsSince(attempt == 0 ? start : candidates_start);
    const hnn::MatchingProblem& problem = candidates.problem;
    report.n_neurons = problem.n_neurons();
    if (problem.candidates.empty()) {
      throw std::runtime_error("no candidate matches passed the gating (" +
                               std::to_string(candidates.pairs_tested) +
                               " pairs tested); widen --max-disparity or the epipolar distance");
    }
    if (options.network_observer) options.network_observer(problem, options.energy, options.dynamics);
    try {
      report.solve = SolveMatchingNetwork(problem, options, runtime, &report.engine_notice);
      break;
    } catch (const hnn::MemoryBudgetExceeded& over) {
      if (!options.fit_memory_budget || options.candidates.dense || attempt == 3) throw;
      // Connections grow about as the square of the features per area: keep a share that
      // should need 80 % of the budget.
      const double share = 0.8 * std::sqrt(static_cast<double>(over.budget_bytes) /
                                            static_cast<double>(over.needed_bytes));
      report.memory_fit.applied = true;
      report.memory_fit.needed_bytes = std::max(report.memory_fit.needed_bytes, over.needed_bytes);
      KeepEvenlySpread(share, &network_left, {&report.disparity_bands, &report.check_bands});
      report.memory_fit.left_features_matched = static_cast<int>(network_left.size());
    }
  }
  const hnn::MatchingProblem& problem = candidates.problem;
  report.n_connections = report.solve.n_connections;
  report.timing_ms.network = report.solve.network_ms;
  report.timing_ms.weights = report.solve.weights_ms;
  report.timing_ms.solve = report.solve.solve_ms;

  start = Clock::now();
  const std::vector<hnn::DecodedMatch> decoded =
      hnn::Decode(problem, report.solve.activation, options.decode, &report.solve.potential);
  report.matches = MatchesWithMargins(problem, decoded, report.solve.potential, options.energy.B);
  // The neighbourhood votes count every decoded winner, before any is dropped by confidence. A
  // coarse-to-fine pair counts them in the pixels of its coarsest level, so that the radii and the
  // 1 px agreement cover the same part of the scene as on the pairs the model was fitted on.
  CountAgreeingNeighbours(report.matches,
                          std::ldexp(1.0f, -report.coarse_to_fine.levels));
  for (StereoMatch& match : report.matches) match.confidence = MatchConfidence(match, options.confidence);
  if (options.min_confidence > 0.0) {
    std::erase_if(report.matches, [&](const StereoMatch& match) {
      return match.confidence < options.min_confidence;
    });
  }
  report.timing_ms.decode = MillisecondsSince(start);
  report.timing_ms.total = MillisecondsSince(total_start);
  return report;
}

}  // namespace hnnstereo::vision
