// The lens-distortion chain through the command line: render --distortion, calibrate --dir (the
// board route: K D, R T, the table frame), pick; the circle route on the same folder; and pick's
// refusals and hints for a calibration whose world frame is not the table or that belongs to
// another rig.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;

using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// One distorted scene shared by the tests (rendering is the slow part).
class LensCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("hnnstereo_lens_cli_" + std::to_string(::getpid()));
    render_ = RunCli("render --seed 5 --objects 3 --distortion -0.25,0.08,0.001,-0.001 --out " +
                     scene_.string());
    if (render_.exit_code == 0) {
      calibrate_ = RunCli("calibrate --dir " + Scene("target") + " --out " + Scene("board.yml") +
                          " --report " + Scene("board.json"));
    }
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }
  void SetUp() override {
    ASSERT_EQ(render_.exit_code, 0) << render_.output;
    ASSERT_EQ(calibrate_.exit_code, 0) << calibrate_.output;
    dir_ = scene_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(dir_);
  }
  static std::string Scene(const std::string& name) { return (scene_ / name).string(); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::string Pick(const std::string& calib) const {
    return "pick --left " + Scene("left.png") + " --right " + Scene("right.png") + " --calib " +
           calib + " --engine cpu --out " + Path("objects.json");
  }
  static fs::path scene_;
  static CliResult render_, calibrate_;
  fs::path dir_;
};

fs::path LensCli::scene_;
CliResult LensCli::render_, LensCli::calibrate_;

TEST_F(LensCli, BoardRouteWritesDistortionAndTheTableFrame) {
  cv::FileStorage storage(Scene("board.yml"), cv::FileStorage::READ);
  EXPECT_EQ(static_cast<std::string>(storage["world_frame"]), "table");
  cv::Mat pose, d1;
  storage["world_from_left_camera"] >> pose;
  storage["D1"] >> d1;
  EXPECT_EQ(pose.rows, 4);
  ASSERT_EQ(d1.total(), 5u);
  EXPECT_NEAR(d1.at<double>(0), -0.25, 0.05) << "k1";
  const nlohmann::json report = ReadJson(Scene("board.json"));
  EXPECT_EQ(report["method"], "board");
  EXPECT_LE(report["extra"]["table_fit_rms_mm"].get<double>(), 0.5);
  for (const auto& camera : report["cameras"]) {
    EXPECT_LE(camera["final"]["rms_px"].get<double>(), 0.3) << camera["camera"];
  }
  // The circle plate's route on the same folder works as before.
  const CliResult circles =
      RunCli("calibrate --target circles --dir " + Scene("target") + " --out " + Path("c.yml"));
  EXPECT_EQ(circles.exit_code, 0) << circles.output;
}

TEST_F(LensCli, PickThroughTheLensFindsThePartsWithoutWarnings) {
  const CliResult result = RunCli(Pick(Scene("board.yml")));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const nlohmann::json objects = ReadJson(Path("objects.json"));
  const nlohmann::json truth = ReadJson(Scene("truth.json"));
  ASSERT_EQ(objects["objects"].size(), truth["objects"].size()) << result.output;
  for (std::size_t i = 0; i < truth["objects"].size(); ++i) {
    for (int axis = 0; axis < 2; ++axis) {
      EXPECT_NEAR(objects["objects"][i]["centroid"][axis].get<double>(),
                  truth["objects"][i]["centroid"][axis].get<double>(), 1.0);
    }
  }
  EXPECT_TRUE(objects["warnings"].empty()) << objects["warnings"];
}

// `calibrate --target chessboard` on the same board images: world = the left camera.
TEST_F(LensCli, PickRefusesALeftCameraFrameWithTheHint) {
  std::string left, right;
  for (int i = 0; fs::exists(Scene("target/board_left_" + std::to_string(i) + ".png")); ++i) {
    left += " " + Scene("target/board_left_" + std::to_string(i) + ".png");
    right += " " + Scene("target/board_right_" + std::to_string(i) + ".png");
  }
  const CliResult calibrated = RunCli("calibrate --target chessboard --rows 6 --cols 9 --square 20"
                                      " --left" + left + " --right" + right +
                                      " --out " + Path("left_camera.yml"));
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.output;
  const CliResult result = RunCli(Pick(Path("left_camera.yml")));
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_NE(result.output.find("is CAL.yml's world frame the table?"), std::string::npos)
      << result.output;
  EXPECT_FALSE(fs::exists(Path("objects.json")));
}

// The right camera of another rig: 40 mm further along x.
TEST_F(LensCli, PickWarnsWhenTheCalibrationIsAnotherRigs) {
  cv::FileStorage in(Scene("calib.yml"), cv::FileStorage::READ);
  cv::Mat P1, P2;
  in["P1"] >> P1;
  in["P2"] >> P2;
  cv::Mat moved = cv::Mat::eye(4, 4, CV_64F);
  moved.at<double>(0, 3) = 40.0;
  cv::FileStorage out(Path("other_rig.yml"), cv::FileStorage::WRITE);
  out << "units" << "mm" << "image_width" << 640 << "image_height" << 480;
  out << "P1" << P1 << "P2" << cv::Mat(P2 * moved);
  out.release();
  const CliResult result = RunCli(Pick(Path("other_rig.yml")));
  EXPECT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("hnnstereo: warning: the residuals say this calibration is not for "
                               "this pair"),
            std::string::npos)
      << result.output;
  const nlohmann::json objects = ReadJson(Path("objects.json"));
  ASSERT_FALSE(objects["warnings"].empty());
  EXPECT_NE(objects["warnings"][0].get<std::string>().find("not for this pair"), std::string::npos);
}

TEST_F(LensCli, RenderRefusesBadDistortion) {
  for (const std::string bad : {"-0.25,0.08", "a,b,c,d", "-0.25,0.08,0.5,0", "nan,0,0,0"}) {
    const CliResult result =
        RunCli("render --seed 1 --distortion " + bad + " --out " + Path("s"));
    EXPECT_EQ(result.exit_code, 2) << bad << ": " << result.output;
    EXPECT_NE(result.output.find("--distortion"), std::string::npos) << result.output;
    EXPECT_FALSE(fs::exists(Path("s"))) << bad;
  }
}

}  // namespace
