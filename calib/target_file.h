#pragma once
// TARGET_DIR/target.yml, read the one way both calibration routes read it (circle plate and
// board; docs/calibration.md).

#include <opencv2/core.hpp>
#include <string>

namespace hnnstereo::calib {

/// "target.yml 'PATH'": how messages name the file.
std::string TargetFileName(const std::string& path);

/// target.yml at `path` read within the text-input limits, checked as the project's YAML
/// (CheckYamlText) and opened: throws std::runtime_error naming it (TargetFileName) when it
/// cannot be; OpenCV's own parse errors propagate as cv::Exception.
cv::FileStorage OpenTargetFile(const std::string& path);

}  // namespace hnnstereo::calib
