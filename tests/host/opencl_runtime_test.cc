// Runtime::ScratchBuffer: a buffer kept per purpose and grown when asked for more. On a CPU
// device a large one (Runtime::NewBuffer) lies over host memory of its own, 2 MB aligned and
// advised as huge pages; it must hold what a kernel writes and what the host writes, across a
// growth, at sizes on both sides of that threshold.
#include <gtest/gtest.h>
#include <sched.h>
#include <unistd.h>

#include <cstddef>
#include <cstdlib>
#include <numeric>
#include <string>
#include <vector>

#include "host/opencl_runtime.h"

namespace hnnstereo::ocl {
namespace {

// Writes value + index into every int of `buffer` with a kernel, then reads it all back.
std::vector<int> FillOnDevice(Runtime& runtime, const cl::Buffer& buffer, std::size_t count,
                              int value) {
  static const char* kSource =
      "__kernel void fill(__global int* out, const int value) {"
      "  const size_t i = get_global_id(0); out[i] = value + (int)i; }";
  cl::Program program(runtime.context(), kSource);
  program.build();
  cl::Kernel kernel(program, "fill");
  kernel.setArg(0, buffer);
  kernel.setArg(1, value);
  runtime.queue().enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(count));
  std::vector<int> out(count);
  runtime.queue().enqueueReadBuffer(buffer, CL_TRUE, 0, sizeof(int) * count, out.data());
  return out;
}

// The runtime pins PoCL's worker threads (POCL_AFFINITY=1, host/opencl_runtime.cc) before the
// first OpenCL call where the process may run on every online CPU, never over a value already
// set, and not where it may not: run under `taskset -c 1` the variable stays unset.
TEST(Runtime, PinsPoclWorkersOnlyWhereEveryCpuIsAllowed) {
  const char* before = std::getenv("POCL_AFFINITY");
  const std::string given = before ? before : "";
  const long online = sysconf(_SC_NPROCESSORS_ONLN);
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  ASSERT_EQ(sched_getaffinity(0, sizeof allowed, &allowed), 0);
  bool every_cpu = std::getenv("POCL_CPU_MAX_CU_COUNT") == nullptr;
  for (long cpu = 0; cpu < online; ++cpu) every_cpu = every_cpu && CPU_ISSET(cpu, &allowed);
  std::string why_not;
  auto runtime = Runtime::Create(DeviceSelection::FromEnvironment(), &why_not);
  const char* after = std::getenv("POCL_AFFINITY");
  if (before) {
    ASSERT_NE(after, nullptr);
    EXPECT_EQ(std::string(after), given);
  } else if (every_cpu) {
    ASSERT_NE(after, nullptr);
    EXPECT_EQ(std::string(after), "1");
  } else {
    EXPECT_EQ(after, nullptr);
  }
}

TEST(ScratchBuffer, HoldsWhatIsWrittenAcrossGrowthAndSizes) {
  std::string why_not;
  auto runtime = Runtime::Create(DeviceSelection::FromEnvironment(), &why_not);
  if (!runtime) GTEST_SKIP() << "no OpenCL device: " << why_not;
  // 1 MB (a plain device buffer), then 24 MB and 40 MB (own host memory on a CPU device).
  int value = 7;
  for (const std::size_t bytes :
       {std::size_t{1} << 20, std::size_t{24} << 20, std::size_t{40} << 20}) {
    const std::size_t count = bytes / sizeof(int);
    const cl::Buffer buffer = runtime->ScratchBuffer("test", bytes);
    std::vector<int> host(count);
    std::iota(host.begin(), host.end(), -value);
    runtime->queue().enqueueWriteBuffer(buffer, CL_TRUE, 0, bytes, host.data());
    std::vector<int> back(count);
    runtime->queue().enqueueReadBuffer(buffer, CL_TRUE, 0, bytes, back.data());
    ASSERT_EQ(back, host) << bytes << " bytes, host write";
    const std::vector<int> filled = FillOnDevice(*runtime, buffer, count, value);
    for (std::size_t i = 0; i < count; i += 4099) {
      ASSERT_EQ(filled[i], value + static_cast<int>(i))
          << bytes << " bytes, kernel write, int " << i;
    }
    ASSERT_EQ(filled.back(), value + static_cast<int>(count - 1));
    // A smaller request of the same purpose gets the same buffer, contents kept.
    const cl::Buffer again = runtime->ScratchBuffer("test", bytes / 2);
    EXPECT_EQ(again(), buffer());
    std::vector<int> kept(count / 2);
    runtime->queue().enqueueReadBuffer(again, CL_TRUE, 0, bytes / 2, kept.data());
    EXPECT_EQ(kept[12345], value + 12345);
    value += 100;
  }
}

}  // namespace
}  // namespace hnnstereo::ocl
