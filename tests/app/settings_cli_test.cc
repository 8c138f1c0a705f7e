// One source of settings (STYLE.md 14): every command shows the defaults the library runs, names
// the matcher's flags as `match` does (a --x/--no-x pair for every boolean, shown with its
// default), and resolves them through the library (api/matcher_settings.h).
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "cli_runner.h"

namespace {

using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;
const std::string& kTeddy = hnnstereo::testing::kTeddyDir;

class SettingsCli : public hnnstereo::testing::CliTest {};

void ExpectHelpHas(const std::string& command, std::initializer_list<const char*> lines) {
  const CliResult result = RunCli(command + " --help");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const char* line : lines)
    EXPECT_NE(result.output.find(line), std::string::npos) << command << ": " << line;
  // CLI11's "--x,--no-x{false}" reads as "off" whatever the default: never shown.
  EXPECT_EQ(result.output.find("{false}"), std::string::npos) << command;
  EXPECT_EQ(result.output.find("{true}"), std::string::npos) << command;
}

TEST_F(SettingsCli, PickShowsEveryBooleanPairWithTheDefaultThatRuns) {
  ExpectHelpHas(
      "pick", {"--subpixel,--no-subpixel (default: on)", "--image-edges,--no-image-edges (default: on)", "--dense,--no-dense (default: off)",
               "--stop TEXT=decisions", "--network TEXT=feature", "--zrange TEXT=-5,200",
               "--memory-budget-mb FLOAT=2048"});
}

// pick refines with the cell's own options: a --lr-check there would change nothing.
TEST_F(SettingsCli, PickOffersNoLeftRightCheckItWouldIgnore) {
  const CliResult result = RunCli("pick --help");
  EXPECT_EQ(result.output.find("lr-check"), std::string::npos);
}

TEST_F(SettingsCli, MatchShowsTheLibraryDefaults) {
  ExpectHelpHas(
      "match",
      {"--lr-check,--no-lr-check (default: on)", "--subpixel,--no-subpixel (default: on)",
       "--network TEXT=disparity", "--data-term TEXT=census", "--stop TEXT=decisions",
       "--check-interval INT=2", "--top-k INT=3", "--T FLOAT=1.5", "--memory-budget-mb FLOAT=2048",
       "--features TEXT=canny", "--engine TEXT=opencl", "--activation TEXT=continuous"});
}

TEST_F(SettingsCli, EvalNamesTheMatcherFlagsAsMatchDoes) {
  ExpectHelpHas(
      "eval",
      {"--lr-check,--no-lr-check (default: on)", "--subpixel,--no-subpixel (default: on)",
       "--epipolar-subpixel,--no-epipolar-subpixel (default: on)",
       "--subpixel-peaks,--no-subpixel-peaks (default: off)", "--subpixel-min-offset FLOAT=0.1",
       "--aggregation-window INT=13", "--T FLOAT=1.5", "--memory-budget-mb FLOAT=6144"});
  const CliResult result = RunCli("eval --help");
  EXPECT_EQ(result.output.find("0/1"), std::string::npos) << result.output;
}

// `match` takes eval's --T and the refinement pairs, through the library's resolver.
TEST_F(SettingsCli, MatchResolvesTheEnergyScaleAndTheRefinementPair) {
  const CliResult result =
      RunCli("match --left " + kTeddy + "/im2.png --right " + kTeddy + "/im6.png --rectified " +
             "--max-disparity 64 --max-features 400 --engine cpu --T 2 --no-lr-check --out " +
             Path("m.csv") + " --report " + Path("r.json"));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  std::ifstream file(Path("r.json"));
  const nlohmann::json report = nlohmann::json::parse(file);
  EXPECT_DOUBLE_EQ(report["energy_options"]["T"].get<double>(), 2.0);
  EXPECT_EQ(report["left_right_check"], false);
  EXPECT_EQ(report["dynamics_options"]["stop_rule"], "decisions");
}

// `lr-check: false` in a --config file is the pair's --no-lr-check; the command line still wins.
TEST_F(SettingsCli, ConfigFalseTurnsAPairOff) {
  std::ofstream(Path("input_config.yml")) << "lr-check: false\n";
  const std::string match = "match --left " + kTeddy + "/im2.png --right " + kTeddy +
                            "/im6.png --rectified --max-features 300 --engine cpu --out " +
                            Path("m.csv") + " --config " + Path("input_config.yml");
  for (const auto& [extra, expected] :
       {std::pair<std::string, bool>{"", false}, {" --lr-check", true}}) {
    const CliResult result = RunCli(match + " --report " + Path("r.json") + extra);
    ASSERT_EQ(result.exit_code, 0) << result.output;
    std::ifstream file(Path("r.json"));
    EXPECT_EQ(nlohmann::json::parse(file)["left_right_check"], expected) << extra;
  }
}

}  // namespace
