#include "host/program_cache.h"

#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

namespace hnnstereo::ocl {
namespace {

// Entry file: "hnnstereo-program 1\n" + key + "\n\0" + binary bytes.
constexpr const char* kMagic = "hnnstereo-program 1\n";

std::uint64_t Fnv1a(const std::string& text) {
  std::uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace

std::string ProgramCacheDirectory() {
  if (const char* dir = std::getenv("HNNSTEREO_KERNEL_CACHE"); dir && *dir) {
    const std::string value(dir);
    if (value == "off" || value == "0") return {};
    return value;
  }
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
    return std::string(xdg) + "/hnnstereo/kernels";
  }
  if (const char* home = std::getenv("HOME"); home && *home) {
    return std::string(home) + "/.cache/hnnstereo/kernels";
  }
  return {};
}

bool ProgramCacheServes(const std::string& platform) {
  return platform.find("Portable Computing Language") == std::string::npos;
}

std::string ProgramCacheEntryName(const std::string& device, const std::string& device_version,
                                  const std::string& driver_version, const std::string& source_hash,
                                  const std::string& options) {
  const std::string key = device + '\n' + device_version + '\n' + driver_version + '\n' +
                          source_hash + '\n' + options;
  char name[32];
  std::snprintf(name, sizeof(name), "%016llx.bin", static_cast<unsigned long long>(Fnv1a(key)));
  return name;
}

std::optional<std::vector<unsigned char>> ReadCachedProgram(const std::string& directory,
                                                            const std::string& entry,
                                                            const std::string& key) {
  if (directory.empty()) return std::nullopt;
  std::ifstream in(directory + "/" + entry, std::ios::binary);
  if (!in) return std::nullopt;
  const std::string header = std::string(kMagic) + key + '\n';
  std::string read(header.size() + 1, '\0');
  if (!in.read(read.data(), static_cast<std::streamsize>(read.size()))) return std::nullopt;
  if (read.compare(0, header.size(), header) != 0 || read.back() != '\0') return std::nullopt;
  std::vector<unsigned char> binary((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
  if (binary.empty()) return std::nullopt;
  return binary;
}

void WriteCachedProgram(const std::string& directory, const std::string& entry,
                        const std::string& key, const std::vector<unsigned char>& binary) {
  if (directory.empty() || binary.empty()) return;
  static std::atomic<unsigned> counter{0};
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error) return;
  std::ostringstream temporary;
  temporary << directory << "/." << entry << '.' << ::getpid() << '.' << counter++ << ".tmp";
  {
    std::ofstream out(temporary.str(), std::ios::binary | std::ios::trunc);
    if (!out) return;
    const std::string header = std::string(kMagic) + key + '\n';
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    out.put('\0');
    out.write(reinterpret_cast<const char*>(binary.data()),
              static_cast<std::streamsize>(binary.size()));
    if (!out) {
      std::filesystem::remove(temporary.str(), error);
      return;
    }
  }
  std::filesystem::rename(temporary.str(), directory + "/" + entry, error);
  if (error) std::filesystem::remove(temporary.str(), error);
}

}  // namespace hnnstereo::ocl
