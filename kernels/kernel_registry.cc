#include "kernels/embedded_kernels.h"

#include <stdexcept>
#include <string>

namespace hnnstereo::kernels {

const KernelSource& FindKernelSource(std::string_view name) {
  for (const KernelSource& source : EmbeddedKernelSources()) {
    if (name == source.name) return source;
  }
  throw std::out_of_range("no embedded OpenCL kernel file named '" + std::string(name) + "'");
}

}  // namespace hnnstereo::kernels
