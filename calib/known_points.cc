#include "calib/known_points.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "calib/circle_calibration.h"
#include "common/input_limits.h"

namespace hnnstereo::calib {

KnownPoints ParseKnownPoints(const std::string& text, const std::string& source) {
  KnownPoints points;
  std::istringstream in(text);
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream fields(line);
    std::vector<double> values;
    std::string token;
    while (fields >> token) {
      char* end = nullptr;
      const double value = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') {
        throw std::runtime_error("points file '" + source + "' line " +
                                 std::to_string(line_number) + ": '" + token + "' is not a number");
      }
      if (!std::isfinite(value)) {
        throw std::runtime_error("points file '" + source + "' line " +
                                 std::to_string(line_number) + ": non-finite value '" + token +
                                 "'");
      }
      // 1e7 (mm for X Y Z, px for u v) is beyond any cell or image; larger values would square
      // to ~1e28 in the DLT's normal equations and swamp everything else.
      if (std::abs(value) > TextInputLimits{}.max_abs_mm) {
        throw std::runtime_error("points file '" + source + "' line " +
                                 std::to_string(line_number) + ": '" + token +
                                 "' is beyond +-1e7 (mm or px)");
      }
      values.push_back(value);
    }
    if (values.empty()) continue;
    if (values.size() != 5) {
      throw std::runtime_error("points file '" + source + "' line " + std::to_string(line_number) +
                               ": expected 5 numbers 'X Y Z u v', got " +
                               std::to_string(values.size()));
    }
    points.points3D_in_world.emplace_back(values[0], values[1], values[2]);
    points.image_points.emplace_back(values[3], values[4]);
  }
  return points;
}

KnownPoints ReadKnownPoints(const std::string& path) {
  return ParseKnownPoints(ReadTextFileWithin(path, "points file"), path);
}

CalibrationResult CalibrateFromKnownPoints(const std::string& left_points_path,
                                           const std::string& right_points_path,
                                           const DltOptions& options) {
  return CalibrateFromKnownPoints(ReadKnownPoints(left_points_path),
                                  ReadKnownPoints(right_points_path), options);
}

CalibrationResult CalibrateFromKnownPoints(const KnownPoints& left, const KnownPoints& right,
                                           const DltOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  CalibrationResult result =
      CalibrateFromCorrespondences("points", {left.points3D_in_world}, {left.image_points},
                                   {right.points3D_in_world}, {right.image_points}, options);
  for (CameraCalibrationReport& camera : result.report.cameras) {
    camera.overlay = DrawCalibrationOverlay(cv::Mat(), camera.observations);
  }
  result.report.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hnnstereo::calib
