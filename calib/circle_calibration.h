#pragma once
// Stereo calibration from the circle target at several known heights (thesis ch. 3.2.5):
// TARGET_DIR/target.yml (schema in docs/calibration.md) names the left and right image of each
// height and the target's world pose; circles are detected and ordered automatically
// (calib/circle_target.h), the rotation of a symmetric grid is chosen per height from the world
// poses, and each camera gets a normalised DLT (calib/dlt.h).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <functional>
#include <string>
#include <vector>

#include "calib/calibration_report.h"
#include "calib/circle_target.h"
#include "calib/dlt.h"

namespace hnnstereo::calib {

/// One placement of the target, seen by both cameras.
struct TargetPlacement {
  std::string left_image;  ///< path (relative paths in target.yml are relative to TARGET_DIR)
  std::string right_image;
  Eigen::Matrix4d world_from_target = Eigen::Matrix4d::Identity();  ///< mm
};

/// The content of target.yml.
struct TargetDescription {
  CircleGridGeometry grid;
  bool dark_circles = true;                 ///< black circles on a white plate
  std::vector<TargetPlacement> placements;  ///< one per height, at least two

  std::string Check() const;
};

/// Reads DIR/target.yml; image paths are resolved against DIR and must exist.
/// @throws std::runtime_error with a one-line reason (missing folder or file, bad YAML, missing
///         or non-finite field, fewer than two placements, missing image).
TargetDescription LoadTargetDirectory(const std::string& target_dir);

/// Writes `target` as a target.yml (atomically); image paths are written as given, poses as
/// `world_from_target` 4x4 matrices. Used by synthetic scene renderers and tests.
/// `more_keys`, when given, writes further keys after the circle ones (the board's).
void SaveTargetDescription(const TargetDescription& target, const std::string& path,
                           const std::function<void(cv::FileStorage*)>& more_keys = {});

/// The rotation chosen per view for a symmetric grid, and how it was decided.
struct GridRotationChoice {
  std::vector<int> rotation_per_view;  ///< index into GridRotations(rows, cols)
  /// The world poses could not tell some rotations apart (e.g. the target moved only along the
  /// vertical through one point); the image-direction rule decided.
  bool decided_by_image_rule = false;
  int num_equivalent = 1;            ///< labelings explaining the data equally well
  double algebraic_residual = 0.0;   ///< smallest eigenvalue of the normalised DLT system
  double reprojection_rms_px = 0.0;  ///< RMS of the linear DLT of the chosen labeling (px)
};

/// Chooses, per view v, the grid rotation r_v (applied as centres'[i] = centres[rotations[r][i]])
/// under which all views together are best explained by one projective camera: the labeling
/// whose camera sees every point in front of it (cheirality) with the smallest reprojection RMS
/// of the linear DLT. Search: exhaustive over the first views (enough to leave one plane, at most
/// 7); from every cheiral seed, each further view joins with the rotation that keeps the
/// accumulated DLT system most consistent (smallest eigenvalue). Labelings with an RMS within
/// 1.25 x best + 0.02 px are equivalent (the poses cannot tell them apart: two heights only, or
/// moves along one vertical axis); among them the one whose world +X axis appears closest to the
/// image's +u direction is chosen (docs/calibration.md, orientation rule).
/// @throws std::invalid_argument on inconsistent sizes.
GridRotationChoice ChooseGridRotations(
    const std::vector<std::vector<Eigen::Vector3d>>& points3D_per_view,
    const std::vector<std::vector<Eigen::Vector2d>>& canonical_centres_per_view,
    const std::vector<std::vector<int>>& rotations);

/// Options of the circle-target calibration.
struct CircleCalibrationOptions {
  CircleDetectionOptions detection;  ///< dark_circles is taken from target.yml
  CircleGridOptions grid;
  DltOptions dlt;
  std::string Check() const;
};

/// target.yml with its images (grey, one per placement and camera), read before any detection.
struct TargetImages {
  TargetDescription target;
  std::vector<cv::Mat> left, right;
};

/// Reads DIR/target.yml (LoadTargetDirectory) and every image it names, so that `calibrate`
/// refuses a bad input as a setup error. @throws std::runtime_error naming the file: as
/// LoadTargetDirectory, an unreadable image, an image not the size of its camera's first.
TargetImages LoadTargetImages(const std::string& target_dir);

/// Detects, orders and calibrates from images LoadTargetImages read. The overlays are drawn on
/// the first height's images. @throws std::runtime_error naming the image or field at fault.
CalibrationResult CalibrateCircleTarget(const TargetImages& images,
                                        const CircleCalibrationOptions& options = {});

/// LoadTargetImages, then CalibrateCircleTarget. Detects, orders and calibrates from TARGET_DIR. The overlays are drawn on the first height's
/// images. @throws std::runtime_error naming the image or field at fault.
CalibrationResult CalibrateCircleTarget(const std::string& target_dir,
                                        const CircleCalibrationOptions& options = {});

/// Calibration from already known correspondences per camera and view (the circle pipeline
/// after detection; also used by tests). Views with the same index in both cameras pair up for
/// the epipolar figure.
CalibrationResult CalibrateFromCorrespondences(
    const std::string& method, const std::vector<std::vector<Eigen::Vector3d>>& left_world,
    const std::vector<std::vector<Eigen::Vector2d>>& left_image,
    const std::vector<std::vector<Eigen::Vector3d>>& right_world,
    const std::vector<std::vector<Eigen::Vector2d>>& right_image, const DltOptions& options);

}  // namespace hnnstereo::calib
