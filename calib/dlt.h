#pragma once
// Projection matrix of one camera from 3D-2D correspondences: the Hartley-normalised direct
// linear transform (DLT) of the thesis (ch. 3.2.3, eq. 3.9), followed by an optional nonlinear
// refinement of the reprojection error (the thesis left a stub for it).
// Hartley & Zisserman, "Multiple View Geometry", 2nd ed., algorithm 7.1 (Gold Standard).
// Pure functions over Eigen: no I/O, no logging, no globals.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "calib/calibration.h"

namespace hnnstereo::calib {

/// Options of EstimateProjectionDlt. Defaults follow the thesis, plus the refinement it lacked.
struct DltOptions {
  /// Minimise the geometric reprojection error with Levenberg-Marquardt after the linear DLT
  /// (the linear DLT minimises an algebraic error; H&Z 7.2). The thesis stopped at the DLT.
  bool refine_nonlinear = true;
  /// Levenberg-Marquardt iteration limit of the refinement.
  int max_refinement_iterations = 100;
  /// Fewest correspondences accepted (11 unknowns, two equations per point: 6 points).
  int min_points = 6;
  /// World points whose smallest spread (singular value of the centred point cloud) is below this
  /// fraction of the largest are "planar": the DLT is degenerate for them (H&Z 7.1, thesis 3.2.3:
  /// "at least two different heights").
  double min_non_planarity = 1e-3;

  /// Empty when valid, otherwise a readable reason naming the field and its value.
  std::string Check() const;
};

/// Reprojection errors of one camera: residual = projected - measured, in pixels.
/// MAE is the mean absolute error, RMS the root mean square; they are labelled as such (the
/// thesis GUI called a mean absolute error a "mean square error").
struct ReprojectionStatistics {
  std::vector<Eigen::Vector2d> residuals_px;  ///< per point, projected - measured (px)
  double mae_x_px = 0.0;                      ///< mean |dx|
  double mae_y_px = 0.0;                      ///< mean |dy|
  double rms_x_px = 0.0;                      ///< sqrt(mean dx^2)
  double rms_y_px = 0.0;                      ///< sqrt(mean dy^2)
  double mae_px = 0.0;                        ///< mean per-point Euclidean error |(dx, dy)|
  double rms_px = 0.0;                        ///< sqrt(mean (dx^2 + dy^2))
  double max_px = 0.0;                        ///< largest per-point Euclidean error
};

/// What EstimateProjectionDlt did and how well.
struct DltReport {
  ProjectionMatrix P = ProjectionMatrix::Zero();            ///< x ~ P X, scaled so that P(2,3) = 1
  Eigen::Vector3d camera_centre = Eigen::Vector3d::Zero();  ///< C with P C = 0 (world units)
  int num_points = 0;
  ReprojectionStatistics linear;  ///< errors of the linear (normalised) DLT
  ReprojectionStatistics final;   ///< errors of the returned P (after refinement if enabled)
  bool refined = false;           ///< true when the nonlinear refinement ran and was kept
  int refinement_iterations = 0;
};

/// Estimates P from `points3D_in_world[i]` <-> `image_points[i]` (pixels) with the normalised
/// DLT: image points moved to centroid 0 and mean distance sqrt(2), world points to mean
/// distance sqrt(3) (H&Z 4.4.4), two equations per point, the right singular vector of the
/// smallest singular value, denormalised, scaled to P(2,3) = 1 (thesis); then optionally refined.
/// @throws std::invalid_argument when the sizes differ, fewer than options.min_points points are
///         given, a value is not finite, or the world points are coplanar (degenerate).
DltReport EstimateProjectionDlt(const std::vector<Eigen::Vector3d>& points3D_in_world,
                                const std::vector<Eigen::Vector2d>& image_points,
                                const DltOptions& options = {});

/// Projects X through P (pixels).
Eigen::Vector2d Project(const ProjectionMatrix& P, const Eigen::Vector3d& point3D_in_world);

/// Per-point and per-axis reprojection errors of P on the given correspondences.
ReprojectionStatistics ComputeReprojectionStatistics(
    const ProjectionMatrix& P, const std::vector<Eigen::Vector3d>& points3D_in_world,
    const std::vector<Eigen::Vector2d>& image_points);

/// Statistics of given residual vectors (projected - measured).
ReprojectionStatistics SummariseResiduals(std::vector<Eigen::Vector2d> residuals_px);

/// Hartley's isotropic normalisation (H&Z 4.4.4): T with centroid -> 0 and mean distance
/// -> sqrt(2) (2D). Returns identity for an empty or single-point set.
Eigen::Matrix3d HartleyNormalisation2D(const std::vector<Eigen::Vector2d>& points);
/// The 3D counterpart: mean distance sqrt(3).
Eigen::Matrix4d HartleyNormalisation3D(const std::vector<Eigen::Vector3d>& points);

/// The linear DLT system A p = 0 (two rows per point, p = P row-major) of already normalised
/// points, as its 12x12 normal matrix A^T A. Used by the circle-target ordering to compare many
/// labelings cheaply.
Eigen::Matrix<double, 12, 12> DltNormalMatrix(const std::vector<Eigen::Vector3d>& points3D,
                                              const std::vector<Eigen::Vector2d>& image_points);

}  // namespace hnnstereo::calib
