#include "perf/memory_bandwidth.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

namespace hnnstereo::perf {
namespace {

typedef float Vec8 __attribute__((vector_size(32)));

// Sum of [begin, end) with four 8-wide accumulators; `end - begin` is a multiple of 32.
float SumRange(const float* begin, const float* end) {
  Vec8 a{}, b{}, c{}, d{};
  for (const float* p = begin; p < end; p += 32) {
    Vec8 x0, x1, x2, x3;
    __builtin_memcpy(&x0, p, sizeof(Vec8));
    __builtin_memcpy(&x1, p + 8, sizeof(Vec8));
    __builtin_memcpy(&x2, p + 16, sizeof(Vec8));
    __builtin_memcpy(&x3, p + 24, sizeof(Vec8));
    a += x0;
    b += x1;
    c += x2;
    d += x3;
  }
  const Vec8 s = (a + b) + (c + d);
  float sum = 0.0f;
  for (int k = 0; k < 8; ++k) sum += s[k];
  return sum;
}

}  // namespace

ReadBandwidth MeasureReadBandwidth(const ReadBandwidthOptions& options) {
  const int threads = options.threads > 0
                          ? options.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const std::size_t per_thread = std::max<std::size_t>(
      32, options.bytes / sizeof(float) / static_cast<std::size_t>(threads) / 32 * 32);
  const std::size_t count = per_thread * static_cast<std::size_t>(threads);
  std::unique_ptr<float[]> data(new float[count]);
  std::vector<float> sums(static_cast<std::size_t>(threads));
  auto run = [&](bool fill) {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
      pool.emplace_back([&, t] {
        float* begin = data.get() + per_thread * static_cast<std::size_t>(t);
        if (fill) {
          std::fill(begin, begin + per_thread, 1.0f);  // first touch by the reading thread
        } else {
          sums[static_cast<std::size_t>(t)] = SumRange(begin, begin + per_thread);
        }
      });
    }
    for (std::thread& thread : pool) thread.join();
  };
  run(true);
  run(false);  // warm-up pass
  std::vector<double> gbps;
  for (int r = 0; r < std::max(1, options.repeats); ++r) {
    const auto start = std::chrono::steady_clock::now();
    run(false);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    gbps.push_back(static_cast<double>(count * sizeof(float)) / seconds / 1e9);
  }
  std::sort(gbps.begin(), gbps.end());
  ReadBandwidth result;
  result.gbps = gbps.back();
  result.median_gbps = gbps[gbps.size() / 2];
  result.bytes = count * sizeof(float);
  result.threads = threads;
  result.method = "sum of a " + std::to_string(result.bytes >> 20) + " MB float array, " +
                  std::to_string(threads) +
                  " threads, 8-wide vector accumulators, fastest of " +
                  std::to_string(gbps.size()) + " passes";
  // Keep the sums observable so the reads are not optimised away.
  volatile float sink = 0.0f;
  for (float s : sums) sink = sink + s;
  (void)sink;
  return result;
}

}  // namespace hnnstereo::perf
