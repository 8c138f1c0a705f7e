#pragma once
// The OpenCL device's streaming read bandwidth, measured in the same run as the benchmark it
// normalises: the roofline of the opencl engine's solve, which streams its weights from the
// device's memory (docs/benchmark.md). On a CPU device (PoCL) that is the host's memory, read
// through the OpenCL runtime; on a GPU it is the card's memory, which the host probe
// (perf/memory_bandwidth.h) does not see at all.

#include "host/opencl_runtime.h"
#include "perf/memory_bandwidth.h"

namespace hnnstereo::perf {

struct DeviceReadBandwidthOptions {
  /// Array read per pass; capped at half of CL_DEVICE_MAX_MEM_ALLOC_SIZE. 256 MB is far beyond
  /// a CPU's caches; a GPU with a large last-level cache (H100: 50 MB) still streams it.
  std::size_t bytes = std::size_t{256} << 20;
  int repeats = 5;  ///< timed passes after one untimed; the fastest counts (least disturbed)
};

/// Sums a float array on the device (kernels/stream_read.cl: strided float4 loads on a GPU,
/// one contiguous chunk of float16 loads per work-item on a CPU device) and times each pass
/// with OpenCL profiling events on a queue of its own. `threads` in the result is the number of
/// work-items. Throws ocl::OpenClError (or cl::Error) when the device cannot run it.
ReadBandwidth MeasureDeviceReadBandwidth(ocl::Runtime& runtime,
                                         const DeviceReadBandwidthOptions& options = {});

}  // namespace hnnstereo::perf
