#include "perf/camera_size_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "common/timing.h"
#include "perf/statistics.h"

namespace hnnstereo::perf {
namespace {

using common::MillisecondsSince;

// Linux: the process's peak resident set (VmHWM, kB) since the last ResetPeakResident.
double PeakResidentMb() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      double kb = 0;
      status >> kb;
      return kb / 1024.0;
    }
    status.ignore(1 << 10, '\n');
  }
  return 0.0;
}

// Writing 5 to clear_refs resets VmHWM to the current resident set (Linux 4.0+); without it the
// figure is the peak since the process started (and says so in the JSON).
bool ResetPeakResident() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  clear.flush();
  return static_cast<bool>(clear);
}

}  // namespace

std::string CameraSizeBenchOptions::Check() const {
  if (megapixels.empty()) return "camera sizes: give at least one size in megapixels";
  for (double mp : megapixels) {
    if (!(mp >= 0.01 && mp <= 50.0)) return "camera sizes must be 0.01..50 megapixels";
  }
  if (repeats < 1) return "camera sizes: repeats must be >= 1";
  if (!(max_disparity > 0.0)) return "camera sizes: max_disparity must be > 0";
  return preset.Check();
}

nlohmann::json RunCameraSizeBench(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                  const CameraSizeBenchOptions& options, ocl::Runtime* runtime) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  const int total = static_cast<int>(options.megapixels.size()) * 2 * (options.repeats + 1);
  int done = 0;
  auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(++done, total, what);
  };
  nlohmann::json rows = nlohmann::json::array();
  double fastest = 0.0, slowest = 0.0;
  for (double mp : options.megapixels) {
    const double factor = std::sqrt(mp * 1e6 / static_cast<double>(left_grey.total()));
    const cv::Size size(static_cast<int>(std::lround(left_grey.cols * factor)),
                        static_cast<int>(std::lround(left_grey.rows * factor)));
    cv::Mat left, right;
    cv::resize(left_grey, left, size, 0, 0, factor >= 1.0 ? cv::INTER_CUBIC : cv::INTER_AREA);
    cv::resize(right_grey, right, size, 0, 0, factor >= 1.0 ? cv::INTER_CUBIC : cv::INTER_AREA);
    vision::MatcherPreset preset = options.preset;
    preset.matcher.candidates.rectified = true;
    preset.matcher.candidates.max_disparity = std::ceil(options.max_disparity * factor);
    const std::string label = std::to_string(size.width) + "x" + std::to_string(size.height);

    // The whole match, as `match` runs it; the peak resident set over the timed runs.
    vision::MatchWithPreset(left, right, nullptr, preset, runtime);  // warm-up
    progress(label + " hnn");
    const bool peak_reset = ResetPeakResident();
    std::vector<double> total_ms, features_ms, candidates_ms, coarse_ms, network_ms, weights_ms,
        solve_ms, decode_ms;
    vision::MatchReport last;
    for (int r = 0; r < options.repeats; ++r) {
      last = vision::MatchWithPreset(left, right, nullptr, preset, runtime);
      const vision::TimingMs& t = last.timing_ms;
      total_ms.push_back(t.total);
      features_ms.push_back(t.features);
      candidates_ms.push_back(t.candidates);
      coarse_ms.push_back(t.coarse);
      network_ms.push_back(t.network);
      weights_ms.push_back(t.weights);
      solve_ms.push_back(t.solve);
      decode_ms.push_back(t.decode);
      progress(label + " hnn");
    }
    const double peak_mb = PeakResidentMb();

    // StereoSGBM (5 x 5, 8 paths, the same range rounded up to 16) on the same pair.
    const int num_disparities =
        static_cast<int>(std::ceil((preset.matcher.candidates.max_disparity + 1) / 16.0)) * 16;
    const int block = 5;
    cv::Ptr<cv::StereoSGBM> sgbm =
        cv::StereoSGBM::create(0, num_disparities, block, 8 * block * block, 32 * block * block);
    cv::Mat disparity;
    sgbm->compute(left, right, disparity);
    progress(label + " StereoSGBM");
    std::vector<double> sgbm_ms;
    for (int r = 0; r < options.repeats; ++r) {
      const auto start = std::chrono::steady_clock::now();
      sgbm->compute(left, right, disparity);
      sgbm_ms.push_back(MillisecondsSince(start));
      progress(label + " StereoSGBM");
    }
    const double hnn = Median(total_ms), sgbm_median = Median(sgbm_ms);
    const double per_1000 = last.n_left > 0 ? 1000.0 * hnn / last.n_left : 0.0;
    fastest = rows.empty() ? per_1000 : std::min(fastest, per_1000);
    slowest = rows.empty() ? per_1000 : std::max(slowest, per_1000);
    nlohmann::json row = {
        {"megapixels", static_cast<double>(size.area()) / 1e6},
        {"width", size.width},
        {"height", size.height},
        {"upsampling", factor},
        {"max_disparity", preset.matcher.candidates.max_disparity},
        {"n_left", last.n_left},
        {"n_neurons", last.n_neurons},
        {"n_connections", last.n_connections},
        {"n_matches", last.matches.size()},
        {"ms", hnn},
        {"stage_ms",
         {{"features", Median(features_ms)}, {"candidates", Median(candidates_ms)},
          {"coarse", Median(coarse_ms)}, {"network", Median(network_ms)},
          {"weights", Median(weights_ms)}, {"solve", Median(solve_ms)},
          {"decode", Median(decode_ms)}}},
        {"ms_per_1000_features", per_1000},
        {"stereo_sgbm_ms", sgbm_median},
        {"stereo_sgbm_num_disparities", num_disparities},
        {"x_stereo_sgbm", sgbm_median > 0 ? hnn / sgbm_median : 0.0},
        {"peak_resident_mb", peak_mb},
        {"peak_is_since_start", !peak_reset},
        {"coarse_to_fine_levels", last.coarse_to_fine.levels},
        {"memory_fit", last.memory_fit.applied}};
    rows.push_back(row);
  }
  return {{"camera_sizes", rows},
          {"ms_per_1000_features_spread", fastest > 0 ? slowest / fastest : 0.0}};
}

}  // namespace hnnstereo::perf
