#pragma once
// Stereo calibration with lens distortion in the table frame, from a chessboard: the board in
// several poses gives each camera's intrinsics with distortion (Zhang 2000, cv::calibrateCamera)
// and the stereo extrinsics (cv::stereoCalibrate), through CalibrateChessboard; one or more views
// of the board lying on the table, whose world pose target.yml gives, fix the world frame: their
// corners, undistorted and triangulated by the rig, are fitted rigidly to the board's world
// points (Umeyama 1991, no scale). Then P1 = K1 [R1 | t1], P2 = K2 [R R1 | R t1 + T] in the
// table frame (z = 0 on the table, z up, mm), for undistorted pixels; K1 D1 K2 D2 R T as OpenCV
// writes them. TARGET_DIR/target.yml names the board and its views (docs/calibration.md).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration_report.h"

namespace hnnstereo::calib {

/// A printed chessboard. Board frame: origin at inner corner (0, 0), +x along a row (increasing
/// column), +y along a column (increasing row), +z out of the printed face; inner corner (r, c)
/// at (c * square, r * square, 0); the square between inner corners (0, 0) and (1, 1) is dark.
struct ChessboardGeometry {
  int rows = 6;              ///< inner corners per column; rows + cols must be odd
  int cols = 9;              ///< inner corners per row
  double square_mm = 20.0;   ///< side of one square (mm)
  double margin_mm = 15.0;   ///< white border beyond the outer squares (mm); renderer only

  std::string Check() const;
  /// The inner corners in the board frame (mm), row-major.
  std::vector<Eigen::Vector3d> Corners() const;
};

/// One view of the board, seen by both cameras.
struct BoardView {
  std::string left_image;   ///< path; relative paths in target.yml are relative to TARGET_DIR
  std::string right_image;
  /// The board's pose (mm). Required for a view on the table: it defines the world frame there
  /// (its z = the board's thickness). For other views it is the truth, when known (renderer).
  Eigen::Matrix4d world_from_board = Eigen::Matrix4d::Identity();
  bool on_table = false;    ///< the board lies on the table: fixes the world frame
};

/// The board part of target.yml (`board: chessboard`, `board_rows`, `board_cols`,
/// `board_square_mm`, `board_views`).
struct BoardTarget {
  ChessboardGeometry board;
  std::vector<BoardView> views;
  std::string Check() const;  ///< >= 3 views, >= 1 on the table
};

/// Writes the board keys into an open target.yml (after the circle keys, if any).
void WriteBoardTarget(const BoardTarget& target, cv::FileStorage* storage);

/// The board part of DIR/target.yml; std::nullopt when target.yml names no board. Image paths
/// are resolved against DIR. @throws std::runtime_error with a one-line reason.
std::optional<BoardTarget> LoadBoardTarget(const std::string& target_dir);

/// Options of the board calibration.
struct BoardCalibrationOptions {
  /// cornerSubPix half window (px): 5 (an 11 x 11 window) stays inside one square down to
  /// squares of 12 px.
  int subpixel_window = 5;
  /// k1 k2 p1 p2 only (ChessboardOptions::fix_k3); false estimates k3 too (wide-angle lenses,
  /// with views reaching the image corners).
  bool fix_k3 = true;
  std::string Check() const;
};

/// Calibrates from the board views (CalibrateChessboard with corners in the board's own order),
/// then fixes the table frame from the views on the table. Report extras: those of
/// CalibrateChessboard plus table_views, table_fit_rms_mm (3D residual of the rigid fit),
/// table_reprojection_rms_left_px / _right_px (the table board through the final cameras).
/// @throws std::runtime_error naming the image or field at fault.
CalibrationResult CalibrateBoardTarget(const BoardTarget& target,
                                       const BoardCalibrationOptions& options = {});

}  // namespace hnnstereo::calib
