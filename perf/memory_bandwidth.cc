#include "perf/memory_bandwidth.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "common/cpu_clones.h"
#include "host/huge_pages.h"

namespace hnnstereo::perf {
namespace {

// 64-byte vectors: one AVX-512 register where the CPU has it (the clone the loader picks), two
// AVX2 or four SSE registers elsewhere. The width matters on this 2-core VM: the sum below
// read 21 GB/s with 16-byte loads and 28 GB/s with 64-byte ones, both cores (a 256 MB array).
// Four accumulators, each a register: an accumulator the compiler keeps in memory (what the
// 32-byte vectors of the default x86-64 target became, a store and reload every add) made the
// loop latency-bound at 15 GB/s, reported as the machine's bandwidth before.
typedef float Vec16 __attribute__((vector_size(64)));
constexpr std::size_t kFloatsPerIteration = 64;

// Sum of [begin, end); `end - begin` is a multiple of kFloatsPerIteration. Cloned for AVX-512
// and AVX2 (host/cpu_clones.h).
HNNSTEREO_TARGET_CLONES("avx512f", "avx2", "default")
double SumRange(const float* begin, const float* end) {
  Vec16 a{}, b{}, c{}, d{};
  for (const float* p = begin; p < end; p += kFloatsPerIteration) {
    Vec16 x0, x1, x2, x3;
    __builtin_memcpy(&x0, p, sizeof(Vec16));
    __builtin_memcpy(&x1, p + 16, sizeof(Vec16));
    __builtin_memcpy(&x2, p + 32, sizeof(Vec16));
    __builtin_memcpy(&x3, p + 48, sizeof(Vec16));
    a += x0;
    b += x1;
    c += x2;
    d += x3;
  }
  const Vec16 s = (a + b) + (c + d);
  double sum = 0.0;
  for (int k = 0; k < 16; ++k) sum += s[k];
  return sum;
}

}  // namespace

ReadBandwidth MeasureReadBandwidth(const ReadBandwidthOptions& options) {
  const int threads = options.threads > 0
                          ? options.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const std::size_t per_thread = std::max<std::size_t>(
      kFloatsPerIteration, options.bytes / sizeof(float) / static_cast<std::size_t>(threads) /
                               kFloatsPerIteration * kFloatsPerIteration);
  const std::size_t count = per_thread * static_cast<std::size_t>(threads);
  // Over huge pages, as the engine's large buffers on a CPU device (host/huge_pages.h): the
  // limit is measured under the same TLB reach as the weight stream it is compared with.
  const HugePageMemory memory = AllocateHugePages(count * sizeof(float));
  if (!memory) throw std::bad_alloc();
  float* const data = static_cast<float*>(memory.get());
  std::vector<double> sums(static_cast<std::size_t>(threads));
  auto run = [&](bool fill) {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
      pool.emplace_back([&, t] {
        float* begin = data + per_thread * static_cast<std::size_t>(t);
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
  // Every element is 1: each thread's sum must be its element count (each lane's partial sum
  // is an integer below 2^24, exact), or the loop skipped reads.
  for (const double sum : sums) {
    if (sum != static_cast<double>(per_thread)) {
      throw std::logic_error("read bandwidth probe: a thread summed " + std::to_string(sum) +
                             " of " + std::to_string(per_thread) + " ones");
    }
  }
  std::sort(gbps.begin(), gbps.end());
  ReadBandwidth result;
  result.gbps = gbps.back();
  result.median_gbps = gbps[gbps.size() / 2];
  result.bytes = count * sizeof(float);
  result.threads = threads;
  result.method = "sum of a " + std::to_string(result.bytes >> 20) +
                  " MB float array (2 MB aligned, huge pages advised), " + std::to_string(threads) +
                  " threads, four 64-byte vector accumulators, fastest of " +
                  std::to_string(gbps.size()) + " passes";
  return result;
}

}  // namespace hnnstereo::perf
