#pragma once
// The machine's streaming read bandwidth, measured in the same run as the benchmark it
// normalises: the roofline of a solve that streams its weights (docs/benchmark.md).

#include <cstddef>
#include <string>

namespace hnnstereo::perf {

struct ReadBandwidthOptions {
  /// Array read per pass. Far beyond the cores' own caches; this VM reports a 480 MB shared L3
  /// and read 74 MB, 256 MB and 1 GB at the same rate (25.8, 25.8, 27.0 GB/s, two threads).
  std::size_t bytes = std::size_t{256} << 20;
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

/// Every thread sums its contiguous share of one float array of ones (first-touched by that
/// thread) with four 64-byte vector accumulators held in registers (GCC vector extensions, so
/// the loop vectorises without -ffast-math; AVX-512 and AVX2 clones), and the sums are checked
/// (std::logic_error if a thread did not read every element).
ReadBandwidth MeasureReadBandwidth(const ReadBandwidthOptions& options = {});

}  // namespace hnnstereo::perf
