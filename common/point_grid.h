#pragma once
// A uniform grid over 2D points for neighbourhood searches: the left features within the support
// radius (host/hopfield_network.cc) and the right features along an epipolar band
// (vision/candidates.cc). Hand-written: a counting sort over a flat cell array is all it needs.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace hnnstereo::hnn {

struct PointGrid {
  /// Cells of side >= `min_cell` (px) over the points' bounding box, coarsened when the points
  /// are few over a huge extent (at most about 4 n + 4096 cells); the points bucketed by a
  /// counting sort that keeps index order within a cell.
  PointGrid(const std::vector<Eigen::Vector2f>& points, double min_cell);

  float x0 = 0, y0 = 0;  ///< the bounding box's low corner
  double cell = 1;       ///< cell side (px)
  int nx = 1, ny = 1;    ///< cells across and down (0 x 0 for no points)
  std::vector<std::int32_t> start;  ///< nx * ny + 1: the points of cell c are items[start[c]..start[c+1])
  std::vector<std::int32_t> items;  ///< point indices grouped by cell (cells row by row)

  int CellX(float x) const;  ///< column of x, clamped to [0, nx - 1]
  int CellY(float y) const;  ///< row of y, clamped to [0, ny - 1]
  /// The items of cells x_first..x_last of row y: one contiguous range.
  std::size_t RowBegin(int y, int x_first) const {
    return static_cast<std::size_t>(start[static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) +
                                          static_cast<std::size_t>(x_first)]);
  }
  std::size_t RowEnd(int y, int x_last) const {
    return static_cast<std::size_t>(start[static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) +
                                          static_cast<std::size_t>(x_last) + 1]);
  }
};

}  // namespace hnnstereo::hnn
