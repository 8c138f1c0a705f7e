#include "vision/stereo/match_io.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>

#include "common/image.h"

namespace hnnstereo::vision {

std::string MatchesCsv(const MatchReport& report) {
  std::string text = "xl,yl,xr,yr,activation,confidence\n";
  char line[160];
  for (const StereoMatch& m : report.matches) {
    std::snprintf(line, sizeof(line), "%.3f,%.3f,%.3f,%.3f,%.6f,%.6f\n", m.left.x(), m.left.y(),
                  m.right.x(), m.right.y(), m.activation, m.confidence);
    text += line;
  }
  return text;
}

nlohmann::json DataTermJson(const MatcherOptions& options) {
  if (options.data_term.kind == DataTermOptions::Kind::kCensus) {
    return {{"kind", DataTermKindName(options.data_term.kind)},
            {"census_window", options.data_term.census_window},
            {"aggregation_window", options.data_term.aggregation_window},
            {"support_gamma", options.data_term.support_gamma}};
  }
  return {{"kind", DataTermKindName(options.data_term.kind)}, {"zncc_window", options.zncc_window}};
}

nlohmann::json MatchReportJson(const MatchReport& report, const MatcherOptions& options) {
  nlohmann::json json;
  json["engine"] = report.solve.engine;
  json["device"] = report.solve.device;
  if (!report.engine_notice.empty()) json["engine_notice"] = report.engine_notice;
  json["features"] = FeatureDetectorName(options.features.detector);
  json["n_left"] = report.n_left;
  json["n_right"] = report.n_right;
  json["n_neurons"] = report.n_neurons;
  json["n_connections"] = report.n_connections;
  json["n_matches"] = report.matches.size();
  json["iterations"] = report.solve.iterations;
  json["converged"] = report.solve.converged;
  json["termination"] = report.solve.termination;
  json["energy_initial"] = report.solve.energy_initial;
  json["energy_final"] = report.solve.energy_final;
  json["energy_trace"] = {{"iteration", report.solve.energy_trace_iterations.size() > 2000
                                            ? std::vector<int>{}
                                            : report.solve.energy_trace_iterations},
                          {"energy", report.solve.energy_trace.size() > 2000
                                         ? std::vector<double>{}
                                         : report.solve.energy_trace}};
  json["timing_ms"] = {{"features", report.timing_ms.features},
                       {"candidates", report.timing_ms.candidates},
                       {"network", report.timing_ms.network},
                       {"weights", report.timing_ms.weights},
                       {"solve", report.timing_ms.solve},
                       {"decode", report.timing_ms.decode},
                       {"total", report.timing_ms.total}};
  if (report.memory_fit.applied) {
    json["memory_fit"] = {{"needed_bytes", report.memory_fit.needed_bytes},
                          {"budget_bytes", options.memory_budget_bytes},
                          {"left_features_matched", report.memory_fit.left_features_matched}};
  }
  if (report.second_chance.applied) {
    const SecondChanceReport& s = report.second_chance;
    json["timing_ms"]["second_chance"] = report.timing_ms.second_chance;
    json["second_chance"] = {{"unmatched", s.unmatched}, {"retried", s.retried},
                             {"support", s.support},     {"neurons", s.neurons},
                             {"matched", s.matched},     {"over_memory_budget", s.over_memory_budget},
                             {"engine", s.engine}};
  }
  if (report.coarse_to_fine.applied) {
    const CoarseToFineReport& c = report.coarse_to_fine;
    json["timing_ms"]["coarse"] = report.timing_ms.coarse;
    json["coarse_to_fine"] = {{"levels", c.levels},
                              {"coarse_width", c.coarse_size.width},
                              {"coarse_height", c.coarse_size.height},
                              {"coarse_matches", c.coarse_matches},
                              {"mean_band_levels", c.mean_band_levels},
                              {"features_whole_range", c.features_whole_range}};
  }
  const auto& e = options.energy;
  json["energy_options"] = {{"A", e.A}, {"B", e.B}, {"C", e.C}, {"D", e.D}, {"W1", e.W1},
                            {"W2", e.W2}, {"T", e.T}, {"lambda", e.lambda}, {"theta", e.theta},
                            {"objective", hnn::ObjectiveName(e.objective)},
                            {"support_radius_px", e.support_radius_px}};
  const auto& d = options.dynamics;
  json["dynamics_options"] = {{"alpha", d.alpha}, {"time_step", d.time_step}, {"tau", d.tau},
                              {"max_steps", d.max_steps},
                              {"stop_rule", hnn::StopRuleName(d.stop_rule)},
                              {"check_interval", d.energy_interval},
                              {"initial_state", hnn::InitialStateName(d.initial_state)},
                              {"activation", hnn::ActivationName(d.activation)}};
  json["candidate_options"] = {{"rectified", options.candidates.rectified},
                               {"network", hnn::NetworkKindName(options.candidates.kind)},
                               {"zncc_peaks", options.candidates.zncc_peaks},
                               {"dense", options.candidates.dense},
                               {"top_k", options.candidates.top_k},
                               {"min_disparity", options.candidates.min_disparity},
                               {"max_disparity", options.candidates.max_disparity},
                               {"max_epipolar_distance_px",
                                options.candidates.max_epipolar_distance_px}};
  json["data_term"] = DataTermJson(options);
  json["decode"] = hnn::DecodeMethodName(options.decode.method);
  json["weight_storage"] = report.solve.weight_storage.empty()
                               ? std::string(hnn::WeightStorageName(options.opencl.storage))
                               : report.solve.weight_storage;
  // Where the opencl row-block solve looped: "host" or "device" (one launch; docs/engine.md),
  // and the device loop's work-groups.
  if (!report.solve.solve_loop.empty()) json["solve_loop"] = report.solve.solve_loop;
  if (report.solve.solve_groups > 0) json["solve_groups"] = report.solve.solve_groups;
  json["min_confidence"] = options.min_confidence;
  const auto& c = options.confidence;
  json["confidence_options"] = {{"bias", c.bias},
                                {"w_potential_margin", c.w_potential_margin},
                                {"w_correlation", c.w_correlation},
                                {"w_correlation_margin", c.w_correlation_margin},
                                {"w_agreement", c.w_agreement},
                                {"w_neighbours", c.w_neighbours},
                                {"w_surface_residual", c.w_surface_residual},
                                {"agreement_radii_px", kAgreementRadiiPx},
                                {"agreement_slope", kAgreementSlope},
                                {"surface_radius_px", kSurfaceRadiusPx},
                                {"potential_margin_cap", c.potential_margin_cap}};
  return json;
}

nlohmann::json MatchFeaturesJson(const MatchReport& report) {
  // One row per match, columns named once (compact for ~10^5 matches).
  nlohmann::json rows = nlohmann::json::array();
  for (const StereoMatch& m : report.matches) {
    rows.push_back({m.left.x(), m.left.y(), m.right.x(), m.right.y(), m.activation, m.confidence,
                    m.potential_margin, m.correlation, m.correlation_margin, m.neighbours[0],
                    m.agreeing[0], m.neighbours[1], m.agreeing[1], m.neighbours[2], m.agreeing[2],
                    m.neighbours[3], m.agreeing[3], m.surface_residual, m.second_chance ? 1 : 0});
  }
  return {{"columns", {"xl", "yl", "xr", "yr", "activation", "confidence", "potential_margin",
                       "correlation", "correlation_margin", "neighbours_3", "agreeing_3",
                       "neighbours_6", "agreeing_6", "neighbours_12", "agreeing_12",
                       "neighbours_24", "agreeing_24", "surface_residual", "second_chance"}},
          {"rows", std::move(rows)}};
}

cv::Mat SparseDisparityMap(const MatchReport& report, int rows, int cols) {
  cv::Mat disparity(rows, cols, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (const auto& match : report.matches) {
    const int x = static_cast<int>(std::lround(match.left.x()));
    const int y = static_cast<int>(std::lround(match.left.y()));
    if (x < 0 || y < 0 || x >= cols || y >= rows) continue;
    disparity.at<float>(y, x) = match.left.x() - match.right.x();
  }
  return disparity;
}

void WriteDisparityMap(const std::string& path, const cv::Mat& disparity) {
  const std::string extension = std::filesystem::path(path).extension().string();
  if (extension == ".pfm") {
    WritePngAtomically(path, disparity);  // OpenCV picks the format by the extension
    return;
  }
  if (extension != ".png") {
    throw std::invalid_argument("disparity map '" + path + "': use .pfm (float) or .png (16-bit, "
                                "KITTI scaling)");
  }
  // KITTI devkit: disparity = png / 256.0, 0 = invalid.
  cv::Mat scaled(disparity.size(), CV_16U, cv::Scalar(0));
  for (int y = 0; y < disparity.rows; ++y) {
    for (int x = 0; x < disparity.cols; ++x) {
      const float d = disparity.at<float>(y, x);
      if (d > 0.0f && d * 256.0f <= 65535.0f) {
        scaled.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(std::lround(d * 256.0f));
      }
    }
  }
  WritePngAtomically(path, scaled);
}

}  // namespace hnnstereo::vision
