#pragma once
// The match command's files (ARCHITECTURE.md): MATCHES.csv and REPORT.json.

#include <nlohmann/json.hpp>
#include <string>

#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

/// "xl,yl,xr,yr,activation,confidence" then one row per match (0-based pixel coordinates).
std::string MatchesCsv(const MatchReport& report);

/// The REPORT.json object: engine, device, sizes, iterations, energies, timing_ms and more.
nlohmann::json MatchReportJson(const MatchReport& report, const MatcherOptions& options);

/// The data term's settings as REPORT.json and EVAL.json record them: {"kind": "census",
/// "census_window", "aggregation_window", "support_gamma"} or {"kind": "zncc", "zncc_window"}.
nlohmann::json DataTermJson(const MatcherOptions& options);

}  // namespace hnnstereo::vision
