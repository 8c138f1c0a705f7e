// perf/device_bandwidth.h: the device's streaming read probe sums every element once (checked
// inside the probe) and reports a plausible bandwidth on the OpenCL device of this machine.
#include <gtest/gtest.h>

#include "perf/device_bandwidth.h"

namespace hnnstereo::perf {
namespace {

TEST(DeviceReadBandwidth, ReadsTheWholeArrayAtAPlausibleRate) {
  std::string why_not;
  auto runtime = ocl::Runtime::Create(ocl::DeviceSelection::FromEnvironment(), &why_not);
  if (!runtime) GTEST_SKIP() << "no OpenCL device: " << why_not;
  DeviceReadBandwidthOptions options;
  options.bytes = std::size_t{64} << 20;
  options.repeats = 3;
  const ReadBandwidth result = MeasureDeviceReadBandwidth(*runtime, options);
  EXPECT_GT(result.gbps, 0.1);     // far below any machine's
  EXPECT_LT(result.gbps, 20000.0); // far above any memory's: a kernel that skipped its reads
  EXPECT_GE(result.gbps, result.median_gbps);
  EXPECT_GT(result.bytes, std::size_t{32} << 20);
  EXPECT_GE(result.threads, 1);
  EXPECT_NE(result.method.find("stream_read"), std::string::npos) << result.method;
}

}  // namespace
}  // namespace hnnstereo::perf
