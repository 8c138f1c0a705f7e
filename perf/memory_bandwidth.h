#pragma once
// The machine's streaming read bandwidth, measured in the same run as the benchmark it
// normalises: the roofline of a solve that streams its weights (docs/benchmark.md).

#include <cstddef>
#include <string>

namespace hnnstereo::perf {

struct ReadBandwidthOptions {
  std::size_t bytes = std::size_t{256} << 20;  ///< array read per pass (far beyond the caches)
  int threads = 0;                             ///< 0 = std::thread::hardware_concurrency()
  int repeats = 5;                             ///< passes; the fastest counts (least disturbed)
};

struct ReadBandwidth {
  double gbps = 0.0;        ///< 1e9 bytes per second, fastest pass
  double median_gbps = 0.0;
  std::size_t bytes = 0;
  int threads = 0;
  std::string method;       ///< what was measured, for the JSON
};

/// Every thread sums its contiguous share of one float array (first-touched by that thread)
/// with 32 independent accumulators held in vector registers (GCC vector extensions, so the
/// loop vectorises without -ffast-math; a scalar float reduction reads about half as fast).
ReadBandwidth MeasureReadBandwidth(const ReadBandwidthOptions& options = {});

}  // namespace hnnstereo::perf
