#include "calib/atomic_file.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace hnnstereo::calib {

std::string TemporaryPathFor(const std::string& path) {
  const std::filesystem::path target(path);
  std::filesystem::path temporary = target;
  // Built with append: GCC 12 reports a false -Wrestrict on "." + std::string temporaries.
  std::string name(".");
  name.append(target.stem().string())
      .append(".tmp")
      .append(std::to_string(::getpid()))
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
    std::error_code error;
    std::filesystem::rename(temporary, path, error);
    if (error) throw std::runtime_error("could not write '" + path + "': " + error.message());
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw;
  }
}

void WriteFileAtomically(const std::string& path, const std::string& contents) {
  WriteAtomically(path, [&](const std::string& temporary) {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot open '" + path + "' for writing");
    out << contents;
    out.close();
    if (!out) throw std::runtime_error("could not write '" + path + "' (disk full?)");
  });
}

}  // namespace hnnstereo::calib
