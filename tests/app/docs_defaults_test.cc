// The defaults the docs print are the ones that run: docs/engine.md's table "Defaults of
// `hnnstereo match`" against `match --help` and against the options REPORT.json records.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

#include "cli_runner.h"

namespace {

using hnnstereo::testing::CliTest;
using hnnstereo::testing::kTeddyDir;
using hnnstereo::testing::RunCli;

// (option, default) rows of the table that follows `heading` in `path`.
std::map<std::string, std::string> DocumentedDefaults(const std::string& path,
                                                      const std::string& heading) {
  std::ifstream in(path);
  std::string line;
  bool inside = false;
  std::map<std::string, std::string> rows;
  const std::regex row(R"(^\| `(--[a-zA-Z-]+)` \| ([^|]+?) \|)");
  while (std::getline(in, line)) {
    if (line.rfind("#", 0) == 0) inside = line.find(heading) != std::string::npos;
    std::smatch m;
    if (inside && std::regex_search(line, m, row)) rows[m[1]] = m[2];
  }
  return rows;
}

// The default `match --help` shows for `option` ("--top-k INT=4").
std::string HelpDefault(const std::string& help, const std::string& option) {
  std::istringstream in(help);
  std::string line;
  const std::regex shown("^\\s+" + option +
                         R"(\s+[A-Z]+=(\S+))");
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, shown)) return m[1];
  }
  return "(none shown)";
}

bool SameValue(const nlohmann::json& value, const std::string& documented) {
  if (value.is_number()) {
    try {
      return std::abs(value.get<double>() - std::stod(documented)) < 1e-9;
    } catch (const std::exception&) {
      return false;
    }
  }
  if (value.is_string()) return value.get<std::string>() == documented;
  return false;
}

class DocsDefaults : public CliTest {};

TEST_F(DocsDefaults, EngineTableEqualsHelpAndReport) {
  const auto documented = DocumentedDefaults(std::string(HNNSTEREO_SOURCE_DIR) + "/docs/engine.md",
                                             "Defaults of `hnnstereo match`");
  ASSERT_GE(documented.size(), 15u) << "the defaults table was not found";
  // Every option the matcher reports must be in the table, with the value that ran.
  const std::map<std::string, std::string> reported = {
      {"--preset", "/preset"},
      {"--features", "/features"},
      {"--network", "/candidate_options/network"},
      {"--top-k", "/candidate_options/top_k"},
      {"--support-radius", "/energy_options/support_radius_px"},
      {"--objective", "/energy_options/objective"},
      {"--max-epipolar", "/candidate_options/max_epipolar_distance_px"},
      {"--min-disparity", "/candidate_options/min_disparity"},
      {"--max-disparity", "/candidate_options/max_disparity"},
      {"--A", "/energy_options/A"},
      {"--B", "/energy_options/B"},
      {"--C", "/energy_options/C"},
      {"--D", "/energy_options/D"},
      {"--lambda", "/energy_options/lambda"},
      {"--theta", "/energy_options/theta"},
      {"--alpha", "/dynamics_options/alpha"},
      {"--dt", "/dynamics_options/time_step"},
      {"--max-steps", "/dynamics_options/max_steps"},
      {"--init", "/dynamics_options/initial_state"},
      {"--activation", "/dynamics_options/activation"},
      {"--decode", "/decode"},
      {"--data-term", "/data_term/kind"},
      {"--stop", "/dynamics_options/stop_rule"},
      {"--check-interval", "/dynamics_options/check_interval"},
      {"--min-confidence", "/min_confidence"}};
  const auto run = RunCli("match --left " + kTeddyDir + "/im2.png --right " + kTeddyDir +
                          "/im6.png --rectified --max-features 400 --engine cpu --quiet --out " +
                          Path("m.csv") + " --report " + Path("r.json"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  std::ifstream report_file(Path("r.json"));
  const nlohmann::json report = nlohmann::json::parse(report_file);
  for (const auto& [option, pointer] : reported) {
    ASSERT_TRUE(documented.count(option)) << option << " is missing from docs/engine.md";
    const nlohmann::json value = report.at(nlohmann::json::json_pointer(pointer));
    EXPECT_TRUE(SameValue(value, documented.at(option)))
        << option << ": docs say " << documented.at(option) << ", the run used " << value;
  }
  // Every documented default is the one --help shows.
  const std::string help = RunCli("match --help").output;
  for (const auto& [option, value] : documented) {
    const std::string shown = HelpDefault(help, option);
    const bool same = shown == value || [&] {
      try {
        return std::abs(std::stod(shown) - std::stod(value)) < 1e-9;
      } catch (const std::exception&) {
        return false;
      }
    }();
    EXPECT_TRUE(same) << option << ": docs say " << value << ", --help shows " << shown;
  }
}

}  // namespace
