#pragma once
// Stereo calibration from chessboard image pairs with OpenCV (Zhang 2000, "A flexible new
// technique for camera calibration"; OpenCV calib3d): corner detection with sub-pixel
// refinement, intrinsics with distortion per camera (cv::calibrateCamera), then the pair
// (cv::stereoCalibrate with the intrinsics fixed). The world frame of the result is the LEFT
// CAMERA frame in millimetres: P1 = K1 [I | 0], P2 = K2 [R | T]; P and F apply to undistorted
// pixel coordinates (D1, D2 are written; `match`/`pick` undistort when D is present).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration_report.h"

namespace hnnstereo::calib {

/// Options of the chessboard calibration.
struct ChessboardOptions {
  int rows = 6;                          ///< inner corners per column (OpenCV sample board: 6)
  int cols = 9;                          ///< inner corners per row (OpenCV sample board: 9)
  double square_mm = 25.0;               ///< side of one square (mm)
  std::vector<std::string> left_images;  ///< one per pair, same order as right_images
  std::vector<std::string> right_images;
  int subpixel_window = 11;  ///< cornerSubPix window size (px), as in OpenCV's stereo_calib
  /// Pairs in which the board is found in both images; fewer is an error.
  int min_pairs = 3;
  /// Put every detection in the board's own order (OrientChessboardCorners): both cameras then
  /// label each corner alike, and a board lying on the table fixes its frame. Needs rows + cols
  /// odd; off for the --target chessboard route (OpenCV's own order, as stereo_calib.cpp).
  bool orient_by_square_colour = false;
  /// Keep k3 = 0 (cv::CALIB_FIX_K3): a standard lens needs k1 k2 p1 p2 only, and views that do
  /// not reach the image corners let a free k3 overfit (k3 = -17 on the rendered cell). Off for
  /// --target chessboard (OpenCV's stereo_calib.cpp estimates k3).
  bool fix_k3 = false;
  /// Views whose board only one camera shows still calibrate that camera's intrinsics (the
  /// image corners, where distortion is largest, are seldom seen by both cameras at once); the
  /// stereo step uses the pairs. Off for --target chessboard (stereo_calib.cpp uses pairs only).
  bool single_camera_views = false;

  std::string Check() const;
};

/// Chessboard corners of one image (row-major over rows x cols inner corners, OpenCV order),
/// refined to sub-pixel; std::nullopt when the board is not found. `image` grey or BGR.
std::optional<std::vector<Eigen::Vector2d>> DetectChessboardCorners(const cv::Mat& image, int rows,
                                                                    int cols,
                                                                    int subpixel_window = 11);

/// Reorders `corners` (row-major rows x cols, as cv::findChessboardCorners gives them) into the
/// board's own frame: the board's +z (x along a row, y along a column) faces the camera, so
/// cross(d_col, d_row) < 0 in pixels (else the rows are reversed), and the square between corners
/// (0, 0) and (1, 1) is the dark one (else the order is reversed: the 180 deg turn). Unambiguous
/// when rows + cols is odd (OpenCV's advice for such boards). `grey` is the image searched.
void OrientChessboardCorners(const cv::Mat& grey, int rows, int cols,
                             std::vector<Eigen::Vector2d>* corners);

/// The images of a chessboard calibration (grey), in the order of ChessboardOptions' paths.
struct ChessboardImages {
  std::vector<cv::Mat> left, right;
};

/// Reads every image `options` names, before any detection (`calibrate` refuses a bad input as
/// a setup error). @throws std::runtime_error naming the image: missing, unreadable, or not the
/// size of its camera's first image.
ChessboardImages LoadChessboardImages(const ChessboardOptions& options);

/// Runs the calibration on the images LoadChessboardImages read for `options`.
/// @throws std::runtime_error naming the option at fault, or when too few pairs show the board.
CalibrationResult CalibrateChessboard(const ChessboardOptions& options,
                                      const ChessboardImages& images);

/// Reads the images, then runs the calibration. Report extras: opencv_rms_left_px, opencv_rms_right_px (as returned by
/// cv::calibrateCamera), stereo_rms_px, num_pairs, skipped images.
/// @throws std::runtime_error naming the image or option at fault.
CalibrationResult CalibrateChessboard(const ChessboardOptions& options);

}  // namespace hnnstereo::calib
