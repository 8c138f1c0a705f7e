#pragma once
// Atomic output files: write to a temporary file beside the target, then rename, so that a
// failure never leaves a half-written output (ARCHITECTURE.md, command-line contract).

#include <functional>
#include <string>

namespace hnnstereo::calib {

/// Writes `contents` to `path` atomically. Throws std::runtime_error naming the path on failure.
void WriteFileAtomically(const std::string& path, const std::string& contents);

/// Calls `write_to(temporary_path)`, then renames the temporary file onto `path`. If `write_to`
/// throws or the file is missing afterwards, the temporary file is removed and the error rethrown.
void WriteAtomically(const std::string& path,
                     const std::function<void(const std::string& temporary_path)>& write_to);

/// The temporary name used for `path` (same folder, same extension so that writers that pick a
/// format by extension, such as cv::imwrite, still work).
std::string TemporaryPathFor(const std::string& path);

}  // namespace hnnstereo::calib
