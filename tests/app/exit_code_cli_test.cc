// One exit-code rule for every command (README.md, "Exit status"): an input that cannot be used,
// found before any work, is a refused setup - exit 2, one line naming the option and the file,
// nothing written; a failure found once the work started is exit 1.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;

using hnnstereo::testing::CliResult;
using hnnstereo::testing::kTeddyDir;
using hnnstereo::testing::RunCli;

// One rendered scene (with its circle target) shared by the tests.
class ExitCodeCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("hnnstereo_exit_code_" + std::to_string(::getpid()));
    render_ = RunCli("render --seed 5 --objects 3 --quiet --out " + scene_.string());
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }
  void SetUp() override {
    ASSERT_EQ(render_.exit_code, 0) << render_.output;
    dir_ = scene_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(dir_);
  }
  static std::string Scene(const std::string& name) { return (scene_ / name).string(); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  // Exit `code`, one "hnnstereo: error:" line holding every one of `reasons`, no output file.
  void ExpectError(const std::string& arguments, int code,
                   const std::vector<std::string>& reasons) const {
    const CliResult result = RunCli(arguments);
    EXPECT_EQ(result.exit_code, code) << arguments << "\n" << result.output;
    EXPECT_EQ(result.output.rfind("hnnstereo: error: ", 0), 0u) << result.output;
    EXPECT_EQ(std::count(result.output.begin(), result.output.end(), '\n'), 1) << result.output;
    for (const std::string& reason : reasons) {
      EXPECT_NE(result.output.find(reason), std::string::npos) << reason << "\n" << result.output;
    }
    for (const char* output : {"out.yml", "out.json", "report.json"}) {
      EXPECT_FALSE(fs::exists(Path(output))) << arguments << " wrote " << output;
    }
  }
  // A copy of the rendered target folder to spoil.
  fs::path CopiedTarget() const {
    const fs::path copy = dir_ / "target";
    fs::copy(scene_ / "target", copy, fs::copy_options::recursive);
    return copy;
  }
  static fs::path scene_;
  static CliResult render_;
  fs::path dir_;
};

fs::path ExitCodeCli::scene_;
CliResult ExitCodeCli::render_;

TEST_F(ExitCodeCli, CalibrateRefusesUnusableInputsWithExitTwo) {
  const std::string out = " --out " + Path("out.yml") + " --report " + Path("report.json");
  ExpectError("calibrate --target circles --dir " + Path("nope") + out, 2,
              {"--dir: ", "'" + Path("nope") + "' does not exist"});
  fs::create_directories(Path("empty"));
  ExpectError("calibrate --target circles --dir " + Path("empty") + out, 2,
              {"--dir: ", "has no target.yml"});
  fs::create_directories(Path("bad"));
  std::ofstream(Path("bad/target.yml")) << "rows: [\n";
  ExpectError("calibrate --target circles --dir " + Path("bad") + out, 2,
              {"--dir: ", Path("bad/target.yml")});
  // An image of another size than its camera's first.
  const fs::path target = CopiedTarget();
  cv::imwrite((target / "left_2.png").string(), cv::Mat(100, 120, CV_8U, cv::Scalar(128)));
  ExpectError("calibrate --target circles --dir " + target.string() + out, 2,
              {"--dir: ", (target / "left_2.png").string(), "differs in size"});
  // An image that is not one.
  std::ofstream(target / "left_2.png") << "not a png";
  ExpectError("calibrate --target circles --dir " + target.string() + out, 2,
              {"--dir: ", (target / "left_2.png").string()});
  ExpectError("calibrate --points-left " + Path("nope.txt") + " --points-right " +
                  Path("nope.txt") + out,
              2, {"--points-left: ", Path("nope.txt")});
  const std::string images = " --left " + Scene("left.png") + " " + Scene("left.png") + " " +
                             Path("nope.png") + " --right " + Scene("right.png") + " " +
                             Scene("right.png") + " " + Scene("right.png");
  ExpectError("calibrate --target chessboard --rows 6 --cols 9" + images + out, 2,
              {"--left/--right: ", Path("nope.png")});
  ExpectError("calibrate --target chessboard --rows 6 --cols 9 --left " + Scene("left.png") +
                  " --right " + Scene("right.png") + out,
              2, {"at least 3 image pairs"});
}

TEST_F(ExitCodeCli, CalibrateFailingAfterTheWorkStartedIsExitOne) {
  // Readable images of the right size where no circle grid is found: detection ran, then failed.
  const fs::path target = CopiedTarget();
  const cv::Mat first = cv::imread((target / "left_0.png").string(), cv::IMREAD_GRAYSCALE);
  cv::imwrite((target / "left_0.png").string(), cv::Mat(first.size(), CV_8U, cv::Scalar(128)));
  ExpectError("calibrate --target circles --dir " + target.string() + " --out " + Path("out.yml"),
              1, {"height 0, left image"});
}

TEST_F(ExitCodeCli, EveryOtherCommandRefusesUnusableInputsWithExitTwo) {
  const std::string pair = " --left " + Scene("left.png") + " --right " + Scene("right.png");
  ExpectError("probe --left " + Path("nope.png") + " --right " + Scene("right.png") + " --calib " +
                  Scene("calib.yml") + " --point 320,240",
              2, {"--left: ", Path("nope.png")});
  ExpectError("probe" + pair + " --calib " + Scene("left.png") + " --point 320,240", 2,
              {"--calib: ", Scene("left.png")});
  ExpectError("probe --left " + kTeddyDir + "/im2.png --right " + kTeddyDir + "/im6.png --calib " +
                  Scene("calib.yml") + " --point 20,20",
              2, {"--calib '" + Scene("calib.yml") + "'"});
  ExpectError("eval --dataset " + Path("nope") + " --out " + Path("out.json"), 2,
              {"--dataset: ", Path("nope")});
  ExpectError("bench --out " + Path("out.json") + " --left " + Path("nope.png"), 2,
              {"--left: ", Path("nope.png")});
  ExpectError("bench --out " + Path("out.json") + " --ground-truth " + Path("nope.png"), 2,
              {"--ground-truth: ", Path("nope.png")});
  ExpectError("bench --out " + Path("out.json") + " --left " + Scene("left.png"), 2,
              {"differ in size"});
  std::ofstream(Path("objects.json")) << "{\"units\": \"mm\", \"objects\": []}\n";
  ExpectError("view --objects " + Path("objects.json") + " --left " + Path("nope.png") +
                  " --duration 0.1",
              2, {"--left: ", Path("nope.png")});
  ExpectError("view --objects " + Path("objects.json") + " --left " + Scene("left.png") +
                  " --calib " + Scene("left.png") + " --duration 0.1",
              2, {"--calib: ", Scene("left.png")});
  std::ofstream(Path("broken.json")) << "{\"objects\": [";
  ASSERT_EQ(RunCli("robot thesis-frame --quiet --out " + Path("frame.yml")).exit_code, 0);
  ExpectError("serve --replay " + Path("broken.json") + " --frame " + Path("frame.yml") +
                  " --robot dryrun:" + Path("d.jsonl") + " --cycles 1",
              2, {"--replay: "});
  EXPECT_FALSE(fs::exists(Path("d.jsonl")));
  ExpectError("view --objects " + Path("broken.json") + " --left " + Scene("left.png") +
                  " --duration 0.1",
              2, {"--objects '" + Path("broken.json") + "'"});
}

}  // namespace
