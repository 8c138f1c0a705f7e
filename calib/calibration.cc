#include "calib/calibration.h"

#include <Eigen/SVD>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <regex>
#include <sstream>
#include <stdexcept>

#include "common/atomic_file.h"
#include "calib/epipolar.h"
#include "common/input_limits.h"

namespace hnnstereo::calib {
namespace {

bool AllFinite(const Eigen::MatrixXd& m) { return m.allFinite(); }

template <int R, int C>
Eigen::Matrix<double, R, C> ReadMatrix(const cv::FileStorage& fs, const std::string& key,
                                       const std::string& path, bool required) {
  if (const std::string problem = CheckMatrixNode(fs[key], R * C); !problem.empty()) {
    throw std::runtime_error("calibration '" + path + "': '" + key + "' " + problem +
                             " (must be " + std::to_string(R) + "x" + std::to_string(C) + ")");
  }
  cv::Mat mat;
  fs[key] >> mat;
  if (mat.empty()) {
    if (required) throw std::runtime_error("calibration '" + path + "' has no '" + key + "'");
    return Eigen::Matrix<double, R, C>::Constant(std::nan(""));
  }
  if (mat.rows * mat.cols != R * C) {
    throw std::runtime_error("calibration '" + path + "': '" + key + "' must be " +
                             std::to_string(R) + "x" + std::to_string(C));
  }
  mat = mat.reshape(1, R);
  mat.convertTo(mat, CV_64F);
  Eigen::Matrix<double, R, C> out;
  cv::cv2eigen(mat, out);
  return out;
}

// Parses "[a b c; d e f; g h i]" as used by Middlebury calib.txt.
Eigen::Matrix3d ParseBracketMatrix(const std::string& text, const std::string& key) {
  std::string cleaned = text;
  for (char& c : cleaned) {
    if (c == '[' || c == ']' || c == ';' || c == ',') c = ' ';
  }
  std::istringstream in(cleaned);
  Eigen::Matrix3d m;
  for (int i = 0; i < 9; ++i) {
    if (!(in >> m(i / 3, i % 3))) {
      throw std::runtime_error("Middlebury calib.txt: '" + key + "' is not a 3x3 matrix");
    }
  }
  return m;
}

}  // namespace

void StereoCalibration::DeriveFromProjections() {
  F = FundamentalFromProjections(P1, P2);
  C1 = CameraCentre(P1);
  C2 = CameraCentre(P2);
}

std::string StereoCalibration::ImageSizeProblem(int cols, int rows) const {
  if (image_width <= 0 || (image_width == cols && image_height == rows)) return {};
  return "is for " + std::to_string(image_width) + "x" + std::to_string(image_height) +
         " images, the pair is " + std::to_string(cols) + "x" + std::to_string(rows);
}

std::string StereoCalibration::Check() const {
  if (!AllFinite(P1) || !AllFinite(P2)) return "P1 or P2 has non-finite values";
  if (!AllFinite(F)) return "F has non-finite values (NaN or infinity)";
  if (F.norm() == 0.0) return "F is zero";
  Eigen::JacobiSVD<ProjectionMatrix> svd1(P1), svd2(P2);
  if (svd1.singularValues()(2) <= 1e-12 * svd1.singularValues()(0)) return "P1 is rank-deficient";
  if (svd2.singularValues()(2) <= 1e-12 * svd2.singularValues()(0)) return "P2 is rank-deficient";
  if (image_width < 0 || image_height < 0) return "negative image size";
  const int max_side = TextInputLimits{}.max_image_side_px;
  if (image_width > max_side || image_height > max_side) {
    return "image size " + std::to_string(image_width) + "x" + std::to_string(image_height) +
           " is beyond the limit of " + std::to_string(max_side) + " px per side";
  }
  if (world_from_left_camera && !world_from_left_camera->allFinite()) {
    return "world_from_left_camera has non-finite values";
  }
  if (intrinsics) {
    const Intrinsics& intr = *intrinsics;
    auto finite = [](const std::vector<double>& values) {
      for (double v : values) {
        if (!std::isfinite(v)) return false;
      }
      return true;
    };
    // Lens distortion is applied to every feature: a NaN here would poison every match.
    if (!intr.K1.allFinite() || !intr.K2.allFinite() || !intr.R.allFinite() ||
        !intr.T.allFinite() || !finite(intr.D1) || !finite(intr.D2)) {
      return "the intrinsics (K1 D1 K2 D2 R T) have non-finite values";
    }
  }
  return {};
}

StereoCalibration ParseMiddleburyCalib(const std::string& text) {
  std::map<std::string, std::string> values;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    std::string key = line.substr(0, eq);
    key.erase(key.find_last_not_of(" \t\r") + 1);
    key.erase(0, key.find_first_not_of(" \t"));
    values[key] = line.substr(eq + 1);
  }
  for (const char* key : {"cam0", "cam1", "baseline"}) {
    if (!values.count(key)) {
      throw std::runtime_error(std::string("Middlebury calib.txt has no '") + key + "'");
    }
  }
  const Eigen::Matrix3d K0 = ParseBracketMatrix(values["cam0"], "cam0");
  const Eigen::Matrix3d K1 = ParseBracketMatrix(values["cam1"], "cam1");
  double baseline = 0.0;
  try {
    baseline = std::stod(values["baseline"]);
  } catch (const std::exception&) {
    throw std::runtime_error("Middlebury calib.txt: 'baseline' is not a number");
  }
  // stod accepts "nan" and "inf"; a zero baseline makes both cameras one (F = 0).
  if (!std::isfinite(baseline) || baseline == 0.0 ||
      std::abs(baseline) > TextInputLimits{}.max_abs_mm) {
    throw std::runtime_error("Middlebury calib.txt: 'baseline' must be a finite non-zero length "
                             "within +-1e7 mm (is '" + values["baseline"] + "')");
  }
  StereoCalibration cal;
  cal.P1.leftCols<3>() = K0;
  cal.P1.col(3).setZero();
  cal.P2.leftCols<3>() = K1;
  cal.P2.col(3) = K1 * Eigen::Vector3d(-baseline, 0.0, 0.0);
  // Strict integers: std::atoi has undefined behaviour on overflow and reads "1e9" as 1.
  const int max_side = TextInputLimits{}.max_image_side_px;
  for (const auto& [key, size] : {std::pair<const char*, int*>{"width", &cal.image_width},
                                  std::pair<const char*, int*>{"height", &cal.image_height}}) {
    if (!values.count(key)) continue;
    long long parsed = 0;
    if (!ParseIntWithin(values[key], 0, max_side, &parsed)) {
      throw std::runtime_error(std::string("Middlebury calib.txt: '") + key +
                               "' must be a whole number of pixels in [0, " +
                               std::to_string(max_side) + "] (is '" + values[key] + "')");
    }
    *size = static_cast<int>(parsed);
  }
  cal.rectified = true;
  cal.DeriveFromProjections();
  return cal;
}

StereoCalibration LoadCalibration(const std::string& path) {
  const std::string text = ReadTextFileWithin(path, "calibration file");

  StereoCalibration cal;
  if (text.find("cam0") != std::string::npos && text.find("baseline") != std::string::npos) {
    cal = ParseMiddleburyCalib(text);
  } else {
    if (const std::string problem = CheckYamlText(text); !problem.empty()) {
      throw std::runtime_error("calibration file '" + path + "' " + problem);
    }
    cv::FileStorage fs;
    try {
      fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
    } catch (const cv::Exception&) {
      throw std::runtime_error("calibration file '" + path + "' is not valid OpenCV YAML");
    }
    if (!fs.isOpened()) {
      throw std::runtime_error("calibration file '" + path + "' is not valid OpenCV YAML");
    }
    try {
      cal.P1 = ReadMatrix<3, 4>(fs, "P1", path, true);
      cal.P2 = ReadMatrix<3, 4>(fs, "P2", path, true);
      const Eigen::Matrix3d F = ReadMatrix<3, 3>(fs, "F", path, false);
      cal.DeriveFromProjections();
      if (!fs["F"].empty()) cal.F = F;  // keep a stored F (may be deliberately perturbed)
      // Read as a number first: OpenCV rounds a real into an int without a range check.
      for (const auto& [key, size] :
           {std::pair<const char*, int*>{"image_width", &cal.image_width},
            std::pair<const char*, int*>{"image_height", &cal.image_height}}) {
        const cv::FileNode node = fs[key];
        if (node.empty()) continue;
        const double value = node.isInt() || node.isReal() ? static_cast<double>(node) : -1.0;
        if (!(value >= 0.0 && value <= TextInputLimits{}.max_image_side_px) ||
            value != std::floor(value)) {
          throw std::runtime_error("calibration file '" + path + "': '" + key +
                                   "' must be a whole number of pixels in [0, " +
                                   std::to_string(TextInputLimits{}.max_image_side_px) + "]");
        }
        *size = static_cast<int>(value);
      }
      if (!fs["units"].empty()) fs["units"] >> cal.units;
      if (fs["world_frame"].isString()) fs["world_frame"] >> cal.world_frame;
      if (!fs["world_from_left_camera"].empty()) {
        cal.world_from_left_camera = ReadMatrix<4, 4>(fs, "world_from_left_camera", path, true);
      }
      if (!fs["rectified"].empty()) {
        // As a double: OpenCV's int read rounds a huge real without a range check.
        cal.rectified = static_cast<double>(fs["rectified"]) != 0.0;
      }
      if (!fs["K1"].empty() && !fs["K2"].empty()) {
        Intrinsics intr;
        intr.K1 = ReadMatrix<3, 3>(fs, "K1", path, true);
        intr.K2 = ReadMatrix<3, 3>(fs, "K2", path, true);
        // At most 14 distortion coefficients (OpenCV's largest model).
        for (const char* key : {"D1", "D2"}) {
          if (const std::string problem = CheckMatrixNode(fs[key], 14); !problem.empty()) {
            throw std::runtime_error("calibration file '" + path + "': '" + key + "' " + problem);
          }
        }
        cv::Mat d;
        fs["D1"] >> d;
        if (!d.empty()) d.reshape(1, 1).convertTo(d, CV_64F), intr.D1.assign(d.begin<double>(), d.end<double>());
        fs["D2"] >> d;
        if (!d.empty()) d.reshape(1, 1).convertTo(d, CV_64F), intr.D2.assign(d.begin<double>(), d.end<double>());
        if (!fs["R"].empty()) intr.R = ReadMatrix<3, 3>(fs, "R", path, true);
        if (!fs["T"].empty()) intr.T = ReadMatrix<3, 1>(fs, "T", path, true);
        cal.intrinsics = intr;
      }
    } catch (const cv::Exception& e) {
      throw std::runtime_error("calibration file '" + path + "' is malformed: " + e.err);
    }
  }
  if (const std::string problem = cal.Check(); !problem.empty()) {
    throw std::runtime_error("calibration file '" + path + "': " + problem);
  }
  return cal;
}

void SaveCalibration(const StereoCalibration& cal, const std::string& path) {
  if (const std::string problem = cal.Check(); !problem.empty()) {
    throw std::runtime_error("refusing to write calibration '" + path + "': " + problem);
  }
  auto to_mat = [](const auto& m) {
    cv::Mat out;
    cv::eigen2cv(Eigen::MatrixXd(m), out);
    return out;
  };
  WriteAtomically(path, [&](const std::string& temporary) {
    cv::FileStorage fs(temporary, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_YAML);
    if (!fs.isOpened()) throw std::runtime_error("cannot open '" + path + "' for writing");
    fs << "units" << cal.units;
    fs << "image_width" << cal.image_width << "image_height" << cal.image_height;
    fs << "rectified" << static_cast<int>(cal.rectified);
    if (!cal.world_frame.empty()) fs << "world_frame" << cal.world_frame;
    if (cal.world_from_left_camera) {
      fs << "world_from_left_camera" << to_mat(*cal.world_from_left_camera);
    }
    fs << "P1" << to_mat(cal.P1) << "P2" << to_mat(cal.P2);
    fs << "F" << to_mat(cal.F);
    fs << "F_right_to_left" << to_mat(cal.F.transpose());
    fs << "C1" << to_mat(cal.C1) << "C2" << to_mat(cal.C2);
    if (cal.intrinsics) {
      const Intrinsics& intr = *cal.intrinsics;
      fs << "K1" << to_mat(intr.K1) << "D1" << cv::Mat(intr.D1, true).reshape(1, 1);
      fs << "K2" << to_mat(intr.K2) << "D2" << cv::Mat(intr.D2, true).reshape(1, 1);
      fs << "R" << to_mat(intr.R) << "T" << to_mat(intr.T);
    }
    for (const auto& [name, value] : cal.error_figures) fs << name << value;
    fs.release();
  });
}

}  // namespace hnnstereo::calib
