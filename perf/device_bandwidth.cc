#include "perf/device_bandwidth.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace hnnstereo::perf {

ReadBandwidth MeasureDeviceReadBandwidth(ocl::Runtime& runtime,
                                         const DeviceReadBandwidthOptions& options) {
  const cl::Device& device = runtime.device();
  const bool gpu = runtime.is_gpu();
  const unsigned units = std::max(1u, device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
  const std::size_t max_alloc = device.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
  std::size_t bytes = std::min(options.bytes, max_alloc / 2);
  // Work-items: on a GPU 2048 per compute unit (enough loads in flight to cover the latency);
  // on a CPU device one per compute unit (core), each streaming a contiguous chunk.
  const std::size_t items = gpu ? std::size_t{units} * 2048 : units;
  const std::size_t float16s = std::max<std::size_t>(items, bytes / 64 / items * items);
  bytes = float16s * 64;
  const cl::Context& context = runtime.context();
  cl::CommandQueue queue(context, device, CL_QUEUE_PROFILING_ENABLE);
  // On a CPU device over huge pages, as the engine's weight blocks (Runtime::NewBuffer).
  cl::Buffer data = runtime.NewBuffer(CL_MEM_READ_ONLY, bytes);
  cl::Buffer partial(context, CL_MEM_WRITE_ONLY, items * sizeof(float));
  queue.enqueueFillBuffer(data, 1.0f, 0, bytes);
  const cl::Program& program = runtime.Program("stream_read", "");
  cl::Kernel kernel(program, gpu ? "stream_read_strided" : "stream_read_chunked");
  kernel.setArg(0, data);
  kernel.setArg(1, static_cast<cl_uint>(gpu ? float16s * 4 : float16s / items));
  kernel.setArg(2, partial);
  // GPU: groups of 256; CPU device: groups of one work-item (one core each).
  const cl::NDRange local = gpu ? cl::NDRange(256) : cl::NDRange(1);
  std::vector<double> gbps;
  for (int r = 0; r <= std::max(1, options.repeats); ++r) {
    cl::Event event;
    queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(items), local, nullptr, &event);
    event.wait();
    const double ns = static_cast<double>(event.getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                                          event.getProfilingInfo<CL_PROFILING_COMMAND_START>());
    if (r > 0 && ns > 0) gbps.push_back(static_cast<double>(bytes) / ns);  // bytes / ns = GB/s
  }
  // The sum is every element once: a wrong kernel (a skipped or doubled range) is not timed.
  std::vector<float> sums(items);
  queue.enqueueReadBuffer(partial, CL_TRUE, 0, items * sizeof(float), sums.data());
  double total = 0.0;
  for (float s : sums) total += s;
  const double expected = static_cast<double>(bytes / sizeof(float));
  if (std::abs(total - expected) > 1e-3 * expected) {
    throw ocl::OpenClError("stream_read summed " + std::to_string(total) + " instead of " +
                               std::to_string(expected),
                           CL_INVALID_VALUE);
  }
  std::sort(gbps.begin(), gbps.end());
  ReadBandwidth result;
  if (gbps.empty()) return result;
  result.gbps = gbps.back();
  result.median_gbps = gbps[gbps.size() / 2];
  result.bytes = bytes;
  result.threads = static_cast<int>(items);
  result.method = "OpenCL kernel stream_read_" + std::string(gpu ? "strided" : "chunked") +
                  " summing a " + std::to_string(bytes >> 20) + " MB float array on the device (" +
                  (gpu ? "" : "huge pages advised, ") + std::to_string(items) + " work-items, " +
                  (gpu ? "float4 loads" : "float16 loads") +
                  "), profiling-event time, fastest of " + std::to_string(gbps.size()) + " passes";
  return result;
}

}  // namespace hnnstereo::perf
