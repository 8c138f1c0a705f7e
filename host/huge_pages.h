#pragma once
// Host memory for large streamed arrays: whole 2 MB pages, 2 MB aligned, advised to Linux as
// transparent huge pages before its first touch, so that streaming it costs a TLB entry per
// 2 MB instead of per 4 KB (docs/engine.md, "Huge pages, and the host stages of large
// networks"). Used by the opencl engine's large buffers on a CPU device
// (ocl::Runtime::NewBuffer) and by the host read probe that gives their roofline. Where the
// system disables huge pages (or elsewhere than Linux) the memory is plain small pages.
#include <cstddef>
#include <cstdlib>
#include <memory>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace hnnstereo {

struct FreeMemory {
  void operator()(void* memory) const { std::free(memory); }
};
/// Memory from AllocateHugePages; release() hands it to an owner that calls std::free.
using HugePageMemory = std::unique_ptr<void, FreeMemory>;

inline constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;

/// At least `bytes` (rounded up to whole huge pages), or null when the allocation fails.
inline HugePageMemory AllocateHugePages(std::size_t bytes) {
  const std::size_t rounded = (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
  HugePageMemory memory(std::aligned_alloc(kHugePageBytes, rounded));
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (memory) madvise(memory.get(), rounded, MADV_HUGEPAGE);  // advice: failure is harmless
#endif
  return memory;
}

}  // namespace hnnstereo
