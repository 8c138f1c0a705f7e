// Torn-file safety: a writer killed with SIGKILL at a random moment leaves the old file or the new
// one, never a mix. The writers are the project's own (WriteFileAtomically for OBJECTS.json,
// MATCHES.csv and the reports; WriteAtomically with cv::FileStorage for CAL.yml; the hnnstereo
// executable itself), each killed at least 100 times. Seeded; the seed is printed.

#include "common/atomic_file.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>
#include <sstream>
#include <string>

#include "calib/calibration.h"
#include "synthetic_rig.h"

namespace hnnstereo::calib {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A scratch folder per test.
fs::path Scratch(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("hnnstereo_kill_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Seconds one call of `write` takes (the mean of a few), to spread the kills over whole writes.
double SecondsPerWrite(const std::function<void(unsigned)>& write) {
  const auto start = std::chrono::steady_clock::now();
  for (unsigned n = 0; n < 4; ++n) write(n);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 4.0;
}

struct KillTally {
  int kills = 0;
  int saw_old = 0;  ///< kills after which the file held the first version
  int saw_new = 0;  ///< ... the second version
};

// Forks `kills` writers that call write(0), write(1), write(2)... forever, kills each with SIGKILL
// after a random delay of up to three writes, and calls check() on the file each time.
KillTally KillWritersAtRandom(int kills, unsigned seed, const std::function<void(unsigned)>& write,
                              const std::function<int()>& check) {
  const double seconds_per_write = SecondsPerWrite(write);
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> delay(0.0, 3.0 * seconds_per_write + 200e-6);
  KillTally tally;
  for (int k = 0; k < kills; ++k) {
    const pid_t child = ::fork();
    if (child < 0) {
      ADD_FAILURE() << "fork failed";
      break;
    }
    if (child == 0) {
      try {
        for (unsigned n = 0;; ++n) write(n);
      } catch (...) {
        ::_exit(3);
      }
    }
    ::usleep(static_cast<useconds_t>(delay(random) * 1e6));
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
        << "the writer stopped on its own (status " << status << ")";
    ++tally.kills;
    const int version = check();
    if (version == 0) ++tally.saw_old;
    if (version == 1) ++tally.saw_new;
    if (::testing::Test::HasFatalFailure()) break;
  }
  return tally;
}

int StaleTemporaries(const fs::path& dir) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    count += entry.path().filename().string().find(".tmp") != std::string::npos ? 1 : 0;
  }
  return count;
}

unsigned Seed() {
  const unsigned seed = static_cast<unsigned>(
      std::chrono::steady_clock::now().time_since_epoch().count() & 0xffffffu);
  std::cout << "seed " << seed << "\n";
  return seed;
}

TEST(AtomicFileKill, WriteFileAtomicallyKilledAtRandomLeavesOldOrNewContents) {
  const fs::path dir = Scratch("bytes");
  const std::string path = (dir / "OBJECTS.json").string();
  // Two versions of different length and filling: any mix of them, or a cut, is neither.
  const std::string versions[2] = {std::string(700 * 1024, 'a') + "\nend of version A\n",
                                   std::string(900 * 1024, 'b') + "\nend of version B\n"};
  WriteFileAtomically(path, versions[0]);
  const KillTally tally = KillWritersAtRandom(
      200, Seed(), [&](unsigned n) { WriteFileAtomically(path, versions[n % 2]); },
      [&]() {
        const std::string now = ReadAll(path);
        if (now == versions[0]) return 0;
        if (now == versions[1]) return 1;
        ADD_FAILURE() << "torn file: " << now.size() << " bytes";
        return -1;
      });
  EXPECT_EQ(tally.kills, 200);
  // Both versions seen: the kills did land between and inside whole writes.
  EXPECT_GT(tally.saw_old, 0);
  EXPECT_GT(tally.saw_new, 0);
  std::cout << tally.kills << " kills: old " << tally.saw_old << ", new " << tally.saw_new
            << ", stale hidden temporaries left " << StaleTemporaries(dir) << "\n";
  fs::remove_all(dir);
}

TEST(AtomicFileKill, SaveCalibrationKilledAtRandomLeavesALoadableOldOrNewCalYml) {
  const fs::path dir = Scratch("calyml");
  const std::string path = (dir / "CAL.yml").string();
  StereoCalibration versions[2];
  for (int v = 0; v < 2; ++v) {
    const testing::StereoRig rig = testing::ThesisRig(1400.0 + 100.0 * v);  // another focal length
    versions[v].P1 = rig.P1;
    versions[v].P2 = rig.P2;
    versions[v].DeriveFromProjections();
    // Enough error figures that a write takes a while (CAL.yml with a long report).
    for (int i = 0; i < 2000; ++i) {
      versions[v].error_figures.emplace_back("figure_" + std::to_string(i), v + i * 1e-3);
    }
  }
  SaveCalibration(versions[0], path);
  const KillTally tally = KillWritersAtRandom(
      100, Seed(), [&](unsigned n) { SaveCalibration(versions[n % 2], path); },
      [&]() {
        try {
          const StereoCalibration now = LoadCalibration(path);
          for (int v = 0; v < 2; ++v) {
            if ((now.P2 - versions[v].P2).norm() < 1e-9) return v;
          }
          ADD_FAILURE() << "CAL.yml holds neither version";
        } catch (const std::exception& e) {
          ADD_FAILURE() << "torn CAL.yml: " << e.what();
        }
        return -1;
      });
  EXPECT_EQ(tally.kills, 100);
  EXPECT_GT(tally.saw_old, 0);
  EXPECT_GT(tally.saw_new, 0);
  std::cout << tally.kills << " kills: old " << tally.saw_old << ", new " << tally.saw_new
            << ", stale hidden temporaries left " << StaleTemporaries(dir) << "\n";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hnnstereo::calib
