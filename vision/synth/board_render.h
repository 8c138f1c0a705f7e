#pragma once
// A synthetic image of a chessboard (calib/board_calibration.h) seen through a camera with
// optional Brown-Conrady distortion (vision/synth/lens_model.h): the pinhole image ray cast per
// sub-sample onto the board's plane (white border, dark table around it), resampled through the
// lens, blurred, with sensor noise. The board images of `render`'s target/, for `calibrate --dir`.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/board_calibration.h"
#include "calib/calibration.h"

namespace hnnstereo::vision {

/// How a board image is rendered.
struct BoardRenderOptions {
  int image_width = 640;          ///< px
  int image_height = 480;         ///< px
  int supersampling = 4;          ///< rays per pixel along each axis
  double table_grey = 60.0;       ///< grey level around the board
  double light_grey = 215.0;      ///< light squares and the border
  double dark_grey = 35.0;        ///< dark squares
  double blur_sigma_px = 0.6;     ///< Gaussian blur (optics), px
  double noise_sigma_grey = 2.0;  ///< additive Gaussian sensor noise, grey levels
  std::vector<double> distortion; ///< k1, k2, p1, p2 [, k3]; empty = pinhole
  std::uint64_t random_seed = 1;  ///< seeds the noise
};

/// The rendered board and whether all of it (border included) lies inside the image.
struct RenderedBoard {
  cv::Mat image;  ///< 8-bit grey
  bool fully_visible = false;
};

/// Renders `board` at `world_from_board` through P = K [R | t] (K from P) and options.distortion.
RenderedBoard RenderChessboard(const calib::ProjectionMatrix& P,
                               const Eigen::Matrix4d& world_from_board,
                               const calib::ChessboardGeometry& board,
                               const BoardRenderOptions& options);

}  // namespace hnnstereo::vision
