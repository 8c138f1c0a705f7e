// End to end: the hnnstereo executable's `calibrate` on generated inputs (HNNSTEREO_BINARY).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "calib/calibration.h"
#include "calib/dlt.h"
#include "synthetic_rig.h"

namespace hnnstereo::calib {
namespace {

namespace fs = std::filesystem;

int RunHnnstereo(const std::string& arguments, const std::string& log) {
  const std::string command =
      std::string("\"") + HNNSTEREO_BINARY + "\" " + arguments + " > \"" + log + "\" 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

class CalibrateCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(HNNSTEREO_BINARY)) GTEST_SKIP() << "no " << HNNSTEREO_BINARY;
  }
};

TEST_F(CalibrateCli, KnownPointsWritesCalibration) {
  const testing::StereoRig rig = testing::ThesisRig();
  const std::string dir = testing::TemporaryDirectory("cli_points");
  std::mt19937_64 generator(11);
  std::normal_distribution<double> noise(0.0, 0.1);
  std::uniform_real_distribution<double> uniform(-50.0, 50.0);
  std::ofstream left(dir + "/left.txt"), right(dir + "/right.txt");
  left << "# X Y Z u v (mm, px)\n";
  right << "# X Y Z u v (mm, px)\n";
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d X(100 + uniform(generator), 385 + uniform(generator), 40.0 * (i % 3));
    const Eigen::Vector2d x1 = Project(rig.P1, X), x2 = Project(rig.P2, X);
    left << X.transpose() << " " << x1.x() + noise(generator) << " " << x1.y() + noise(generator)
         << "\n";
    right << X.transpose() << " " << x2.x() + noise(generator) << " " << x2.y() + noise(generator)
          << "\n";
  }
  left.close();
  right.close();
  const std::string out = dir + "/cal.yml";
  ASSERT_EQ(RunHnnstereo("calibrate --points-left " + dir + "/left.txt --points-right " + dir +
                             "/right.txt --out " + out + " --report " + dir + "/calib.json",
                         dir + "/log.txt"),
            0)
      << ReadText(dir + "/log.txt");
  const StereoCalibration cal = LoadCalibration(out);
  EXPECT_LT((cal.C1 - rig.C1).norm(), 15.0);
  EXPECT_LT((cal.C2 - rig.C2).norm(), 15.0);
  EXPECT_NE(ReadText(dir + "/calib.json").find("\"mae_px\""), std::string::npos);
  EXPECT_NE(ReadText(dir + "/log.txt").find("RMS"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir + "/cal_left.png"));
}

TEST_F(CalibrateCli, CircleTargetDirectory) {
  const testing::StereoRig rig = testing::ThesisRig();
  const CircleGridGeometry grid;
  CircleTargetRenderOptions render;
  render.num_distractors = 5;
  const auto placements = testing::RenderRandomPlacements(rig, grid, 3, 21, render, true, 40, 80);
  ASSERT_EQ(placements.size(), 3u);
  const std::string dir = testing::TemporaryDirectory("cli_circles");
  testing::WriteTargetDirectory(placements, grid, dir + "/target");
  fs::create_directories(dir + "/report");
  const std::string out = dir + "/cal.yml";
  ASSERT_EQ(RunHnnstereo("calibrate --target circles --dir " + dir + "/target --out " + out +
                             " --report " + dir + "/report/calib.json",
                         dir + "/log.txt"),
            0)
      << ReadText(dir + "/log.txt");
  const StereoCalibration cal = LoadCalibration(out);
  EXPECT_LT((cal.C1 - rig.C1).norm(), 20.0);
  EXPECT_EQ(cal.image_width, 640);
  EXPECT_TRUE(fs::exists(dir + "/report/cal_left.png"));
  EXPECT_TRUE(fs::exists(dir + "/report/cal_right.png"));
}

TEST_F(CalibrateCli, ErrorsAreOneLineAndWriteNothing) {
  const std::string dir = testing::TemporaryDirectory("cli_errors");
  const std::string out = dir + "/cal.yml";
  // An input that cannot be used, found before any work: a refused setup, exit 2.
  EXPECT_EQ(RunHnnstereo("calibrate --target circles --dir " + dir + "/missing --out " + out,
                         dir + "/log.txt"),
            2);
  const std::string log = ReadText(dir + "/log.txt");
  EXPECT_EQ(log.rfind("hnnstereo: error: ", 0), 0u) << log;
  EXPECT_NE(log.find("does not exist"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(out));
  // NaN in a points file.
  std::ofstream(dir + "/bad.txt") << "1 2 3 4 5\nnan 2 3 4 5\n";
  EXPECT_EQ(RunHnnstereo("calibrate --points-left " + dir + "/bad.txt --points-right " + dir +
                             "/bad.txt --out " + out,
                         dir + "/log.txt"),
            2);
  EXPECT_NE(ReadText(dir + "/log.txt").find("line 2"), std::string::npos);
  EXPECT_FALSE(fs::exists(out));
  // Nothing but temporary-free output folder.
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    files += entry.path().filename().string().find(".tmp") != std::string::npos ? 1 : 0;
  }
  EXPECT_EQ(files, 0);
  // --help teaches the formats.
  EXPECT_EQ(RunHnnstereo("calibrate --help", dir + "/help.txt"), 0);
  EXPECT_NE(ReadText(dir + "/help.txt").find("X Y Z u v"), std::string::npos);
  EXPECT_NE(ReadText(dir + "/help.txt").find("origin_mm"), std::string::npos);
}

}  // namespace
}  // namespace hnnstereo::calib
