#include "robot/frame_io.h"

#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <stdexcept>

#include "common/atomic_file.h"
#include "common/input_limits.h"

namespace hnnstereo::robot {

std::string RobotFrame::Check() const {
  const Eigen::Matrix4d m = robot_from_world.matrix();
  if (!m.allFinite()) return "robot_from_world is not finite";
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    return "robot_from_world's bottom row must be 0 0 0 1";
  }
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      std::abs(r.determinant() - 1.0) > 1e-6) {
    return "robot_from_world's rotation is not orthonormal with determinant +1";
  }
  SafetyLimits limits;
  limits.workspace_min = workspace_min;
  limits.workspace_max = workspace_max;
  if (auto error = limits.Check(); !error.empty()) return error;
  if (!std::isfinite(rms_mm) || rms_mm < 0.0) return "rms_mm must be a number >= 0";
  if (max_reach_mm && !(std::isfinite(*max_reach_mm) && *max_reach_mm > 0.0)) {
    return "max_reach_mm must be a positive number";
  }
  return {};
}

RobotFrame LoadRobotFrame(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) {
    throw std::invalid_argument("frame file '" + path + "' does not exist");
  }
  // Read within the text-file limits first (a FRAME.yml is a few hundred bytes), then parse
  // from memory.
  std::string text;
  try {
    text = calib::ReadTextFileWithin(path, "frame file");
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
  // YAML only, as CAL.yml and target.yml: OpenCV 4.6's XML parser dereferences a null pointer
  // on a file that ends inside its header ("<?xml version=", found by fuzz/fuzz_frame_yml.cc),
  // and OpenCV reads "<?xml" as XML whatever format flag it is given.
  if (const std::string problem = calib::CheckYamlText(text); !problem.empty()) {
    throw std::invalid_argument("frame file '" + path + "' " + problem);
  }
  cv::FileStorage storage;
  try {
    storage.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY |
                           cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception&) {
    throw std::invalid_argument("frame file '" + path + "' is not an OpenCV YAML file");
  }
  if (!storage.isOpened()) {
    throw std::invalid_argument("frame file '" + path + "' cannot be read as OpenCV YAML");
  }
  auto read = [&](const char* key, int rows, int cols) {
    cv::Mat m;
    // A matrix header claiming huge sizes would be allocated before its data is read.
    if (const std::string problem = calib::CheckMatrixNode(storage[key], 16); !problem.empty()) {
      throw std::invalid_argument("frame file '" + path + "': '" + key + "': " + problem);
    }
    try {
      storage[key] >> m;
    } catch (const cv::Exception&) {
      m.release();
    }
    if (m.empty() || m.rows != rows || m.cols != cols) {
      throw std::invalid_argument("frame file '" + path + "': '" + key + "' must be a " +
                                  std::to_string(rows) + "x" + std::to_string(cols) + " matrix");
    }
    m.convertTo(m, CV_64F);
    return m;
  };
  RobotFrame frame;
  Eigen::Matrix4d transform;
  cv::cv2eigen(read("robot_from_world", 4, 4), transform);
  frame.robot_from_world.matrix() = transform;
  cv::cv2eigen(read("workspace_min", 3, 1), frame.workspace_min);
  cv::cv2eigen(read("workspace_max", 3, 1), frame.workspace_max);
  if (storage["rms_mm"].empty() || !storage["rms_mm"].isReal()) {
    throw std::invalid_argument("frame file '" + path + "': 'rms_mm' must be a number");
  }
  frame.rms_mm = static_cast<double>(storage["rms_mm"]);
  if (!storage["max_reach_mm"].empty()) {
    if (!storage["max_reach_mm"].isReal() && !storage["max_reach_mm"].isInt()) {
      throw std::invalid_argument("frame file '" + path + "': 'max_reach_mm' must be a number");
    }
    frame.max_reach_mm = static_cast<double>(storage["max_reach_mm"]);
  }
  if (auto error = frame.Check(); !error.empty()) {
    throw std::invalid_argument("frame file '" + path + "': " + error);
  }
  return frame;
}

void SaveRobotFrame(const std::string& path, const RobotFrame& frame) {
  if (auto error = frame.Check(); !error.empty()) throw std::invalid_argument(error);
  calib::WriteAtomically(path, [&](const std::string& temporary) {
    // YAML whatever the extension (LoadRobotFrame reads YAML only).
    cv::FileStorage storage(temporary, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_YAML);
    if (!storage.isOpened()) throw std::runtime_error("cannot write '" + path + "'");
    cv::Mat transform, min, max;
    cv::eigen2cv(Eigen::Matrix4d(frame.robot_from_world.matrix()), transform);
    cv::eigen2cv(frame.workspace_min, min);
    cv::eigen2cv(frame.workspace_max, max);
    storage << "robot_from_world" << transform << "workspace_min" << min << "workspace_max" << max
            << "rms_mm" << frame.rms_mm;
    if (frame.max_reach_mm) storage << "max_reach_mm" << *frame.max_reach_mm;
  });
}

RobotFrame ThesisRobotFrame() {
  RobotFrame frame;
  frame.robot_from_world = Eigen::Isometry3d::Identity();
  frame.robot_from_world.rotate(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
  frame.robot_from_world.pretranslate(Eigen::Vector3d(600.0, 400.0, 0.0));
  // Exact half turn (cos pi is not exactly -1 in doubles).
  frame.robot_from_world.linear() = Eigen::Vector3d(-1, -1, 1).asDiagonal();
  // The rendered table maps to x_r in [320, 680], y_r in [-135, 165] mm; picks with their
  // approach reach z_r = 200 mm and lie at most 727 mm from the base.
  frame.workspace_min = Eigen::Vector3d(100.0, -300.0, 0.0);
  frame.workspace_max = Eigen::Vector3d(720.0, 300.0, 450.0);
  frame.max_reach_mm = 800.0;
  return frame;
}

}  // namespace hnnstereo::robot
