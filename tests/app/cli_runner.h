#pragma once
// Runs the hnnstereo executable for command-line contract tests, and a per-test scratch folder.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace hnnstereo::testing {

struct CliResult {
  int exit_code;
  std::string output;  ///< stdout and stderr together
};

/// Runs `HNNSTEREO_BINARY arguments` with optional `VAR=value ...` environment prefix.
inline CliResult RunCli(const std::string& arguments, const std::string& environment = "") {
  namespace fs = std::filesystem;
  const fs::path log =
      fs::temp_directory_path() / ("hnnstereo_cli_" + std::to_string(::getpid()) + ".log");
  const std::string command = environment + " " + HNNSTEREO_BINARY + " " + arguments + " > " +
                              log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream in(log);
  std::stringstream text;
  text << in.rdbuf();
  fs::remove(log);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text.str()};
}

/// A fixture with an empty scratch folder per test.
class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("hnnstereo_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->test_suite_name() + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

inline const std::string kTeddyDir = std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy";

}  // namespace hnnstereo::testing
