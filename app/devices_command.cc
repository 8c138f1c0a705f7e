// `hnnstereo devices`: the OpenCL platforms and devices, with what to pass to --device, and the
// device the opencl engine would use now.
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "app/cli_support.h"
#include "app/commands.h"
#include "host/opencl_runtime.h"

namespace hnnstereo::app {
namespace {

struct DevicesArgs {
  bool quiet = false;
  std::string device;  ///< --device: show only this one (index or name part)
};

void RunDevices(const DevicesArgs& args) {
  std::string why_none;
  const std::vector<ocl::DeviceInfo> devices = ocl::ListDevices(&why_none);
  if (devices.empty()) {
    if (!args.device.empty()) OpenRuntimeFor(hnn::EngineKind::kOpenCL, args.device);  // refuses
    if (!args.quiet) {
      std::printf("no OpenCL device: %s\nthe opencl engine falls back to the cpu engine (same "
                  "dynamics, one thread); README.md, 'Running on a GPU', says what to install\n",
                  why_none.c_str());
    }
    return;
  }
  // The device the matcher opens now with --device (it throws, listing the devices, when
  // --device or HNNSTEREO_OPENCL_* asks for a missing one).
  const std::unique_ptr<ocl::Runtime> runtime =
      OpenRuntimeFor(hnn::EngineKind::kOpenCL, args.device);
  if (args.quiet) return;
  std::size_t platform = devices.front().platform_index + 1;  // none printed yet
  for (const ocl::DeviceInfo& info : devices) {
    const bool in_use = runtime != nullptr && runtime->description() ==
                                                  info.device_name + " (" + info.platform_name + ")";
    const bool by_index = !args.device.empty() &&
                          args.device.find_first_not_of("0123456789") == std::string::npos;
    if (!args.device.empty() &&
        (!in_use || (by_index && std::to_string(info.device_index) != args.device))) {
      continue;  // --device: that device only
    }
    if (info.platform_index != platform) {
      platform = info.platform_index;
      std::printf("platform %zu: %s\n", info.platform_index, info.platform_name.c_str());
    }
    std::printf("  device %zu: %s [%s] %s, %u compute units, %.1f GiB\n", info.device_index,
                info.device_name.c_str(), info.type.c_str(), info.version.c_str(),
                info.compute_units,
                static_cast<double>(info.global_memory_bytes) / (1024.0 * 1024.0 * 1024.0));
  }
  std::printf("in use: %s\n", runtime ? runtime->description().c_str() : "none (cpu engine)");
  std::printf("choose with --device INDEX or --device NAME-PART (case-insensitive), or "
              "HNNSTEREO_OPENCL_DEVICE; HNNSTEREO_OPENCL_PLATFORM picks the platform by index or "
              "name part; without either the first GPU, else the first device\n");
}

}  // namespace

void AddDevicesCommand(CLI::App& app) {
  auto args = std::make_shared<DevicesArgs>();
  CLI::App* cmd = app.add_subcommand(
      "devices", "List the OpenCL platforms and devices, and the one the opencl engine uses");
  cmd->footer(
      "Example:\n"
      "  hnnstereo devices\n"
      "  hnnstereo match ... --device 0        # or --device nvidia, or HNNSTEREO_OPENCL_DEVICE=0");
  cmd->add_option("--device", args->device,
                  "Show only this device (index or name part, as 'match --device' takes it); "
                  "refused when none matches");
  cmd->add_flag("--quiet", args->quiet, "Print nothing; the exit status says whether the device "
                                        "asked for by HNNSTEREO_OPENCL_DEVICE exists");
  cmd->callback([args] { RunDevices(*args); });
}

}  // namespace hnnstereo::app
