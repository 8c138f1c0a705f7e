#pragma once
// The stereo calibration a pick cell runs from, and its file forms (ARCHITECTURE.md, CAL.yml).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace hnnstereo::calib {

using ProjectionMatrix = Eigen::Matrix<double, 3, 4>;

/// Optional OpenCV-style intrinsic calibration (chessboard path).
struct Intrinsics {
  Eigen::Matrix3d K1, K2;                ///< camera matrices
  std::vector<double> D1, D2;            ///< distortion coefficients (OpenCV order)
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< right_from_left rotation
  Eigen::Vector3d T = Eigen::Vector3d::Zero();      ///< right_from_left translation (mm)
};

/// A stereo calibration: both projection matrices in the world frame (mm), F and the centres.
struct StereoCalibration {
  ProjectionMatrix P1 = ProjectionMatrix::Zero();  ///< left camera, x1 ~ P1 X
  ProjectionMatrix P2 = ProjectionMatrix::Zero();  ///< right camera, x2 ~ P2 X
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();     ///< x2^T F x1 = 0
  Eigen::Vector3d C1 = Eigen::Vector3d::Zero();    ///< left camera centre (world, mm)
  Eigen::Vector3d C2 = Eigen::Vector3d::Zero();    ///< right camera centre (world, mm)
  int image_width = 0;
  int image_height = 0;
  std::string units = "mm";
  bool rectified = false;                 ///< true for a rectified pair (Middlebury calib.txt)
  std::optional<Intrinsics> intrinsics;   ///< present after a chessboard calibration
  /// What the world frame is, as the calibrator knows it (CAL.yml `world_frame`): "table" (z = 0
  /// on the table, z up), "left camera" (--target chessboard), empty when not recorded.
  std::string world_frame;
  /// The left camera's pose in the table frame (CAL.yml `world_from_left_camera`, 4x4, mm), from
  /// a board lying on the table; absent otherwise.
  std::optional<Eigen::Matrix4d> world_from_left_camera;
  /// Error figures written by the calibrator (name -> value), e.g. "left_rms_px".
  std::vector<std::pair<std::string, double>> error_figures;

  /// Fills F, C1 and C2 from P1 and P2.
  void DeriveFromProjections();
  /// Empty when usable; otherwise a one-line reason (non-finite values, rank-deficient P...).
  std::string Check() const;
  /// Empty when images of cols x rows fit this calibration (or it records no size); otherwise
  /// "is for WxH images, the pair is cols x rows" - P and F hold for the calibrated size only.
  std::string ImageSizeProblem(int cols, int rows) const;
};

/// Reads a CAL.yml (OpenCV FileStorage YAML) or a Middlebury calib.txt (chosen by content).
/// Throws std::runtime_error with a one-line reason on a missing, unreadable or invalid file.
StereoCalibration LoadCalibration(const std::string& path);

/// Parses the text of a Middlebury 2014 calib.txt: P1 = K0 [I | 0], P2 = K1 [I | (-b, 0, 0)].
StereoCalibration ParseMiddleburyCalib(const std::string& text);

/// Writes CAL.yml atomically (temporary file, then rename). Throws std::runtime_error.
void SaveCalibration(const StereoCalibration& calibration, const std::string& path);

}  // namespace hnnstereo::calib
