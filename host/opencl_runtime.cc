#include "host/opencl_runtime.h"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <vector>

#include "host/huge_pages.h"
#include "host/program_cache.h"
#include "kernels/embedded_kernels.h"

namespace hnnstereo::ocl {
namespace {

// PoCL's CPU device runs a kernel's work-groups on its own worker threads, one a core, which
// sleep between commands. Left to the OS, both of its workers were often queued on one core of
// the 2-core VM while the other core idled (in some processes at every solve): the device loop's
// second work-group then started only after the first had done every step alone (counted per solve
// in `bench --sizes 1000`, 16 solves a process: 7, 0, 16 and 0 of them in four processes), the
// 1,000-feature solve then at one core's speed. POCL_AFFINITY=1 pins worker i to
// CPU i: no solve ran alone in four processes, and the case's roofline fraction was 61-65 %
// against 37-64 %. Set before the first OpenCL call (PoCL reads it when it starts its workers),
// never over a value already set (POCL_AFFINITY=0 opts out), and only where the process may run
// on every online CPU and PoCL counts its cores itself, so that no pin asks for a CPU the process
// may not use. (setenv is not safe against a getenv in another thread: the commands open their
// runtime before they start threads of their own - serve and pick before the link and the page.)
void PinPoclWorkersWhereSafe() {
  static const bool pinned = [] {
    if (std::getenv("POCL_AFFINITY") || std::getenv("POCL_CPU_MAX_CU_COUNT")) return false;
    const long online = sysconf(_SC_NPROCESSORS_ONLN);
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    if (online < 1 || online > CPU_SETSIZE || sched_getaffinity(0, sizeof allowed, &allowed) != 0) {
      return false;
    }
    for (long cpu = 0; cpu < online; ++cpu) {
      if (!CPU_ISSET(static_cast<int>(cpu), &allowed)) return false;
    }
    return setenv("POCL_AFFINITY", "1", 0) == 0;
  }();
  (void)pinned;
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// True when `selector` (an index or a name substring) selects item `index` named `name`.
bool Selects(const std::string& selector, std::size_t index, const std::string& name) {
  if (selector.empty()) return true;
  if (std::all_of(selector.begin(), selector.end(), [](unsigned char c) { return std::isdigit(c); })) {
    return selector.size() < 10 && std::stoul(selector) == index;
  }
  return Lower(name).find(Lower(selector)) != std::string::npos;
}

std::string Trim(std::string text) {
  while (!text.empty() && (text.back() == '\0' || std::isspace(static_cast<unsigned char>(text.back())))) {
    text.pop_back();
  }
  return text;
}

}  // namespace

const char* ErrorName(cl_int code) {
  switch (code) {
#define HNN_CASE(x) \
  case x:           \
    return #x;
    HNN_CASE(CL_SUCCESS)
    HNN_CASE(CL_DEVICE_NOT_FOUND)
    HNN_CASE(CL_DEVICE_NOT_AVAILABLE)
    HNN_CASE(CL_COMPILER_NOT_AVAILABLE)
    HNN_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    HNN_CASE(CL_OUT_OF_RESOURCES)
    HNN_CASE(CL_OUT_OF_HOST_MEMORY)
    HNN_CASE(CL_BUILD_PROGRAM_FAILURE)
    HNN_CASE(CL_INVALID_VALUE)
    HNN_CASE(CL_INVALID_PLATFORM)
    HNN_CASE(CL_INVALID_DEVICE)
    HNN_CASE(CL_INVALID_CONTEXT)
    HNN_CASE(CL_INVALID_COMMAND_QUEUE)
    HNN_CASE(CL_INVALID_MEM_OBJECT)
    HNN_CASE(CL_INVALID_BINARY)
    HNN_CASE(CL_INVALID_BUILD_OPTIONS)
    HNN_CASE(CL_INVALID_PROGRAM)
    HNN_CASE(CL_INVALID_PROGRAM_EXECUTABLE)
    HNN_CASE(CL_INVALID_KERNEL_NAME)
    HNN_CASE(CL_INVALID_KERNEL)
    HNN_CASE(CL_INVALID_ARG_INDEX)
    HNN_CASE(CL_INVALID_ARG_VALUE)
    HNN_CASE(CL_INVALID_ARG_SIZE)
    HNN_CASE(CL_INVALID_KERNEL_ARGS)
    HNN_CASE(CL_INVALID_WORK_DIMENSION)
    HNN_CASE(CL_INVALID_WORK_GROUP_SIZE)
    HNN_CASE(CL_INVALID_WORK_ITEM_SIZE)
    HNN_CASE(CL_INVALID_GLOBAL_OFFSET)
    HNN_CASE(CL_INVALID_EVENT_WAIT_LIST)
    HNN_CASE(CL_INVALID_OPERATION)
    HNN_CASE(CL_INVALID_BUFFER_SIZE)
    HNN_CASE(CL_INVALID_GLOBAL_WORK_SIZE)
    HNN_CASE(CL_PLATFORM_NOT_FOUND_KHR)
#undef HNN_CASE
    default:
      return "CL_UNKNOWN_ERROR";
  }
}

OpenClError::OpenClError(const std::string& what, cl_int code)
    : std::runtime_error("OpenCL: " + what + " failed with " + ErrorName(code) + " (" +
                         std::to_string(code) + ")"),
      code_(code) {}

ProgramBuildError::ProgramBuildError(const std::string& program, const std::string& options,
                                     const std::string& log)
    : OpenClError("building kernels '" + program + "' with options '" + options + "':\n" + log,
                  CL_BUILD_PROGRAM_FAILURE),
      log_(log) {}

DeviceSelection DeviceSelection::FromEnvironment() {
  DeviceSelection selection;
  if (const char* platform = std::getenv("HNNSTEREO_OPENCL_PLATFORM")) selection.platform = platform;
  if (const char* device = std::getenv("HNNSTEREO_OPENCL_DEVICE")) selection.device = device;
  return selection;
}

std::vector<DeviceInfo> ListDevices(std::string* why_none) {
  std::vector<DeviceInfo> devices;
  std::vector<cl::Platform> platforms;
  PinPoclWorkersWhereSafe();
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error& e) {
    if (why_none) *why_none = std::string("no OpenCL platform (") + ErrorName(e.err()) + ")";
    return devices;
  }
  if (platforms.empty()) {
    if (why_none) *why_none = "no OpenCL platform is installed";
    return devices;
  }
  for (std::size_t p = 0; p < platforms.size(); ++p) {
    std::vector<cl::Device> found;
    try {
      platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &found);
    } catch (const cl::Error&) {
      continue;  // a platform without devices answers CL_DEVICE_NOT_FOUND
    }
    for (std::size_t d = 0; d < found.size(); ++d) {
      DeviceInfo info;
      info.platform_index = p;
      info.platform_name = Trim(platforms[p].getInfo<CL_PLATFORM_NAME>());
      info.device_index = d;
      info.device_name = Trim(found[d].getInfo<CL_DEVICE_NAME>());
      const cl_device_type type = found[d].getInfo<CL_DEVICE_TYPE>();
      info.type = (type & CL_DEVICE_TYPE_GPU)           ? "gpu"
                  : (type & CL_DEVICE_TYPE_CPU)         ? "cpu"
                  : (type & CL_DEVICE_TYPE_ACCELERATOR) ? "accelerator"
                                                        : "other";
      info.version = Trim(found[d].getInfo<CL_DEVICE_VERSION>());
      info.global_memory_bytes = found[d].getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
      info.compute_units = found[d].getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
      devices.push_back(std::move(info));
    }
  }
  if (devices.empty() && why_none) *why_none = "the OpenCL platforms list no device";
  return devices;
}

std::string DescribeDevices(const std::vector<DeviceInfo>& devices) {
  if (devices.empty()) return "no OpenCL device is installed";
  std::string text;
  for (const DeviceInfo& info : devices) {
    if (!text.empty()) text += "; ";
    text += "platform " + std::to_string(info.platform_index) + " '" + info.platform_name +
            "': device " + std::to_string(info.device_index) + " '" + info.device_name + "' (" +
            info.type + ")";
  }
  return text;
}

Runtime::Runtime(cl::Context context, cl::Device device, std::string description)
    : context_(std::move(context)),
      device_(std::move(device)),
      queue_(context_, device_),
      description_(std::move(description)),
      is_gpu_((device_.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) != 0),
      program_cache_serves_(ProgramCacheServes(
          cl::Platform(device_.getInfo<CL_DEVICE_PLATFORM>()).getInfo<CL_PLATFORM_NAME>())) {}

std::unique_ptr<Runtime> Runtime::Create(const DeviceSelection& selection, std::string* why_not) {
  std::vector<cl::Platform> platforms;
  PinPoclWorkersWhereSafe();
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error& e) {
    if (why_not) *why_not = std::string("no OpenCL platform (") + ErrorName(e.err()) + ")";
    return nullptr;
  }
  if (platforms.empty()) {
    if (why_not) *why_not = "no OpenCL platform is installed";
    return nullptr;
  }
  struct Found {
    cl::Platform platform;
    cl::Device device;
    bool gpu;
  };
  std::vector<Found> found;
  for (std::size_t p = 0; p < platforms.size(); ++p) {
    const std::string platform_name = Trim(platforms[p].getInfo<CL_PLATFORM_NAME>());
    if (!Selects(selection.platform, p, platform_name)) continue;
    std::vector<cl::Device> devices;
    try {
      platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;
    }
    for (std::size_t d = 0; d < devices.size(); ++d) {
      const std::string device_name = Trim(devices[d].getInfo<CL_DEVICE_NAME>());
      if (!Selects(selection.device, d, device_name)) continue;
      found.push_back({platforms[p], devices[d],
                       (devices[d].getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) != 0});
    }
  }
  if (found.empty()) {
    if (why_not) {
      std::string asked;
      if (!selection.platform.empty()) asked += "platform '" + selection.platform + "'";
      if (!selection.device.empty()) {
        asked += std::string(asked.empty() ? "" : " ") + "device '" + selection.device + "'";
      }
      *why_not = "no OpenCL device matches " + asked + "; there are: " + DescribeDevices(ListDevices());
    }
    return nullptr;
  }
  auto chosen = std::find_if(found.begin(), found.end(), [](const Found& f) { return f.gpu; });
  if (chosen == found.end() || !selection.device.empty()) chosen = found.begin();
  try {
    cl::Context context(chosen->device);
    const std::string description = Trim(chosen->device.getInfo<CL_DEVICE_NAME>()) + " (" +
                                    Trim(chosen->platform.getInfo<CL_PLATFORM_NAME>()) + ")";
    return std::unique_ptr<Runtime>(new Runtime(context, chosen->device, description));
  } catch (const cl::Error& e) {
    if (why_not) *why_not = std::string("cannot open the OpenCL device (") + ErrorName(e.err()) + ")";
    return nullptr;
  }
}

const cl::Program& Runtime::Program(const std::string& name, const std::string& options) {
  const kernels::KernelSource& source = kernels::FindKernelSource(name);
  const auto key = std::make_tuple(std::string(source.hash), options);
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;
  const std::string build_options = options + " -cl-std=CL1.2";
  // The on-disk binary cache (host/program_cache.h): a binary built earlier for this device,
  // driver, source and options skips the compiler; anything wrong with it means a rebuild.
  const std::string cache_dir = program_cache_serves_ ? ProgramCacheDirectory() : std::string();
  std::string cache_key, cache_entry;
  if (!cache_dir.empty()) {
    const std::string device_name = device_.getInfo<CL_DEVICE_NAME>();
    const std::string device_version = device_.getInfo<CL_DEVICE_VERSION>();
    const std::string driver_version = device_.getInfo<CL_DRIVER_VERSION>();
    cache_key = device_name + '|' + device_version + '|' + driver_version + '|' + source.hash +
                '|' + build_options;
    cache_entry = ProgramCacheEntryName(device_name, device_version, driver_version, source.hash,
                                        build_options);
    if (auto binary = ReadCachedProgram(cache_dir, cache_entry, cache_key)) {
      try {
        cl::Program cached(context_, std::vector<cl::Device>{device_},
                           cl::Program::Binaries{*binary});
        cached.build(std::vector<cl::Device>{device_}, build_options.c_str());
        return programs_.emplace(key, std::move(cached)).first->second;
      } catch (const cl::Error&) {
        // a stale or foreign entry: build from source below and overwrite it
      }
    }
  }
  cl::Program program(context_, std::string(source.source));
  try {
    program.build(std::vector<cl::Device>{device_}, build_options.c_str());
  } catch (const cl::BuildError& e) {
    std::string log;
    for (const auto& [device, text] : e.getBuildLog()) log += text;
    throw ProgramBuildError(name, options, log);
  } catch (const cl::Error& e) {
    std::string log;
    try {
      log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device_);
    } catch (const cl::Error&) {
    }
    throw ProgramBuildError(name, options, log.empty() ? ErrorName(e.err()) : log);
  }
  if (!cache_dir.empty()) {
    try {
      const auto binaries = program.getInfo<CL_PROGRAM_BINARIES>();
      if (binaries.size() == 1) WriteCachedProgram(cache_dir, cache_entry, cache_key, binaries[0]);
    } catch (const cl::Error&) {
      // no binary to keep: the next process compiles again
    }
  }
  return programs_.emplace(key, std::move(program)).first->second;
}

cl::Buffer Runtime::NewBuffer(cl_mem_flags flags, std::size_t bytes) {
  bytes = std::max<std::size_t>(bytes, 4);
  // A CPU device's buffer is host memory: a large one lies over huge pages of its own
  // (host/huge_pages.h), freed by the buffer's destructor callback once OpenCL is done with it.
  if (bytes >= kHugeBufferBytes && (device_.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_CPU) != 0) {
    if (HugePageMemory memory = AllocateHugePages(bytes)) {
      cl_int error = CL_SUCCESS;
      cl_mem buffer =
          clCreateBuffer(context_(), flags | CL_MEM_USE_HOST_PTR, bytes, memory.get(), &error);
      if (error == CL_SUCCESS) {
        error = clSetMemObjectDestructorCallback(
            buffer, [](cl_mem, void* user) { std::free(user); }, memory.get());
        if (error == CL_SUCCESS) {
          memory.release();           // now the callback's
          return cl::Buffer(buffer);  // takes the reference
        }
        clReleaseMemObject(buffer);  // never used: its memory can go at once
      }
    }
  }
  return cl::Buffer(context_, flags, bytes);
}

cl::Buffer Runtime::ScratchBuffer(const std::string& purpose, std::size_t bytes) {
  bytes = std::max<std::size_t>(bytes, 4);
  auto& [buffer, size] = scratch_[purpose];
  if (size < bytes) {
    buffer = cl::Buffer();  // release the old one before allocating the larger
    buffer = NewBuffer(CL_MEM_READ_WRITE, bytes);
    size = bytes;
  }
  return buffer;
}

}  // namespace hnnstereo::ocl
