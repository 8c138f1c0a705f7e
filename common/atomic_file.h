#pragma once
// Atomic output files: write to a temporary file beside the target, then rename, so that a
// failure never leaves a half-written output (ARCHITECTURE.md, command-line contract).

#include <functional>
#include <string>

namespace hnnstereo::calib {

/// Writes `contents` to `path` atomically. Throws std::runtime_error naming the path on failure.
void WriteFileAtomically(const std::string& path, const std::string& contents);

/// Calls `write_to(temporary_path)`, flushes the temporary file to the disk (fsync), then renames
/// it onto `path` and flushes the folder: a reader sees the old file or the new one, never a mix,
/// even when the writer is killed (SIGKILL) or the power fails at any moment. If `write_to`
/// throws or the file is missing afterwards, the temporary file is removed and the error rethrown.
void WriteAtomically(const std::string& path,
                     const std::function<void(const std::string& temporary_path)>& write_to);

/// A fresh temporary name for `path` (same folder, same extension so that writers that pick a
/// format by extension, such as cv::imwrite, still work): ".STEM.tmpPID-N.EXT", unique per call.
/// A writer killed between the write and the rename leaves this hidden file behind, never a
/// torn `path`.
std::string TemporaryPathFor(const std::string& path);

}  // namespace hnnstereo::calib
