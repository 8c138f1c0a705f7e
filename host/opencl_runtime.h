#pragma once
// OpenCL runtime: device choice, typed errors and a program cache, held in an explicit object
// that callers pass around (no hidden globals; Boost.Compute / VexCL habits).

#include <CL/opencl.hpp>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>

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
};

class Runtime {
 public:
  /// Opens the selected device. Returns nullopt (and the reason in `why_not`) when no OpenCL
  /// platform or no matching device exists.
  static std::unique_ptr<Runtime> Create(const DeviceSelection& selection, std::string* why_not);

  const cl::Context& context() const { return context_; }
  const cl::Device& device() const { return device_; }
  cl::CommandQueue& queue() { return queue_; }
  /// "<device name> (<platform name>)".
  std::string description() const { return description_; }

  /// The program built from the embedded kernel file `name` with `options`, built once per
  /// (source hash, options) and cached here. Throws ProgramBuildError with the log on failure.
  const cl::Program& Program(const std::string& name, const std::string& options);

 private:
  Runtime(cl::Context context, cl::Device device, std::string description);
  cl::Context context_;
  cl::Device device_;
  cl::CommandQueue queue_;
  std::string description_;
  std::map<std::tuple<std::string, std::string>, cl::Program> programs_;
};

}  // namespace hnnstereo::ocl
