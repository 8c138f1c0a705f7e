#pragma once
// The OpenCL C sources of kernels/*.cl, embedded at build time by cmake/cl2cpp.cmake.

#include <string>
#include <string_view>
#include <vector>

namespace hnnstereo::kernels {

struct KernelSource {
  const char* name;    ///< file name without extension, e.g. "hopfield"
  const char* source;  ///< OpenCL C text
  const char* hash;    ///< SHA1 of the text, used as the program-cache key
};

/// All embedded kernel files.
const std::vector<KernelSource>& EmbeddedKernelSources();

/// The kernel file called `name`; throws std::out_of_range when it is not embedded.
const KernelSource& FindKernelSource(std::string_view name);

}  // namespace hnnstereo::kernels
