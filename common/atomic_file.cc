#include "common/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace hnnstereo::calib {
namespace {

// Flushes a file's (or a folder's) data to the disk. The rename alone already protects against a
// killed process (the page cache survives it); fsync makes the new contents durable before they
// become visible under the target name, so that a power cut, too, leaves the old file or the new
// one, never a renamed but empty file (ext4 data=writeback, XFS). Folders that cannot be opened
// for reading are skipped silently: durability is a bonus there, not a precondition.
bool SyncPath(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_DIRECTORY : 0) | O_RDONLY | O_CLOEXEC);
  if (fd < 0) return directory;
  const bool synced = ::fsync(fd) == 0 || errno == EINVAL;  // EINVAL: fsync not supported here
  ::close(fd);
  return synced;
}

}  // namespace

std::string TemporaryPathFor(const std::string& path) {
  // Unique per call, not only per process: two threads of one process (the serve loop and its
  // web page) writing the same file must not share, and truncate, one temporary file.
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path target(path);
  std::filesystem::path temporary = target;
  // Built with append: GCC 12 reports a false -Wrestrict on "." + std::string temporaries.
  std::string name(".");
  name.append(target.stem().string())
      .append(".tmp")
      .append(std::to_string(::getpid()))
      .append("-")
      .append(std::to_string(counter.fetch_add(1)))
      .append(target.extension().string());
  temporary.replace_filename(name);
  return temporary.string();
}

void WriteAtomically(const std::string& path,
                     const std::function<void(const std::string& temporary_path)>& write_to) {
  const std::string temporary = TemporaryPathFor(path);
  try {
    write_to(temporary);
    if (!std::filesystem::exists(temporary)) {
      throw std::runtime_error("could not write '" + path + "'");
    }
    if (!SyncPath(temporary, false)) {
      throw std::runtime_error("could not write '" + path + "': " + std::strerror(errno));
    }
    std::error_code error;
    std::filesystem::rename(temporary, path, error);
    if (error) throw std::runtime_error("could not write '" + path + "': " + error.message());
    std::filesystem::path folder = std::filesystem::path(path).parent_path();
    SyncPath(folder.empty() ? "." : folder.string(), true);  // the rename itself
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw;
  }
}

void WriteFileAtomically(const std::string& path, const std::string& contents) {
  WriteAtomically(path, [&](const std::string& temporary) {
    const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) {
      throw std::runtime_error("cannot open '" + path + "' for writing: " + std::strerror(errno));
    }
    std::size_t written = 0;
    while (written < contents.size()) {
      const ssize_t n = ::write(fd, contents.data() + written, contents.size() - written);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const int saved = errno;
        ::close(fd);
        throw std::runtime_error("could not write '" + path + "' (disk full?): " +
                                 std::strerror(saved));
      }
      written += static_cast<std::size_t>(n);
    }
    if (::close(fd) != 0) {
      throw std::runtime_error("could not write '" + path + "': " + std::strerror(errno));
    }
  });
}

}  // namespace hnnstereo::calib
