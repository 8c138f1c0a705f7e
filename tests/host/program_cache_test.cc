// The on-disk program binary cache: round trip, key check, corrupt entries, racing writers, and
// a real OpenCL program loaded back from its cached binary.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include "host/opencl_engine.h"
#include "host/opencl_runtime.h"
#include "host/program_cache.h"

namespace hnnstereo::ocl {
namespace {

std::string ScratchDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("hnnstereo_program_cache_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir.string();
}

TEST(ProgramCache, RoundTripAndKeyCheck) {
  const std::string dir = ScratchDir("roundtrip");
  const std::string entry = ProgramCacheEntryName("dev", "1.2", "drv", "abc", "-DX=1");
  EXPECT_NE(entry, ProgramCacheEntryName("dev", "1.2", "drv", "abc", "-DX=2"));
  EXPECT_NE(entry, ProgramCacheEntryName("dev", "1.2", "drv2", "abc", "-DX=1"));
  EXPECT_FALSE(ReadCachedProgram(dir, entry, "key").has_value());  // nothing yet
  const std::vector<unsigned char> binary = {1, 2, 3, 0, 255, 7};
  WriteCachedProgram(dir, entry, "key", binary);
  const auto back = ReadCachedProgram(dir, entry, "key");
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(*back, binary);
  // Another key under the same file name (a hash collision) is not served.
  EXPECT_FALSE(ReadCachedProgram(dir, entry, "other key").has_value());
  // No temporary files left behind.
  int files = 0;
  for (const auto& file : std::filesystem::directory_iterator(dir)) {
    EXPECT_EQ(file.path().extension(), ".bin");
    ++files;
  }
  EXPECT_EQ(files, 1);
  std::filesystem::remove_all(dir);
}

TEST(ProgramCache, CorruptEntryIsIgnored) {
  const std::string dir = ScratchDir("corrupt");
  std::filesystem::create_directories(dir);
  const std::string entry = ProgramCacheEntryName("d", "v", "r", "h", "o");
  std::ofstream(dir + "/" + entry) << "garbage";
  EXPECT_FALSE(ReadCachedProgram(dir, entry, "key").has_value());
  std::ofstream(dir + "/" + entry, std::ios::trunc);  // empty file
  EXPECT_FALSE(ReadCachedProgram(dir, entry, "key").has_value());
  std::filesystem::remove_all(dir);
}

TEST(ProgramCache, RacingWritersLeaveOneValidEntry) {
  const std::string dir = ScratchDir("race");
  const std::string entry = ProgramCacheEntryName("d", "v", "r", "h", "o");
  std::vector<unsigned char> binary(1 << 20);
  for (std::size_t i = 0; i < binary.size(); ++i) binary[i] = static_cast<unsigned char>(i * 7);
  std::vector<std::thread> writers;
  for (int t = 0; t < 8; ++t) {
    writers.emplace_back([&] {
      for (int r = 0; r < 5; ++r) WriteCachedProgram(dir, entry, "key", binary);
    });
  }
  // Readers during the race see either nothing or the whole binary, never a torn one.
  for (int r = 0; r < 50; ++r) {
    if (auto back = ReadCachedProgram(dir, entry, "key")) {
      ASSERT_EQ(back->size(), binary.size());
    }
  }
  for (std::thread& w : writers) w.join();
  const auto back = ReadCachedProgram(dir, entry, "key");
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(*back, binary);
  std::filesystem::remove_all(dir);
}

TEST(ProgramCache, OffDisablesIt) {
  ::setenv("HNNSTEREO_KERNEL_CACHE", "off", 1);
  EXPECT_TRUE(ProgramCacheDirectory().empty());
  ::setenv("HNNSTEREO_KERNEL_CACHE", "/tmp/somewhere", 1);
  EXPECT_EQ(ProgramCacheDirectory(), "/tmp/somewhere");
  ::unsetenv("HNNSTEREO_KERNEL_CACHE");
}

TEST(ProgramCache, ServesEveryPlatformButPocl) {
  EXPECT_FALSE(ProgramCacheServes("Portable Computing Language"));
  EXPECT_TRUE(ProgramCacheServes("NVIDIA CUDA"));
  EXPECT_TRUE(ProgramCacheServes("Intel(R) OpenCL"));
}

// A second runtime (a new process, as far as the program cache knows) builds the hopfield
// program from the cached binary, and it runs. On PoCL nothing is stored (ProgramCacheServes):
// the second runtime builds from PoCL's own cache.
TEST(ProgramCache, SecondRuntimeLoadsTheCachedBinary) {
  const std::string dir = ScratchDir("opencl");
  ::setenv("HNNSTEREO_KERNEL_CACHE", dir.c_str(), 1);
  std::string why_not;
  auto first = Runtime::Create(DeviceSelection::FromEnvironment(), &why_not);
  if (!first) {
    ::unsetenv("HNNSTEREO_KERNEL_CACHE");
    GTEST_SKIP() << "no OpenCL device: " << why_not;
  }
  first->Program("hopfield", "-DOBJECTIVE=4");
  int entries = 0;
  if (std::filesystem::exists(dir)) {
    for ([[maybe_unused]] const auto& file : std::filesystem::directory_iterator(dir)) ++entries;
  }
  const std::string platform =
      cl::Platform(first->device().getInfo<CL_DEVICE_PLATFORM>()).getInfo<CL_PLATFORM_NAME>();
  EXPECT_EQ(entries, ProgramCacheServes(platform) ? 1 : 0) << platform;
  auto second = Runtime::Create(DeviceSelection::FromEnvironment(), &why_not);
  ASSERT_TRUE(second);
  const cl::Program& program = second->Program("hopfield", "-DOBJECTIVE=4");
  cl::Kernel kernel(program, "neuron_euler");  // the kernels are there
  EXPECT_EQ(kernel.getInfo<CL_KERNEL_FUNCTION_NAME>(), "neuron_euler");
  ::unsetenv("HNNSTEREO_KERNEL_CACHE");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace hnnstereo::ocl
