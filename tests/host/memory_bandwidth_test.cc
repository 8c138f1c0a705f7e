// perf/memory_bandwidth.h: the host's streaming read probe reads every element (the probe
// checks its sums) and reports a plausible bandwidth.
#include <gtest/gtest.h>

#include <thread>

#include "perf/memory_bandwidth.h"

namespace hnnstereo::perf {
namespace {

TEST(MachineReadBandwidth, ReadsTheWholeArrayAtAPlausibleRate) {
  for (const int threads : {1, 2, 3}) {
    ReadBandwidthOptions options;
    options.bytes = (std::size_t{16} << 20) + 100;  // not a multiple of a thread's stride
    options.threads = threads;
    options.repeats = 3;
    const ReadBandwidth result = MeasureReadBandwidth(options);
    EXPECT_GT(result.gbps, 0.1);      // far below any machine's
    EXPECT_LT(result.gbps, 20000.0);  // far above any memory's: a loop that skipped its reads
    EXPECT_GE(result.gbps, result.median_gbps);
    EXPECT_EQ(result.threads, threads);
    EXPECT_GT(result.bytes, std::size_t{15} << 20);
    EXPECT_LE(result.bytes, options.bytes);
    EXPECT_NE(result.method.find("64-byte"), std::string::npos) << result.method;
  }
}

TEST(MachineReadBandwidth, DefaultsToEveryCore) {
  ReadBandwidthOptions options;
  options.bytes = std::size_t{4} << 20;
  options.repeats = 1;
  EXPECT_EQ(MeasureReadBandwidth(options).threads,
            std::max(1, static_cast<int>(std::thread::hardware_concurrency())));
}

}  // namespace
}  // namespace hnnstereo::perf
