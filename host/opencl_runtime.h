#pragma once
// OpenCL runtime: device choice, typed errors and a program cache, held in an explicit object
// that callers pass around (no hidden globals; Boost.Compute / VexCL habits).

#include <CL/opencl.hpp>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace hnnstereo::ocl {

/// The symbolic name of an OpenCL error code, e.g. "CL_OUT_OF_RESOURCES".
const char* ErrorName(cl_int code);

/// An OpenCL call failed: carries the code and its name.
class OpenClError : public std::runtime_error {
 public:
  OpenClError(const std::string& what, cl_int code);
  cl_int code() const { return code_; }

 private:
  cl_int code_;
};

/// A kernel program failed to build: carries the build log.
class ProgramBuildError : public OpenClError {
 public:
  ProgramBuildError(const std::string& program, const std::string& options, const std::string& log);
  const std::string& log() const { return log_; }

 private:
  std::string log_;
};

/// Which device to use. Unset fields come from the environment (HNNSTEREO_OPENCL_PLATFORM,
/// HNNSTEREO_OPENCL_DEVICE: an index or a case-insensitive substring of the name), else the
/// first GPU, else the first device of any type.
struct DeviceSelection {
  std::string platform;  ///< index or name substring; empty = any
  std::string device;    ///< index or name substring; empty = prefer a GPU
  static DeviceSelection FromEnvironment();
  /// True when nothing was asked for (then a missing device may fall back to the cpu engine).
  bool empty() const { return platform.empty() && device.empty(); }
};

/// One OpenCL device as `hnnstereo devices` lists it.
struct DeviceInfo {
  std::size_t platform_index = 0;  ///< what HNNSTEREO_OPENCL_PLATFORM takes
  std::string platform_name;
  std::size_t device_index = 0;    ///< index within its platform: what --device takes
  std::string device_name;         ///< a case-insensitive substring of it also works
  std::string type;                ///< "gpu", "cpu", "accelerator" or "other"
  std::string version;             ///< CL_DEVICE_VERSION
  std::uint64_t global_memory_bytes = 0;
  unsigned compute_units = 0;
};

/// All OpenCL platforms' devices, in platform then device order. Empty when there are none,
/// with the reason in `why_none` (no ICD loader platform, a platform that fails to list...).
std::vector<DeviceInfo> ListDevices(std::string* why_none = nullptr);

/// One line naming the devices that exist, e.g. "platform 0 'Portable Computing Language':
/// device 0 'cpu-haswell-...' (cpu)", or "no OpenCL device is installed".
std::string DescribeDevices(const std::vector<DeviceInfo>& devices);

class Runtime {
 public:
  /// Opens the selected device. Returns nullptr (and the reason in `why_not`) when no OpenCL
  /// platform or no matching device exists; when a device was asked for, the reason lists the
  /// devices that exist.
  static std::unique_ptr<Runtime> Create(const DeviceSelection& selection, std::string* why_not);

  const cl::Context& context() const { return context_; }
  const cl::Device& device() const { return device_; }
  cl::CommandQueue& queue() { return queue_; }
  /// "<device name> (<platform name>)".
  std::string description() const { return description_; }
  /// CL_DEVICE_TYPE_GPU: where the engine's choices differ (work-group per row, per-weight
  /// build, csr for wide rows) and the roofline is the card's own memory.
  bool is_gpu() const { return is_gpu_; }

  /// The program built from the embedded kernel file `name` with `options`, built once per
  /// (source hash, options) and cached here. Throws ProgramBuildError with the log on failure.
  const cl::Program& Program(const std::string& name, const std::string& options);

  /// A read-write device buffer of at least `bytes` for `purpose`, the one of the last call
  /// with that purpose when it is large enough (grown otherwise). On a CPU device the first
  /// touch of a fresh buffer costs a page fault per 4 KB: on all of Teddy's 66 MB of weight
  /// blocks that was ~20-30 ms of every match. Allocated by NewBuffer. Its contents are
  /// whatever the last user left; the caller must write before reading, and be done with it
  /// before the next call with the same purpose (a runtime is used from one thread, like
  /// Program()).
  cl::Buffer ScratchBuffer(const std::string& purpose, std::size_t bytes);

  /// Buffers of at least this size get huge pages on a CPU device (NewBuffer).
  static constexpr std::size_t kHugeBufferBytes = std::size_t{8} << 20;
  /// A new device buffer of `bytes` with `flags` (no host pointer flags). On a CPU device one of
  /// kHugeBufferBytes or more lies over host memory of its own, 2 MB aligned and advised as
  /// transparent huge pages (Linux; plain small pages where the system disabled them), so that
  /// streaming it costs a TLB entry per 2 MB; the memory is freed with the buffer.
  cl::Buffer NewBuffer(cl_mem_flags flags, std::size_t bytes);

 private:
  Runtime(cl::Context context, cl::Device device, std::string description);
  cl::Context context_;
  cl::Device device_;
  cl::CommandQueue queue_;
  std::string description_;
  bool is_gpu_ = false;
  bool program_cache_serves_ = true;  ///< ProgramCacheServes(this device's platform)
  std::map<std::tuple<std::string, std::string>, cl::Program> programs_;
  std::map<std::string, std::pair<cl::Buffer, std::size_t>> scratch_;
};

}  // namespace hnnstereo::ocl
