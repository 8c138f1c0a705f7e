#include "calib/target_file.h"

#include <stdexcept>

#include "common/input_limits.h"

namespace hnnstereo::calib {

std::string TargetFileName(const std::string& path) { return "target.yml '" + path + "'"; }

cv::FileStorage OpenTargetFile(const std::string& path) {
  const std::string text = ReadTextFileWithin(path, "target.yml");
  if (const std::string problem = CheckYamlText(text); !problem.empty()) {
    throw std::runtime_error(TargetFileName(path) + " " + problem);
  }
  cv::FileStorage storage(text, cv::FileStorage::READ | cv::FileStorage::MEMORY |
                                    cv::FileStorage::FORMAT_YAML);
  if (!storage.isOpened()) throw std::runtime_error(TargetFileName(path) + " cannot be read");
  return storage;
}

}  // namespace hnnstereo::calib
