#pragma once
// Calibration from known 3D-2D points per camera (`calibrate --points-left F --points-right F`):
// text files with one correspondence per line, "X Y Z u v" (world mm, pixels), '#' comments.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "calib/calibration_report.h"
#include "calib/dlt.h"

namespace hnnstereo::calib {

/// The correspondences of one camera.
struct KnownPoints {
  std::vector<Eigen::Vector3d> points3D_in_world;  ///< mm
  std::vector<Eigen::Vector2d> image_points;       ///< px, 0-based, pixel centres at integers
};

/// Parses the text of a points file: "X Y Z u v" per line, blank lines and '#' comments skipped.
/// @throws std::runtime_error naming `source` and the line (wrong field count, not a number,
///         NaN or infinity).
KnownPoints ParseKnownPoints(const std::string& text, const std::string& source);

/// Reads and parses a points file. @throws std::runtime_error (missing, unreadable, malformed).
KnownPoints ReadKnownPoints(const std::string& path);

/// DLT for each camera from the two cameras' points; the epipolar figure pairs points with equal
/// world coordinates. @throws std::runtime_error with a one-line reason (coplanar, fewer than 6).
CalibrationResult CalibrateFromKnownPoints(const KnownPoints& left, const KnownPoints& right,
                                           const DltOptions& options = {});

/// ReadKnownPoints for each file, then the DLT for each camera; the epipolar figure pairs points with equal world
/// coordinates. The overlays are drawn on white canvases (no images are known).
/// @throws std::runtime_error with a one-line reason (e.g. coplanar points, fewer than 6).
CalibrationResult CalibrateFromKnownPoints(const std::string& left_points_path,
                                           const std::string& right_points_path,
                                           const DltOptions& options = {});

}  // namespace hnnstereo::calib
