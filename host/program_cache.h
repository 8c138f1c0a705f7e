#pragma once
// On-disk cache of built OpenCL program binaries, so that the first match of a process costs
// what later ones do (kernel compilation is ~1 s on PoCL). Keyed by device name, device and
// driver version, kernel source hash and build options; stored under the user's cache
// directory. Safe when processes race: each entry is written to a unique temporary file and
// renamed into place (atomic on POSIX), and a corrupt or foreign entry is ignored and rebuilt.

#include <optional>
#include <string>
#include <vector>

namespace hnnstereo::ocl {

/// The cache folder: $HNNSTEREO_KERNEL_CACHE, else $XDG_CACHE_HOME/hnnstereo/kernels, else
/// $HOME/.cache/hnnstereo/kernels. Empty when caching is off (HNNSTEREO_KERNEL_CACHE=off, or no
/// home directory).
std::string ProgramCacheDirectory();

/// Whether programs built on `platform` (CL_PLATFORM_NAME) go into this cache. Not on PoCL: it
/// keeps built programs and kernels in its own cache (POCL_CACHE_DIR), and asking it for a
/// program binary compiles every kernel of the program for the binary first, which made a
/// cold start (an empty cache) about 2.5x slower (tests/host/program_cache_test.cc).
bool ProgramCacheServes(const std::string& platform);

/// The file name of an entry: a 64-bit FNV-1a hash of the key fields, in hex, plus ".bin".
std::string ProgramCacheEntryName(const std::string& device, const std::string& device_version,
                                  const std::string& driver_version, const std::string& source_hash,
                                  const std::string& options);

/// The binary stored under `entry` (with its full key checked), or nullopt.
std::optional<std::vector<unsigned char>> ReadCachedProgram(const std::string& directory,
                                                            const std::string& entry,
                                                            const std::string& key);
/// Stores `binary` under `entry` (atomically); failures are ignored (the cache is an
/// optimisation, never a reason to fail a match).
void WriteCachedProgram(const std::string& directory, const std::string& entry,
                        const std::string& key, const std::vector<unsigned char>& binary);

}  // namespace hnnstereo::ocl
