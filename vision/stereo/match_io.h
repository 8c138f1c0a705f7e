#pragma once
// The match command's files (ARCHITECTURE.md): MATCHES.csv and REPORT.json.

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

/// "xl,yl,xr,yr,activation,confidence" then one row per match (0-based pixel coordinates).
std::string MatchesCsv(const MatchReport& report);

/// The REPORT.json object: engine, device, sizes, iterations, energies, timing_ms and the
/// options; not the matches (MATCHES.csv holds them).
nlohmann::json MatchReportJson(const MatchReport& report, const MatcherOptions& options);

/// Every match with the features its confidence is computed from (`match --report-matches`,
/// read by scripts/fit_confidence.py): {"columns": [names], "rows": [[values], ...]}.
nlohmann::json MatchFeaturesJson(const MatchReport& report);

/// The data term's settings as REPORT.json and EVAL.json record them: {"kind": "census",
/// "census_window", "aggregation_window", "support_gamma"} or {"kind": "zncc", "zncc_window"}.
nlohmann::json DataTermJson(const MatcherOptions& options);

/// The sparse disparity map of a rectified pair's matches, d = x_l - x_r at (round(x_l),
/// round(y_l)) of a rows x cols map, CV_32F; NaN where no feature matched (the convention of
/// Middlebury's PFM maps, with NaN for "unknown").
cv::Mat SparseDisparityMap(const MatchReport& report, int rows, int cols);

/// Writes `disparity` (SparseDisparityMap) atomically by the file's extension: .pfm as float32
/// (OpenCV reads it back with cv::imread(path, cv::IMREAD_UNCHANGED)); .png as uint16 in the
/// KITTI scaling, round(256 d), 0 = no match (disparities outside (0, 255.99] are left out).
/// Throws std::invalid_argument for another extension, std::runtime_error when writing fails.
void WriteDisparityMap(const std::string& path, const cv::Mat& disparity);

}  // namespace hnnstereo::vision
