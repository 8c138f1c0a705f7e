// The render, pick, probe and demo commands' contracts: files, keys, one-line errors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
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

// One rendered scene shared by the tests (rendering is the slow part).
class PickCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("hnnstereo_pick_cli_scene_" + std::to_string(::getpid()));
    render_ = RunCli("render --seed 5 --objects 3 --out " + scene_.string());
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }
  void SetUp() override {
    ASSERT_EQ(render_.exit_code, 0) << render_.output;
    dir_ = scene_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(dir_);
  }
  std::string Scene(const std::string& name) const { return (scene_ / name).string(); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::string Pair() const {
    return "--left " + Scene("left.png") + " --right " + Scene("right.png") + " --calib " +
           Scene("calib.yml");
  }
  void ExpectCleanFailure(const CliResult& result, const std::string& reason) const {
    EXPECT_NE(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("hnnstereo: error: "), std::string::npos) << result.output;
    EXPECT_NE(result.output.find(reason), std::string::npos) << result.output;
    EXPECT_TRUE(fs::is_empty(dir_)) << "a failed command wrote files";
  }
  static fs::path scene_;
  static CliResult render_;
  fs::path dir_;
};

fs::path PickCli::scene_;
CliResult PickCli::render_;

TEST_F(PickCli, RenderWritesTheSceneFolder) {
  for (const char* name : {"left.png", "right.png", "calib.yml", "truth.json", "target/target.yml",
                           "target/left_0.png", "target/right_0.png"}) {
    EXPECT_TRUE(fs::exists(scene_ / name)) << name;
  }
  const nlohmann::json truth = ReadJson(scene_ / "truth.json");
  EXPECT_EQ(truth["units"], "mm");
  ASSERT_EQ(truth["objects"].size(), 3u);
  double previous_height = 1e9;
  for (const auto& object : truth["objects"]) {
    for (const char* key : {"id", "centroid", "height", "yaw_deg", "points", "shape", "size"}) {
      EXPECT_TRUE(object.contains(key)) << key;
    }
    EXPECT_LE(object["height"].get<double>(), previous_height);  // tallest first
    previous_height = object["height"].get<double>();
  }
  const cv::Mat left = cv::imread(Scene("left.png"), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(left.type(), CV_8UC1);
}

TEST_F(PickCli, PickWritesObjectsJsonMatchingTheTruth) {
  const CliResult result = RunCli("pick " + Pair() + " --engine cpu --out " + Path("objects.json") +
                               " --overlay " + Path("overlay.png") + " --ply " + Path("points.ply") +
                               " --histogram " + Path("heights.png") + " --energy-plot " +
                               Path("energy.png"));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const nlohmann::json objects = ReadJson(dir_ / "objects.json");
  const nlohmann::json truth = ReadJson(scene_ / "truth.json");
  EXPECT_EQ(objects["units"], "mm");
  ASSERT_EQ(objects["objects"].size(), truth["objects"].size()) << result.output;
  for (std::size_t i = 0; i < objects["objects"].size(); ++i) {
    const auto& detected = objects["objects"][i];
    for (const char* key : {"id", "centroid", "height", "yaw_deg", "points"}) {
      EXPECT_TRUE(detected.contains(key)) << key;
    }
    // Both lists are tallest first, and the scene's heights are apart.
    const auto& expected = truth["objects"][i];
    EXPECT_NEAR(detected["height"].get<double>(), expected["height"].get<double>(), 3.0);
    EXPECT_NEAR(detected["centroid"][0].get<double>(), expected["centroid"][0].get<double>(), 4.0);
    EXPECT_NEAR(detected["centroid"][1].get<double>(), expected["centroid"][1].get<double>(), 4.0);
    if (detected["round"].get<bool>()) {
      EXPECT_TRUE(detected["yaw_deg"].is_null()) << "a round part has no orientation";
    } else {
      EXPECT_GT(detected["yaw_deg"].get<double>(), -90.0);
      EXPECT_LE(detected["yaw_deg"].get<double>(), 90.0);
    }
  }
  EXPECT_EQ(cv::imread(Path("overlay.png")).cols, 640);
  EXPECT_EQ(cv::imread(Path("heights.png")).cols, 900) << "plots are at least 800 px wide";
  EXPECT_EQ(cv::imread(Path("energy.png")).cols, 900);
  std::ifstream ply(Path("points.ply"));
  std::string first_line;
  std::getline(ply, first_line);
  EXPECT_EQ(first_line, "ply");
}

TEST_F(PickCli, ProbeFindsTheHeightOfATopFace) {
  const nlohmann::json truth = ReadJson(scene_ / "truth.json");
  // The left image point of the tallest part's top centre, from the true camera.
  cv::FileStorage storage(Scene("calib.yml"), cv::FileStorage::READ);
  cv::Mat P1;
  storage["P1"] >> P1;
  const auto& centroid = truth["objects"][0]["centroid"];
  const cv::Mat X = (cv::Mat_<double>(4, 1) << centroid[0].get<double>(),
                     centroid[1].get<double>(), centroid[2].get<double>(), 1.0);
  const cv::Mat x = P1 * X;
  // A little off the centre onto a textured spot is not guaranteed; probe several points and
  // expect most of them on the top face.
  int on_top = 0;
  for (int dx = -6; dx <= 6; dx += 6) {
    const double u = x.at<double>(0) / x.at<double>(2) + dx, v = x.at<double>(1) / x.at<double>(2);
    const CliResult result = RunCli("probe " + Pair() + " --point " + std::to_string(u) + "," +
                                 std::to_string(v));
    if (result.exit_code != 0) continue;
    const auto at = result.output.find("height");
    if (at == std::string::npos) continue;
    const double height = std::atof(result.output.substr(result.output.rfind("height") + 6).c_str());
    if (std::abs(height - truth["objects"][0]["height"].get<double>()) < 4.0) ++on_top;
  }
  EXPECT_GE(on_top, 2);
}

TEST_F(PickCli, HelpTeachesEveryCommand) {
  for (const std::string command : {"render", "pick", "probe", "demo"}) {
    const CliResult result = RunCli(command + " --help");
    EXPECT_EQ(result.exit_code, 0) << command;
    EXPECT_NE(result.output.find("Example"), std::string::npos) << command;
  }
}

TEST_F(PickCli, PickMissingImage) {
  ExpectCleanFailure(RunCli("pick --left " + Path("nope.png") + " --right " + Scene("right.png") +
                            " --calib " + Scene("calib.yml") + " --out " + Path("o.json")),
                     "does not exist");
}

TEST_F(PickCli, PickUnknownClustering) {
  ExpectCleanFailure(RunCli("pick " + Pair() + " --clustering kmeans --out " + Path("o.json")),
                     "--clustering");
}

TEST_F(PickCli, PickCalibrationForAnotherImageSize) {
  const fs::path small = scene_ / "input_small";
  fs::create_directories(small);
  cv::imwrite((small / "l.png").string(), cv::Mat(100, 120, CV_8UC1, cv::Scalar(80)));
  cv::imwrite((small / "r.png").string(), cv::Mat(100, 120, CV_8UC1, cv::Scalar(80)));
  ExpectCleanFailure(RunCli("pick --left " + (small / "l.png").string() + " --right " +
                            (small / "r.png").string() + " --calib " + Scene("calib.yml") +
                            " --out " + Path("o.json")),
                     "640x480");
}

TEST_F(PickCli, ProbeOutsideTheImage) {
  ExpectCleanFailure(RunCli("probe " + Pair() + " --point 5000,10"), "outside");
  ExpectCleanFailure(RunCli("probe " + Pair() + " --point 12"), "--point");
}

TEST_F(PickCli, RenderRefusesAnImpossibleScene) {
  const CliResult result = RunCli("render --seed 1 --objects 30 --min-gap 60 --out " + Path("s"));
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.output.find("cannot place"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(Path("s") + "/left.png"));
}

}  // namespace
