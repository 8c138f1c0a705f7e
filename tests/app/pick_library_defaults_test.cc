// One source of truth for the matcher settings: `pick` (and `serve`, which shares its flags,
// app/cell_sensing.h) runs the library's PositionSensingOptions defaults, which the stress
// acceptance measures (docs/sensing.md). The command's flags start from those options,
// but the match preset's settings (hnn-default's stop rule and check interval) used to replace
// them: `render --seed 249002 --min-gap 0` gave a 67 x 45 mm top 0.7 mm off with `pick` and
// 6.6 mm off with the library, whose energy stop rule (its default then) kept 48 more points.
// The library now stops as the preset does; the test keeps the two from drifting apart again.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "calib/calibration.h"
#include "cli_runner.h"
#include "vision/sensing/position_sensing.h"

namespace {

namespace fs = std::filesystem;
using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;

TEST(PickLibraryDefaults, PickSensesWhatTheLibraryDefaultsSense) {
  const fs::path dir =
      fs::temp_directory_path() / ("hnnstereo_pick_defaults_" + std::to_string(::getpid()));
  const CliResult render = RunCli("render --seed 249002 --min-gap 0 --quiet --out " + dir.string());
  ASSERT_EQ(render.exit_code, 0) << render.output;
  const std::string left = (dir / "left.png").string(), right = (dir / "right.png").string();
  const std::string calib = (dir / "calib.yml").string();
  const CliResult pick = RunCli("pick --engine cpu --quiet --left " + left + " --right " + right +
                                " --calib " + calib + " --out " + (dir / "objects.json").string());
  ASSERT_EQ(pick.exit_code, 0) << pick.output;
  std::ifstream in(dir / "objects.json");
  const nlohmann::json sensed_by_pick = nlohmann::json::parse(in);

  hnnstereo::vision::PositionSensingOptions options;  // the library's defaults
  options.matcher.engine = hnnstereo::hnn::EngineKind::kCpu;
  const hnnstereo::vision::PositionSensingReport report = hnnstereo::vision::SensePositions(
      cv::imread(left, cv::IMREAD_GRAYSCALE), cv::imread(right, cv::IMREAD_GRAYSCALE),
      hnnstereo::calib::LoadCalibration(calib), options, nullptr);
  fs::remove_all(dir);

  EXPECT_EQ(sensed_by_pick["matches"].get<int>(), static_cast<int>(report.match.matches.size()));
  ASSERT_EQ(sensed_by_pick["objects"].size(), report.objects.size());
  for (std::size_t i = 0; i < report.objects.size(); ++i) {
    SCOPED_TRACE(i);
    const nlohmann::json& object = sensed_by_pick["objects"][i];
    EXPECT_EQ(object["points"].get<int>(), report.objects[i].points);
    EXPECT_EQ(object["merged"].get<bool>(), report.objects[i].merged);
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_NEAR(object["centroid"][axis].get<double>(), report.objects[i].centroid[axis], 1e-6);
    }
  }
}

}  // namespace
