// No command ever overwrites one of its inputs, and a dry-run loop cannot fill a disk
// (app/cli_support.h RefuseOutputsOverInputs, robot/cell_loop.h min_cycle_period): every output
// option and a dryrun: link's file against every input file or folder, resolved paths.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;

using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// One rendered scene (with its circle target) shared by the tests.
class NoOverwriteCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("hnnstereo_no_overwrite_" + std::to_string(::getpid()));
    render_ = RunCli("render --seed 5 --objects 3 --out " + scene_.string());
    const CliResult fit = RunCli(
        "robot thesis-frame --out " + (scene_ / "frame.yml").string());
    frame_ok_ = fit.exit_code == 0;
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }
  void SetUp() override {
    ASSERT_EQ(render_.exit_code, 0) << render_.output;
    ASSERT_TRUE(frame_ok_);
  }
  static std::string Scene(const std::string& name) { return (scene_ / name).string(); }
  std::string Pair() const {
    return " --left " + Scene("left.png") + " --right " + Scene("right.png") + " --calib " +
           Scene("calib.yml");
  }
  // Refused before any work: exit 2, one error line naming `reason`, and `input` unchanged.
  void ExpectRefusedAndUnchanged(const std::string& arguments, const std::string& reason,
                                 const fs::path& input) {
    const std::string before = ReadAll(input);
    ASSERT_FALSE(before.empty()) << input;
    const CliResult result = RunCli(arguments);
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_EQ(result.output.rfind("hnnstereo: error: ", 0), 0u) << result.output;
    EXPECT_NE(result.output.find(reason), std::string::npos) << result.output;
    EXPECT_EQ(ReadAll(input), before) << input << " was changed by: " << arguments;
  }
  static fs::path scene_;
  static CliResult render_;
  static bool frame_ok_;
};

fs::path NoOverwriteCli::scene_;
CliResult NoOverwriteCli::render_;
bool NoOverwriteCli::frame_ok_ = false;

TEST_F(NoOverwriteCli, ADryRunFileIsNeverAnInput) {
  ExpectRefusedAndUnchanged("pick" + Pair() + " --out " + Scene("o.json") + " --frame " +
                                Scene("frame.yml") + " --robot dryrun:" + Scene("left.png"),
                            "--robot '" + Scene("left.png") + "' would overwrite the input --left",
                            Scene("left.png"));
  ExpectRefusedAndUnchanged("serve" + Pair() + " --frame " + Scene("frame.yml") +
                                " --robot dryrun:" + Scene("calib.yml") + " --cycles 1",
                            "would overwrite the input --calib", Scene("calib.yml"));
  // Resolved paths: ./x and x, a/../a/x are the same file.
  const fs::path cwd = fs::current_path();
  fs::current_path(scene_);
  ExpectRefusedAndUnchanged("serve" + Pair() + " --frame frame.yml --robot dryrun:./frame.yml "
                                "--cycles 1",
                            "would overwrite the input --frame", Scene("frame.yml"));
  fs::current_path(cwd);
}

TEST_F(NoOverwriteCli, CalibrateNeverWritesOverItsTarget) {
  const fs::path target = scene_ / "target";
  ASSERT_TRUE(fs::is_directory(target));
  fs::path description;
  for (const auto& entry : fs::directory_iterator(target)) {
    if (entry.path().extension() == ".yml") description = entry.path();
  }
  ASSERT_FALSE(description.empty()) << "render writes the target's description";
  const std::string calibrate = "calibrate --target circles --dir " + target.string();
  ExpectRefusedAndUnchanged(calibrate + " --out " + description.string(),
                            "would overwrite a file of the input folder --dir", description);
  ExpectRefusedAndUnchanged(calibrate + " --out " + Scene("new.yml") + " --report " +
                                description.string(),
                            "--report", description);
  EXPECT_FALSE(fs::exists(Scene("new.yml")));
}

TEST_F(NoOverwriteCli, EveryOutputOptionIsGuarded) {
  ExpectRefusedAndUnchanged("pick" + Pair() + " --out " + Scene("o.json") + " --histogram " +
                                Scene("right.png"),
                            "--histogram '" + Scene("right.png") + "' would overwrite the input",
                            Scene("right.png"));
  std::ofstream(Scene("options.yml")) << "max-disparity: 40\n";
  ExpectRefusedAndUnchanged("match" + Pair() + " --config " + Scene("options.yml") + " --out " +
                                Scene("options.yml"),
                            "would overwrite the input --config", Scene("options.yml"));
}

TEST_F(NoOverwriteCli, ADryRunFileIsAppendedToNotTruncated) {
  const fs::path picks = scene_ / "append.jsonl";
  std::ofstream(picks) << "{\"type\":\"earlier\"}\n";
  const CliResult served =
      RunCli("serve" + Pair() + " --frame " + Scene("frame.yml") + " --robot dryrun:" +
             picks.string() + " --cycles 1 --quiet");
  ASSERT_EQ(served.exit_code, 0) << served.output;
  const std::string text = ReadAll(picks);
  EXPECT_EQ(text.rfind("{\"type\":\"earlier\"}\n", 0), 0u) << text;
  EXPECT_NE(text.find("\"type\":\"cycle\""), std::string::npos) << text;
}

TEST_F(NoOverwriteCli, ServeRefusesMissingImagesBeforeListening) {
  const fs::path picks = scene_ / "spin.jsonl";
  const CliResult result = RunCli("serve --left " + Scene("nope.png") + " --right " +
                                  Scene("right.png") + " --calib " + Scene("calib.yml") +
                                  " --frame " + Scene("frame.yml") + " --robot dryrun:" +
                                  picks.string());
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_NE(result.output.find("--left '" + Scene("nope.png") + "' does not exist"),
            std::string::npos)
      << result.output;
  EXPECT_FALSE(fs::exists(picks));
}

TEST_F(NoOverwriteCli, ADryRunLoopIsPaced) {
  // Three cycles with --period 0.4 cannot take less than two periods (a lower bound only: a slow
  // machine makes it longer, never shorter).
  const auto start = std::chrono::steady_clock::now();
  const CliResult served =
      RunCli("serve --replay " + Scene("truth.json") + " --frame " + Scene("frame.yml") +
             " --robot dryrun:" + Scene("paced.jsonl") + " --cycles 3 --period 0.4 --quiet");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(served.exit_code, 0) << served.output;
  EXPECT_GE(seconds, 0.8);
  const CliResult negative = RunCli("serve --replay " + Scene("truth.json") + " --frame " +
                                    Scene("frame.yml") + " --cycles 1 --period -1");
  EXPECT_EQ(negative.exit_code, 2) << negative.output;
  EXPECT_NE(negative.output.find("--period"), std::string::npos) << negative.output;
}

}  // namespace
