// The library facade (<hnnstereo/hnnstereo.h>) against the CLI: the same matches for the same
// pair and settings (rectified Teddy; a rendered, calibrated scene with overrides), the report's
// keys, and bad input (a one-line reason, the CLI's wording).
#include <hnnstereo/hnnstereo.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <algorithm>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>
#include <string>

#include "cli_runner.h"

namespace {

using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;
const std::string& kTeddy = hnnstereo::testing::kTeddyDir;

// MATCHES.csv as the CLI writes it (vision/match_io.cc).
std::string Csv(const hnnstereo::MatchResult& result) {
  std::string text = "xl,yl,xr,yr,activation,confidence\n";
  char line[160];
  for (const hnnstereo::Match& m : result.matches) {
    std::snprintf(line, sizeof(line), "%.3f,%.3f,%.3f,%.3f,%.6f,%.6f\n", m.xl, m.yl, m.xr, m.yr,
                  m.activation, m.confidence);
    text += line;
  }
  return text;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

cv::Mat Read(const std::string& path) { return cv::imread(path, cv::IMREAD_UNCHANGED); }

class HnnstereoFacade : public hnnstereo::testing::CliTest {};

TEST_F(HnnstereoFacade, MatchesTeddyLikeTheCli) {
  const CliResult cli = RunCli("match --left " + kTeddy + "/im2.png --right " + kTeddy +
                               "/im6.png --rectified --max-disparity 64 --quiet --out " + Path("m.csv"));
  ASSERT_EQ(cli.exit_code, 0) << cli.output;
  hnnstereo::Matcher matcher;
  EXPECT_EQ(matcher.preset(), "hnn-default");
  const hnnstereo::MatchResult result =
      matcher.Match(Read(kTeddy + "/im2.png"), Read(kTeddy + "/im6.png"), 64);
  EXPECT_GT(result.matches.size(), 300u);
  EXPECT_EQ(Csv(result), ReadFile(Path("m.csv")));
  for (const char* key : {"\"engine\"", "\"device\"", "\"n_left\"", "\"n_neurons\"", "\"timing_ms\"",
                          "\"energy_final\"", "\"preset\":\"hnn-default\""}) {
    EXPECT_NE(result.report.json.find(key), std::string::npos) << key;
  }
  EXPECT_GT(result.report.n_neurons, 0);
  EXPECT_GT(result.report.timing_ms.total, 0.0);
  // The Matcher is reusable: a second call gives the same matches.
  EXPECT_EQ(Csv(matcher.Match(Read(kTeddy + "/im2.png"), Read(kTeddy + "/im6.png"), 64)), Csv(result));
}

TEST_F(HnnstereoFacade, MatchesACalibratedPairLikeTheCliWithOverrides) {
  ASSERT_EQ(RunCli("render --seed 3 --objects 2 --out " + Path("scene")).exit_code, 0);
  const std::string scene = Path("scene");
  const CliResult cli = RunCli("match --left " + scene + "/left.png --right " + scene +
                               "/right.png --calib " + scene + "/calib.yml --max-features 1500 "
                               "--top-k 6 --quiet --out " + Path("m.csv"));
  ASSERT_EQ(cli.exit_code, 0) << cli.output;
  const hnnstereo::Calibration calibration = hnnstereo::LoadCalibration(scene + "/calib.yml");
  EXPECT_FALSE(calibration.rectified());
  EXPECT_GT(calibration.image_width(), 0);
  hnnstereo::Matcher matcher("hnn-default", {{"max-features", "1500"}, {"top-k", "6"}});
  const hnnstereo::MatchResult result =
      matcher.Match(Read(scene + "/left.png"), Read(scene + "/right.png"), calibration);
  EXPECT_GT(result.matches.size(), 100u);
  EXPECT_EQ(Csv(result), ReadFile(Path("m.csv")));
}

TEST(HnnstereoFacadeBadInput, ThrowsOneLineReasons) {
  const cv::Mat left = Read(kTeddy + "/im2.png"), right = Read(kTeddy + "/im6.png");
  const auto expect_throw = [](auto call, const std::string& reason, bool invalid_argument) {
    try {
      call();
      ADD_FAILURE() << "no exception; expected " << reason;
    } catch (const std::invalid_argument& error) {
      EXPECT_TRUE(invalid_argument) << error.what();
      EXPECT_NE(std::string(error.what()).find(reason), std::string::npos) << error.what();
      EXPECT_EQ(std::string(error.what()).find('\n'), std::string::npos) << error.what();
    } catch (const std::runtime_error& error) {
      EXPECT_FALSE(invalid_argument) << error.what();
      EXPECT_NE(std::string(error.what()).find(reason), std::string::npos) << error.what();
      EXPECT_EQ(std::string(error.what()).find('\n'), std::string::npos) << error.what();
    }
  };
  expect_throw([] { hnnstereo::Matcher("no-such-preset"); }, "unknown preset 'no-such-preset'", true);
  expect_throw([] { hnnstereo::Matcher("hnn-default", {{"top-k", "many"}}); }, "'top-k'", true);
  expect_throw([] { hnnstereo::Matcher("hnn-default", {{"bogus", "1"}}); }, "unknown option 'bogus'", true);
  expect_throw([] { hnnstereo::Matcher("hnn-default", {{"engine", "gpu"}}); }, "unknown engine 'gpu'", true);
  hnnstereo::Matcher matcher("hnn-default", {{"engine", "cpu"}});
  expect_throw([&] { matcher.Match(cv::Mat(), right, 64); }, "left image is empty", true);
  expect_throw([&] { matcher.Match(left, right(cv::Rect(0, 0, 100, 100)), 64); }, "differ in size", true);
  expect_throw([&] { matcher.Match(left, right, hnnstereo::Calibration()); }, "calibration is empty", true);
  // Refused before any work, as `hnnstereo match` refuses them (api::CheckMatchSetup).
  expect_throw([&] { matcher.Match(left, left, 64); }, "left and right are identical", true);
  expect_throw([&] { matcher.Match(left, right, 0); }, "--max-disparity 0.0 must be", true);
  expect_throw([&] { matcher.Match(cv::Mat::zeros(64, 64, CV_8U), cv::Mat(64, 64, CV_8U, cv::Scalar(9)), 32); },
               "no features", false);
  expect_throw([] { hnnstereo::LoadCalibration("/nonexistent/cal.yml"); }, "cal.yml", false);
}

TEST(HnnstereoFacadeNames, ListsPresetsAndOptions) {
  const std::vector<std::string> presets = hnnstereo::PresetNames();
  ASSERT_FALSE(presets.empty());
  EXPECT_EQ(presets.front(), "hnn-default");
  const std::vector<std::string> options = hnnstereo::MatcherOptionNames();
  for (const char* name : {"max-features", "engine", "device", "top-k", "no-lr-check", "threshold"}) {
    EXPECT_NE(std::find(options.begin(), options.end(), name), options.end()) << name;
  }
  EXPECT_STREQ(hnnstereo::Version(), HNNSTEREO_PROJECT_VERSION);
}

// The facade takes every flag `match` and `eval` take, by the same name (one resolver), and
// refuses a bad value of the new ones with the CLI's wording.
TEST(HnnstereoFacadeNames, TakesTheCommandsMatcherFlags) {
  const std::vector<std::string> options = hnnstereo::MatcherOptionNames();
  for (const char* name : {"lr-check", "subpixel", "subpixel-min-offset", "epipolar-snap",
                           "epipolar-subpixel", "lr-tolerance", "zncc-peaks", "subpixel-peaks",
                           "census-window", "aggregation-window", "support-gamma", "T",
                           "min-correlation", "memory-budget-mb"}) {
    EXPECT_NE(std::find(options.begin(), options.end(), name), options.end()) << name;
  }
  EXPECT_NO_THROW(hnnstereo::Matcher("hnn-default", {{"engine", "cpu"}, {"T", "2"},
                                                     {"subpixel", "false"}, {"lr-check", "false"}}));
  EXPECT_THROW(hnnstereo::Matcher("hnn-default", {{"engine", "cpu"}, {"subpixel-min-offset", "0.7"}}),
               std::invalid_argument);
}

}  // namespace
