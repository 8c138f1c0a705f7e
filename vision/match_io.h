#pragma once
// The match command's files (ARCHITECTURE.md): MATCHES.csv and REPORT.json.

#include <nlohmann/json.hpp>
#include <string>

#include "vision/stereo_matcher.h"

namespace hnnstereo::vision {

/// "xl,yl,xr,yr,activation,confidence" then one row per match (0-based pixel coordinates).
std::string MatchesCsv(const MatchReport& report);

/// The REPORT.json object: engine, device, sizes, iterations, energies, timing_ms and more.
nlohmann::json MatchReportJson(const MatchReport& report, const MatcherOptions& options);

}  // namespace hnnstereo::vision
