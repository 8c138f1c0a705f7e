#include "common/point_grid.h"

#include <algorithm>
#include <cmath>

namespace hnnstereo::hnn {

PointGrid::PointGrid(const std::vector<Eigen::Vector2f>& points, double min_cell)
    : cell(std::max(min_cell, 1.0)) {
  const std::size_t n = points.size();
  if (n == 0) {
    nx = ny = 0;
    start.assign(1, 0);
    return;
  }
  float x1 = points[0].x(), y1 = points[0].y();
  x0 = x1, y0 = y1;
  for (const auto& p : points) {
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  // Sparse points over a huge extent: coarser cells keep the grid within a few cells a point.
  const double extent_x = static_cast<double>(x1) - x0, extent_y = static_cast<double>(y1) - y0;
  const double max_cells = 4.0 * static_cast<double>(n) + 4096.0;
  if ((extent_x / cell + 1.0) * (extent_y / cell + 1.0) > max_cells) {
    cell = std::max(cell, std::sqrt((extent_x + 1.0) * (extent_y + 1.0) / (max_cells / 4.0)));
  }
  nx = static_cast<int>(extent_x / cell) + 1;
  ny = static_cast<int>(extent_y / cell) + 1;
  const auto n_cells = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  start.assign(n_cells + 1, 0);
  std::vector<std::int32_t> cell_of(n);
  for (std::size_t i = 0; i < n; ++i) {
    cell_of[i] = CellY(points[i].y()) * nx + CellX(points[i].x());
    ++start[static_cast<std::size_t>(cell_of[i]) + 1];
  }
  for (std::size_t c = 0; c < n_cells; ++c) start[c + 1] += start[c];
  items.resize(n);
  std::vector<std::int32_t> fill(start.begin(), start.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    items[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell_of[i])]++)] =
        static_cast<std::int32_t>(i);
  }
}

int PointGrid::CellX(float x) const {
  return std::clamp(static_cast<int>((static_cast<double>(x) - x0) / cell), 0, nx - 1);
}
int PointGrid::CellY(float y) const {
  return std::clamp(static_cast<int>((static_cast<double>(y) - y0) / cell), 0, ny - 1);
}

}  // namespace hnnstereo::hnn
