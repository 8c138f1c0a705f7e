// Bad setups are refused before any work, in one line naming the argument: one image given
// twice (match, pick, probe, serve), a disparity range beyond the image width, outputs that
// cannot be written, a device that does not exist. And one CLI style: the command list, exit
// codes, --config errors naming the file and the key, --quiet everywhere.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;

using hnnstereo::testing::CliResult;
using hnnstereo::testing::kTeddyDir;
using hnnstereo::testing::RunCli;

const std::string kLeft = kTeddyDir + "/im2.png";
const std::string kRight = kTeddyDir + "/im6.png";

// One rendered scene shared by the tests (rendering is the slow part).
class SetupCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("hnnstereo_setup_cli_" + std::to_string(::getpid()));
    render_ = RunCli("render --seed 5 --objects 3 --out " + scene_.string());
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }
  void SetUp() override {
    dir_ = scene_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(dir_);
  }
  std::string Scene(const std::string& name) const { return (scene_ / name).string(); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  // Runs a command; `seconds` receives the CPU time it used (user + system), which does not
  // depend on how many other builds share the machine.
  CliResult Timed(const std::string& arguments, double* seconds, const std::string& env = "") {
    const auto cpu = [] {
      rusage usage{};
      getrusage(RUSAGE_CHILDREN, &usage);
      return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
             1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    };
    const double before = cpu();
    CliResult result = RunCli(arguments, env);
    *seconds = cpu() - before;
    return result;
  }
  // Failed with exit `code`, one "hnnstereo: error:" line holding `reason`, nothing written.
  void ExpectRefused(const CliResult& result, int code, const std::string& reason) const {
    EXPECT_EQ(result.exit_code, code) << result.output;
    EXPECT_EQ(result.output.rfind("hnnstereo: error: ", 0), 0u) << result.output;
    EXPECT_NE(result.output.find(reason), std::string::npos) << result.output;
    EXPECT_EQ(std::count(result.output.begin(), result.output.end(), '\n'), 1) << result.output;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      EXPECT_EQ(entry.path().filename().string().rfind("input", 0), 0u)
          << "a refused command wrote " << entry.path();
    }
  }
  static fs::path scene_;
  static CliResult render_;
  fs::path dir_;
};

fs::path SetupCli::scene_;
CliResult SetupCli::render_;

TEST_F(SetupCli, MatchRefusesOneImageTwiceAtOnce) {
  double seconds = 0;
  ExpectRefused(Timed("match --left " + kLeft + " --right " + kLeft + " --rectified --out " +
                          Path("m.csv"),
                      &seconds),
                2, "--left and --right are identical");
  EXPECT_LT(seconds, 1.0);
  // Uncalibrated: it once "estimated" F from 1,318 of 1,318 inliers at 0.00 px.
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + kLeft + " --out " + Path("m.csv")),
                2, "identical");
  // A noisy copy is one image twice too.
  cv::Mat noisy = cv::imread(kLeft, cv::IMREAD_GRAYSCALE), noise(noisy.size(), CV_8S);
  cv::randn(noise, 0, 3);
  cv::add(noisy, noise, noisy, cv::noArray(), CV_8U);
  cv::imwrite(Path("input_noisy.png"), noisy);
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + Path("input_noisy.png") +
                       " --rectified --out " + Path("m.csv")),
                2, "nearly identical");
}

TEST_F(SetupCli, PickAndProbeRefuseOneImageTwice) {
  ASSERT_EQ(render_.exit_code, 0) << render_.output;
  double seconds = 0;
  ExpectRefused(Timed("pick --left " + Scene("left.png") + " --right " + Scene("left.png") +
                          " --calib " + Scene("calib.yml") + " --out " + Path("o.json"),
                      &seconds),
                2, "--left and --right are identical");
  EXPECT_LT(seconds, 1.0);
  ExpectRefused(RunCli("probe --left " + Scene("left.png") + " --right " + Scene("left.png") +
                       " --calib " + Scene("calib.yml") + " --point 320,240"),
                2, "identical");
}

TEST_F(SetupCli, ServePublishesASensingErrorAndSendsNothingForOneImageTwice) {
  ASSERT_EQ(render_.exit_code, 0) << render_.output;
  std::ofstream(Path("input_frame.yml"))
      << "%YAML:1.0\n---\nrobot_from_world: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n"
         "   data: [ 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1. ]\n"
         "workspace_min: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
         "   data: [ -1000., -1000., -100. ]\n"
         "workspace_max: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
         "   data: [ 1000., 1000., 1000. ]\nrms_mm: 0.\n";
  const CliResult served =
      RunCli("serve --left " + Scene("left.png") + " --right " + Scene("left.png") + " --calib " +
             Scene("calib.yml") + " --frame " + Path("input_frame.yml") + " --robot dryrun:" +
             Path("input_picks.jsonl") + " --cycles 1");
  ASSERT_EQ(served.exit_code, 0) << served.output;
  std::ifstream in(Path("input_picks.jsonl"));
  std::string line;
  int cycles = 0;
  while (std::getline(in, line)) {
    const nlohmann::json json = nlohmann::json::parse(line);
    EXPECT_NE(json["type"], "pick") << "a pose was sent: " << line;
    if (json["type"] == "cycle") {
      ++cycles;
      EXPECT_EQ(json["status"], -1) << line;
      EXPECT_NE(json["error"].get<std::string>().find("identical"), std::string::npos) << line;
    }
  }
  EXPECT_EQ(cycles, 1);
}

TEST_F(SetupCli, SwappedRectifiedPairIsSaid) {
  const CliResult result = RunCli("match --left " + kRight + " --right " + kLeft +
                                  " --rectified --engine cpu --max-features 1500 --quiet --out " + Path("m.csv"));
  EXPECT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("hnnstereo: warning: --left and --right look swapped"),
            std::string::npos)
      << result.output;
  const CliResult straight = RunCli("match --left " + kLeft + " --right " + kRight +
                                    " --rectified --engine cpu --max-features 1500 --quiet --out " + Path("m2.csv"));
  EXPECT_EQ(straight.exit_code, 0) << straight.output;
  EXPECT_EQ(straight.output.find("swapped"), std::string::npos) << straight.output;
}

// A cell pair given right-left found no part and said nothing; now it says why.
TEST_F(SetupCli, PickSaysWhenTheImagesLookSwapped) {
  ASSERT_EQ(render_.exit_code, 0) << render_.output;
  const CliResult result = RunCli("pick --left " + Scene("right.png") + " --right " +
                                  Scene("left.png") + " --calib " + Scene("calib.yml") +
                                  " --out " + Path("o.json"));
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find("hnnstereo: error: no parts, and --left and --right look swapped"),
            std::string::npos)
      << result.output;
  EXPECT_FALSE(fs::exists(Path("o.json")));
}

TEST_F(SetupCli, DisparityBeyondTheImageWidthIsRefusedAtOnce) {
  for (const std::string range : {"--max-disparity 1e9", "--max-disparity 1e6",
                                  "--max-disparity 450", "--min-disparity -1e9"}) {
    double seconds = 0;
    ExpectRefused(Timed("match --left " + kLeft + " --right " + kRight + " --rectified " + range +
                            " --out " + Path("m.csv"),
                        &seconds),
                  2, range.substr(0, range.find(' ')) + " ");
    EXPECT_LT(seconds, 1.0) << range;
  }
}

TEST_F(SetupCli, UnwritableOutputsAreRefusedBeforeWork) {
  std::ofstream(Path("input_file.txt")) << "x";
  const std::string match = "match --left " + kLeft + " --right " + kRight + " --rectified ";
  double seconds = 0;
  // The last output is the bad one: nothing at all is written, and no matching is done.
  ExpectRefused(Timed(match + "--out " + Path("m.csv") + " --report " + Path("r.json") +
                          " --overlay " + Path("input_file.txt/o.png"),
                      &seconds),
                2, "--overlay '" + Path("input_file.txt/o.png") + "'");
  EXPECT_LT(seconds, 1.0);
  ExpectRefused(RunCli(match + "--out " + Path("missing/m.csv")), 2, "does not exist");
  ExpectRefused(RunCli(match + "--out " + dir_.string()), 2, "is a folder");
  ExpectRefused(RunCli(match + "--out " + Path("m.csv") + " --report " + Path("m.csv")), 2,
                "also another output");
  ExpectRefused(RunCli(match + "--out " + Path("m.csv") + " --overlay " + kLeft), 2,
                "--overlay '" + kLeft + "' would overwrite the input --left");
  ASSERT_EQ(render_.exit_code, 0) << render_.output;
  ExpectRefused(RunCli("pick --left " + Scene("left.png") + " --right " + Scene("right.png") +
                       " --calib " + Scene("calib.yml") + " --out " + Path("o.json") + " --ply " +
                       Path("input_file.txt/p.ply")),
                2, "--ply");
  ExpectRefused(RunCli("calibrate --target circles --dir " + Scene("target") + " --out " +
                       Path("missing/cal.yml")),
                2, "--out");
  ExpectRefused(RunCli("render --seed 1 --out " + Path("input_file.txt")), 2, "is a file");
  ExpectRefused(RunCli("render --seed 1 --resolution 1280*1024 --out " + Path("r")), 2,
                "--resolution must be WIDTHxHEIGHT");
  ExpectRefused(RunCli("render --seed 1 --resolution 20x20 --out " + Path("r")), 2,
                "--resolution: the image size must be 64-8192 px");
  EXPECT_FALSE(fs::exists(Path("r")));
}

TEST_F(SetupCli, ADeviceThatDoesNotExistIsAnError) {
  const std::string match = "match --left " + kLeft + " --right " + kRight +
                            " --rectified --out " + Path("m.csv");
  const CliResult asked = RunCli(match + " --device no-such-device");
  ExpectRefused(asked, 2, "--device 'no-such-device': no OpenCL device matches");
  const CliResult from_env = RunCli(match, "HNNSTEREO_OPENCL_DEVICE=no-such-device");
  ExpectRefused(from_env, 2, "HNNSTEREO_OPENCL_DEVICE='no-such-device'");
  ExpectRefused(RunCli(match + " --device 99"), 2, "there are: ");
}

TEST_F(SetupCli, DevicesListsWhatToPass) {
  const CliResult result = RunCli("devices");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const bool none = result.output.find("no OpenCL device") != std::string::npos;
  if (!none) {
    EXPECT_NE(result.output.find("platform 0: "), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("  device 0: "), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("in use: "), std::string::npos) << result.output;
  }
  EXPECT_NE(RunCli("devices", "HNNSTEREO_OPENCL_DEVICE=no-such-device").exit_code, 0);
  const CliResult quiet = RunCli("devices --quiet");
  EXPECT_EQ(quiet.exit_code, 0);
  EXPECT_EQ(quiet.output, "");
}

TEST_F(SetupCli, NoOrAnUnknownCommandPrintsTheCommandList) {
  for (const std::string arguments : {"", "frobnicate"}) {
    const CliResult result = RunCli(arguments);
    EXPECT_EQ(result.exit_code, 2) << result.output;
    for (const char* command : {"match", "pick", "serve", "devices", "calibrate"}) {
      EXPECT_NE(result.output.find(command), std::string::npos) << command << result.output;
    }
    EXPECT_NE(result.output.find("Usage: hnnstereo"), std::string::npos) << result.output;
  }
  EXPECT_NE(RunCli("frobnicate").output.find("hnnstereo: error: unknown command 'frobnicate'"),
            std::string::npos);
}

TEST_F(SetupCli, ArgumentErrorsAreOneLineWithThePrefix) {
  ExpectRefused(RunCli("match --left " + kLeft), 2, "--right");
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + kRight + " --out " + Path("m.csv") +
                       " --max-disparity lots"),
                2, "--max-disparity");
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + kRight + " --out " + Path("m.csv") +
                       " --no-such-option"),
                2, "--no-such-option");
}

TEST_F(SetupCli, ConfigFileErrorsNameTheFileAndTheKey) {
  std::ofstream(Path("input_typo.yml")) << "# options\nmax_disparty: 64\n";
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + kRight + " --rectified --out " +
                       Path("m.csv") + " --config " + Path("input_typo.yml")),
                2, "config file '" + Path("input_typo.yml") + "' line 2, key 'max-disparty'");
  std::ofstream(Path("input_value.yml")) << "max_disparity: lots\n";
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + kRight + " --rectified --out " +
                       Path("m.csv") + " --config " + Path("input_value.yml")),
                2, "line 1, key 'max-disparity'");
  ExpectRefused(RunCli("match --left " + kLeft + " --right " + kRight + " --rectified --out " +
                       Path("m.csv") + " --config " + Path("input_none.yml")),
                2, "--config file '" + Path("input_none.yml") + "' cannot be read");
}

// Description, usage naming the program, options, then examples - the same for every command.
TEST_F(SetupCli, HelpIsLaidOutTheSameWayEverywhere) {
  for (const std::string command :
       {"match", "calibrate", "render", "pick", "serve", "demo", "probe", "devices"}) {
    const std::string help = RunCli(command + " --help").output;
    const auto usage = help.find("Usage: hnnstereo " + command);
    const auto options = help.find("Options:");
    ASSERT_NE(usage, std::string::npos) << command << help;
    EXPECT_GT(usage, 0u) << command << ": the description comes first";
    EXPECT_LT(usage, options) << command;
    const auto example = help.find("Example");
    EXPECT_NE(example, std::string::npos) << command << ": no example";
    EXPECT_GT(example, options) << command << ": the examples follow the options";
  }
}

TEST_F(SetupCli, EveryCommandTakesQuiet) {
  const CliResult help = RunCli("--help");
  for (const std::string command :
       {"match", "calibrate", "bench", "eval", "render", "pick", "serve", "demo", "probe",
        "devices", "robot fit-frame", "robot thesis-frame", "robot show-frame", "robot send"}) {
    const CliResult result = RunCli(command + " --help");
    EXPECT_EQ(result.exit_code, 0) << command;
    EXPECT_NE(result.output.find("--quiet"), std::string::npos) << command;
  }
  ASSERT_EQ(render_.exit_code, 0) << render_.output;
  const CliResult probe = RunCli("probe --left " + Scene("left.png") + " --right " +
                                 Scene("right.png") + " --calib " + Scene("calib.yml") +
                                 " --point 320,240 --quiet");
  EXPECT_EQ(probe.output, "") << probe.output;
}

}  // namespace
