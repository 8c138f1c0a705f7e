#pragma once
// A synthetic image of the circle target (calib/circle_target.h) seen through a projective
// camera: white plate with dark circles on a dark table, anti-aliased, blurred, with sensor noise
// and optional distracting blobs (reflections, other circular marks). Used by the calibration
// tests and by the synthetic pick-cell renderer (`hnnstereo render`, its target/ folder).

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "calib/circle_target.h"

namespace hnnstereo::calib {

/// How the target image is rendered.
struct CircleTargetRenderOptions {
  int image_width = 640;          ///< px
  int image_height = 480;         ///< px
  double plate_margin_mm = 20.0;  ///< plate border beyond the outer circle centres (mm)
  double table_grey = 70.0;       ///< grey level of the background (table)
  double plate_grey = 215.0;      ///< grey level of the plate
  double circle_grey = 35.0;      ///< grey level of the circles
  double blur_sigma_px = 0.8;     ///< Gaussian blur (optics), px
  double noise_sigma_grey = 2.0;  ///< additive Gaussian sensor noise, grey levels
  /// Random shift (Gaussian, per axis, px) applied to each circle's image: localisation noise
  /// whose size is known exactly (the "0.2 px noise" of the acceptance test).
  double centre_jitter_px = 0.0;
  /// Distracting blobs placed off the plate: bright reflections, some with dark circular,
  /// elliptic or square marks inside (circular ones pass the circularity check on purpose).
  int num_distractors = 0;
  int supersampling = 4;          ///< anti-aliasing factor
  std::uint64_t random_seed = 1;  ///< seeds noise, jitter and distractors

  std::string Check() const;
};

/// The rendered image and its truth.
struct RenderedCircleTarget {
  cv::Mat image;                            ///< 8-bit grey
  std::vector<Eigen::Vector2d> centres_px;  ///< true circle centres (row-major), incl. jitter
  std::vector<Eigen::Vector2d> distractor_centres_px;
  bool fully_visible = false;  ///< the whole plate lies inside the image
};

/// Renders `grid` at `world_from_target` through `P` (x ~ P X, world in mm).
/// @throws std::invalid_argument on invalid options or a target behind the camera.
RenderedCircleTarget RenderCircleTarget(const ProjectionMatrix& P,
                                        const Eigen::Matrix4d& world_from_target,
                                        const CircleGridGeometry& grid,
                                        const CircleTargetRenderOptions& options = {});

/// A pinhole camera P = K [R | -R C] at `centre_mm` looking at `look_at_mm`, with the image's
/// "up" as close to `up_in_world` as possible. For tests and synthetic scenes.
ProjectionMatrix LookAtCamera(double focal_px, const Eigen::Vector2d& principal_point_px,
                              const Eigen::Vector3d& centre_mm, const Eigen::Vector3d& look_at_mm,
                              const Eigen::Vector3d& up_in_world);

}  // namespace hnnstereo::calib
