#pragma once
// Grouping triangulated points into parts (THESIS.md section 4, thesis 6.2.10).
//
// Two methods over the same input (world points, table z = 0, mm):
//  - thesis: single-pass leader clustering on height (the text calls it k-means). A point with a
//    plausible height joins the first cluster whose mean Z is within a threshold, else opens a
//    new one; clusters whose means are within the threshold merge; small clusters are dropped.
//    Known failure (reported by the thesis): parts of similar height that stand apart become one
//    cluster, and many parts exhaust the hand-tuned threshold.
//  - grid (default): density clustering in 3D on a voxel grid. Points above the table go into
//    cells (taller than wide: height is the noisy axis); occupied cells within reach of each
//    other form one part. Parts of the same
//    height that stand apart stay apart; any shape is fine.
// Pure functions: no I/O.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hnnstereo::vision {

enum class ClusteringMethod { kGrid, kThesisLeader };

/// "grid" or "thesis".
std::string_view ClusteringMethodName(ClusteringMethod method);
std::optional<ClusteringMethod> ParseClusteringMethod(std::string_view name);

/// The thesis's leader clustering on height. Defaults from the thesis code.
struct LeaderClusteringOptions {
  double min_height_mm = 10.0;   ///< thesis code: 1 cm < Z (zero-height rejection), mm
  double max_height_mm = 150.0;  ///< thesis code: Z < 15 cm (text: below 20 cm), mm
  /// Join and merge distance between a point's Z and a cluster's mean Z (mm). The thesis tuned
  /// it by hand per scene; 5 mm is about twice the depth error of one pixel of disparity in the
  /// default cell.
  double threshold_mm = 5.0;
  int min_points = 10;           ///< clusters with fewer points are dropped
  std::string Check() const;
};

/// Density clustering on a 3D grid (the default).
struct GridClusteringOptions {
  double min_height_mm = 4.0;    ///< points below are the table (zero-height rejection), mm
  double max_height_mm = 250.0;  ///< points above are mismatches, mm
  /// Cell edge in the table plane (mm).
  double cell_mm = 3.0;
  /// Occupied cells within this many cells in x and y (and one cell in z) join. Matched edge
  /// points are sparse (gaps of a few mm along an edge), so 2: points up to 2 cells apart along
  /// an axis link; parts further apart than (reach + 1) * cell_mm * sqrt(2) = 12.7 mm in the
  /// table plane never merge.
  int reach_cells = 2;
  /// Cell edge along z (mm). Height is the noisy axis (one pixel of disparity is about 2.7 mm of
  /// height in the default cell), so taller cells keep a noisy edge chain in one piece.
  double height_cell_mm = 8.0;
  int min_points_per_cell = 1;   ///< sparser cells are ignored (isolated mismatches)
  /// Smaller components are noise (mismatches, occluding contours). Kept low: a top face whose
  /// sides run along the epipolar lines (few, weak matches there) falls apart into its two
  /// strong edges and its marks, 20-40 points each; position sensing joins such
  /// fragments at one height (MergeTopFaceIslands) and only then drops parts under
  /// PositionSensingOptions::min_strong_points. The smallest default part (25 mm, 10 mm tall)
  /// gives well over 100 matched points.
  int min_points = 15;
  std::string Check() const;
};

struct ClusteringReport {
  std::string method;                     ///< "grid" or "thesis"
  std::vector<int> labels;                ///< per input point: cluster index, or -1
  std::vector<std::vector<int>> clusters; ///< input indices per cluster
  int n_outside_height_window = 0;        ///< points rejected by the height window
  int n_in_small_clusters = 0;            ///< points of dropped clusters / components
  int n_merges = 0;                       ///< thesis: cluster merges after the single pass
  double time_ms = 0.0;
};

/// Thesis leader clustering (6.2.10). Throws std::invalid_argument on bad options.
ClusteringReport ClusterByHeightLeader(const std::vector<Eigen::Vector3d>& points_in_world,
                                       const LeaderClusteringOptions& options = {});

/// 3D grid density clustering. Throws std::invalid_argument on bad options.
ClusteringReport ClusterOnGrid(const std::vector<Eigen::Vector3d>& points_in_world,
                               const GridClusteringOptions& options = {});

}  // namespace hnnstereo::vision
