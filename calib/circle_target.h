#pragma once
// The circle calibration target of the thesis (ch. 3.2.4-3.2.5, fig. 3.3): a plate with a
// rows x cols grid of circles. Detection (threshold, border following, circularity check,
// sub-pixel centres) and the automatic ordering of the circles to grid positions that replaces
// the thesis's 108 mouse clicks. OpenCV at the image edge; the grid geometry in Eigen.
//
// Target frame: origin at the centre of circle (row 0, col 0), +x along increasing column,
// +y along increasing row, +z out of the printed face (towards the cameras). Circle (r, c) is at
// (c * pitch, r * pitch, 0) in the target frame. Grid points are indexed row-major: r * cols + c.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace hnnstereo::calib {

/// The physical grid of a circle target.
struct CircleGridGeometry {
  int rows = 3;                   ///< circle rows (thesis: 3)
  int cols = 3;                   ///< circle columns (thesis: 3)
  double pitch_mm = 25.0;         ///< centre-to-centre distance of neighbouring circles (thesis)
  double circle_radius_mm = 7.0;  ///< circle radius; used by the renderer only

  std::string Check() const;
  int size() const { return rows * cols; }
  /// Circle (row, col) in the target frame (mm).
  Eigen::Vector3d PointInTarget(int row, int col) const {
    return {col * pitch_mm, row * pitch_mm, 0.0};
  }
  /// All circle centres in the world, row-major, for a target at `world_from_target`.
  std::vector<Eigen::Vector3d> PointsInWorld(const Eigen::Matrix4d& world_from_target) const;
};

/// How circles are found in one image.
struct CircleDetectionOptions {
  enum class Threshold {
    kOtsu,        ///< Otsu's threshold (thesis text, [13])
    kIntermeans,  ///< iterative intermeans (Ridler-Calvard) plus `intermeans_offset` (thesis code)
  };
  Threshold threshold = Threshold::kOtsu;
  /// Grey levels added to the intermeans threshold (the thesis code used +40).
  double intermeans_offset = 40.0;
  /// Circles darker than the plate (true: black circles on a white plate, as in the thesis).
  bool dark_circles = true;
  /// Smallest blob area accepted (px^2).
  double min_area_px = 12.0;
  /// Largest blob area accepted, as a fraction of the image area.
  double max_area_fraction = 0.05;
  /// Circularity check of the thesis (3.2.4): standard deviation / mean of the border-to-centroid
  /// distance. 0 for a circle; about 0.08 for an ellipse of axis ratio 0.8 (a tilted view).
  double max_radial_deviation = 0.15;
  /// Blob area / convex hull area; rejects crescents and notched reflections.
  double min_convexity = 0.9;
  /// Grey-level weighted centroid (area-coverage weights, unbiased under symmetric blur)
  /// instead of the binary centroid of the thesis.
  bool subpixel_centres = true;

  std::string Check() const;
};

/// One circular blob found in an image.
struct CircleBlob {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  double area_px = 0.0;           ///< area of the thresholded blob (px^2)
  double radial_deviation = 0.0;  ///< the circularity measure (see max_radial_deviation)
};

/// Threshold, border following (cv::findContours), circularity check, sub-pixel centres.
/// `image` may be grey or BGR, 8-bit. Returns the blobs in no particular order.
std::vector<CircleBlob> DetectCircleBlobs(const cv::Mat& image,
                                          const CircleDetectionOptions& options = {});

/// The threshold (grey level) the detector uses for `grey` (8-bit, one channel).
double ComputeThreshold(const cv::Mat& grey, const CircleDetectionOptions& options);

/// How the rows x cols grid is found among the blobs.
struct CircleGridOptions {
  /// At most this many blobs (the most circular) are considered; limits the C(n, 4) search.
  int max_candidates = 40;
  /// A grid position predicted by the corner homography must have a blob within this fraction of
  /// the local grid spacing.
  double max_prediction_error = 0.25;
  /// Largest ratio of blob areas within one grid (perspective changes sizes only a little).
  double max_area_ratio = 4.0;

  std::string Check() const;
};

/// The grid found in one image.
struct CircleGridDetection {
  bool found = false;
  std::string message;            ///< why not, when not found
  std::vector<CircleBlob> blobs;  ///< all circular blobs of the image
  /// Canonical labeling: blob index per grid point (row-major). See FindCircleGrid.
  std::vector<int> grid_blob_index;
  /// Circle centres in the canonical labeling (row-major), px.
  std::vector<Eigen::Vector2d> centres_px;
  /// RMS distance of the centres to the best-fitting projective grid, as a fraction of the mean
  /// grid spacing in the image.
  double grid_fit_residual = 0.0;
};

/// Finds the rows x cols subset of `blobs` that forms a projective grid and labels it.
/// Search: every convex quadruple of blobs is hypothesised as the grid's four corners; the
/// homography grid -> image they define predicts the other circles; a hypothesis is complete when
/// every prediction has a distinct blob within max_prediction_error of the local spacing; among
/// complete hypotheses the one with the smallest least-squares homography residual wins. Blobs
/// that fit no complete grid (reflections, other marks) are ignored.
/// Labeling (canonical), documented in docs/calibration.md:
///  1. handedness: the target's +z faces the camera, so in pixel coordinates (v down)
///     cross(d_col, d_row) < 0, where d_col, d_row are the image directions of +col and +row;
///  2. rotation: of the rotations of the grid onto itself (4 for a square grid, 2 otherwise), the
///     one whose +col direction is closest to the image's +u (rightward) direction.
/// The calibration then re-chooses the rotation per height with the world poses (see
/// circle_calibration.h), so rule 2 only decides when the poses cannot.
CircleGridDetection FindCircleGrid(const std::vector<CircleBlob>& blobs,
                                   const CircleGridGeometry& grid,
                                   const CircleGridOptions& options = {});

/// DetectCircleBlobs then FindCircleGrid.
CircleGridDetection DetectCircleGrid(const cv::Mat& image, const CircleGridGeometry& grid,
                                     const CircleDetectionOptions& detection_options = {},
                                     const CircleGridOptions& grid_options = {});

/// The handedness-preserving symmetries of the grid as index maps: labeling L relabelled by
/// symmetry s is L'[i] = L[s[i]]. s[0] is the identity; 4 entries for a square grid (rotations by
/// 0, 90, 180, 270 degrees), 2 otherwise (0, 180).
std::vector<std::vector<int>> GridRotations(int rows, int cols);

/// world_from_target for a target lying flat (its +z = world +z) with circle (0, 0) at
/// `origin_mm` and its +x axis turned by `yaw_deg` about world +z (counter-clockwise seen from
/// above). The pose form of target.yml (docs/calibration.md).
Eigen::Matrix4d WorldFromTargetFlat(const Eigen::Vector3d& origin_mm, double yaw_deg);

}  // namespace hnnstereo::calib
