// Every value a command's help allows works, and a value it does not is refused in one line:
// render --objects up to 30, devices --device, --device with an engine that runs on the host.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;

using hnnstereo::testing::CliResult;
using hnnstereo::testing::CliTest;
using hnnstereo::testing::kTeddyDir;
using hnnstereo::testing::RunCli;

class FlagValuesCli : public CliTest {
 protected:
  // Exit 2, one "hnnstereo: error:" line holding `reason`.
  static void ExpectRefused(const CliResult& result, const std::string& reason) {
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_EQ(result.output.rfind("hnnstereo: error: ", 0), 0u) << result.output;
    EXPECT_EQ(std::count(result.output.begin(), result.output.end(), '\n'), 1) << result.output;
    EXPECT_NE(result.output.find(reason), std::string::npos) << result.output;
  }
};

// The help says 1-30; 30 parts once failed with "cannot place part 13 of 30". At the default
// sizes they fit with smaller top faces; sizes the caller chose are kept and a count that does
// not fit them is refused.
TEST_F(FlagValuesCli, RenderPlacesThirtyParts) {
  const CliResult result = RunCli("render --seed 1 --objects 30 --out " + Path("s30"));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("30 parts fit with top faces and gap scaled by"), std::string::npos)
      << result.output;
  const nlohmann::json truth = nlohmann::json::parse(std::ifstream(Path("s30/truth.json")));
  EXPECT_EQ(truth["objects"].size(), 30u);
  const CliResult kept =
      RunCli("render --seed 1 --objects 30 --size-range 25,75 --out " + Path("kept"));
  ExpectRefused(kept, "--size-range and --min-gap");
  EXPECT_FALSE(fs::exists(Path("kept")));
}

TEST_F(FlagValuesCli, DevicesShowsTheDeviceAskedFor) {
  const CliResult all = RunCli("devices");
  ASSERT_EQ(all.exit_code, 0) << all.output;
  ExpectRefused(RunCli("devices --device 5"), "--device '5'");
  if (all.output.find("no OpenCL device") != std::string::npos) return;
  const CliResult one = RunCli("devices --device 0");
  ASSERT_EQ(one.exit_code, 0) << one.output;
  EXPECT_NE(one.output.find("  device 0: "), std::string::npos) << one.output;
  EXPECT_EQ(one.output.find("  device 1: "), std::string::npos) << one.output;
  EXPECT_NE(one.output.find("in use: "), std::string::npos) << one.output;
}

TEST_F(FlagValuesCli, DeviceIsRefusedForTheEnginesOnTheHost) {
  for (const std::string engine : {"cpu", "thesis"}) {
    ExpectRefused(RunCli("match --left " + kTeddyDir + "/im2.png --right " + kTeddyDir +
                         "/im6.png --rectified --engine " + engine + " --device 3 --out " +
                         Path("m.csv")),
                  "--device '3' is for --engine opencl");
    EXPECT_FALSE(fs::exists(Path("m.csv")));
  }
  ExpectRefused(RunCli("demo --engine cpu --device 3 --out " + Path("demo")),
                "--device '3' is for --engine opencl");
  ExpectRefused(RunCli("eval --dataset " + kTeddyDir + " --engine cpu --device 3 --out " +
                       Path("e.json")),
                "--device '3' is for --engine opencl");
  EXPECT_FALSE(fs::exists(Path("demo")));
  EXPECT_FALSE(fs::exists(Path("e.json")));
}

}  // namespace
