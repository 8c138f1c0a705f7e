#include "vision/sensing/clustering.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "common/timing.h"

namespace hnnstereo::vision {
namespace {

using common::MillisecondsSince;

// Relabels so that cluster indices are dense and `clusters` lists each one's points.
void FinishClusters(std::vector<int>* labels, int min_points, ClusteringReport* report) {
  int max_label = -1;
  for (int label : *labels) max_label = std::max(max_label, label);
  std::vector<int> counts(static_cast<std::size_t>(max_label + 1), 0);
  for (int label : *labels) {
    if (label >= 0) ++counts[static_cast<std::size_t>(label)];
  }
  std::vector<int> dense(counts.size(), -1);
  for (std::size_t c = 0; c < counts.size(); ++c) {
    if (counts[c] >= min_points) {
      dense[c] = static_cast<int>(report->clusters.size());
      report->clusters.emplace_back();
    } else {
      report->n_in_small_clusters += counts[c];
    }
  }
  for (std::size_t i = 0; i < labels->size(); ++i) {
    int& label = (*labels)[i];
    if (label < 0) continue;
    label = dense[static_cast<std::size_t>(label)];
    if (label >= 0) report->clusters[static_cast<std::size_t>(label)].push_back(static_cast<int>(i));
  }
  report->labels = *labels;
}

}  // namespace

std::string_view ClusteringMethodName(ClusteringMethod method) {
  return method == ClusteringMethod::kGrid ? "grid" : "thesis";
}

std::optional<ClusteringMethod> ParseClusteringMethod(std::string_view name) {
  if (name == "grid") return ClusteringMethod::kGrid;
  if (name == "thesis") return ClusteringMethod::kThesisLeader;
  return std::nullopt;
}

std::string LeaderClusteringOptions::Check() const {
  std::ostringstream out;
  if (!(min_height_mm < max_height_mm)) {
    out << "LeaderClusteringOptions: min_height_mm (" << min_height_mm
        << ") must be below max_height_mm (" << max_height_mm << ")";
  } else if (!(threshold_mm > 0.0)) {
    out << "LeaderClusteringOptions.threshold_mm must be positive (is " << threshold_mm << ")";
  } else if (min_points < 1) {
    out << "LeaderClusteringOptions.min_points must be >= 1 (is " << min_points << ")";
  }
  return out.str();
}

std::string GridClusteringOptions::Check() const {
  std::ostringstream out;
  if (!(min_height_mm < max_height_mm)) {
    out << "GridClusteringOptions: min_height_mm (" << min_height_mm
        << ") must be below max_height_mm (" << max_height_mm << ")";
  } else if (!(cell_mm > 0.0)) {
    out << "GridClusteringOptions.cell_mm must be positive (is " << cell_mm << ")";
  } else if (!(height_cell_mm > 0.0)) {
    out << "GridClusteringOptions.height_cell_mm must be positive (is " << height_cell_mm << ")";
  } else if (reach_cells < 1 || reach_cells > 5) {
    out << "GridClusteringOptions.reach_cells must be in [1, 5] (is " << reach_cells << ")";
  } else if (min_points_per_cell < 1 || min_points < 1) {
    out << "GridClusteringOptions: min_points_per_cell and min_points must be >= 1 (are "
        << min_points_per_cell << ", " << min_points << ")";
  }
  return out.str();
}

ClusteringReport ClusterByHeightLeader(const std::vector<Eigen::Vector3d>& points_in_world,
                                       const LeaderClusteringOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  const auto start = std::chrono::steady_clock::now();
  ClusteringReport report;
  report.method = "thesis";
  std::vector<int> labels(points_in_world.size(), -1);
  std::vector<double> sums;
  std::vector<int> counts;
  // Single pass: the first cluster whose mean Z is within the threshold takes the point.
  for (std::size_t i = 0; i < points_in_world.size(); ++i) {
    const double z = points_in_world[i].z();
    if (!(z > options.min_height_mm && z < options.max_height_mm)) {
      ++report.n_outside_height_window;
      continue;
    }
    int chosen = -1;
    for (std::size_t c = 0; c < sums.size() && chosen < 0; ++c) {
      if (std::abs(sums[c] / counts[c] - z) < options.threshold_mm) chosen = static_cast<int>(c);
    }
    if (chosen < 0) {
      chosen = static_cast<int>(sums.size());
      sums.push_back(0.0);
      counts.push_back(0);
    }
    sums[static_cast<std::size_t>(chosen)] += z;
    ++counts[static_cast<std::size_t>(chosen)];
    labels[i] = chosen;
  }
  // Merge clusters whose means are within the threshold, until none are.
  std::vector<int> merged_into(sums.size());
  for (std::size_t c = 0; c < merged_into.size(); ++c) merged_into[c] = static_cast<int>(c);
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t a = 0; a < sums.size() && !changed; ++a) {
      if (counts[a] == 0) continue;
      for (std::size_t b = a + 1; b < sums.size() && !changed; ++b) {
        if (counts[b] == 0) continue;
        if (std::abs(sums[a] / counts[a] - sums[b] / counts[b]) < options.threshold_mm) {
          sums[a] += sums[b];
          counts[a] += counts[b];
          sums[b] = 0.0;
          counts[b] = 0;
          for (int& target : merged_into) {
            if (target == static_cast<int>(b)) target = static_cast<int>(a);
          }
          ++report.n_merges;
          changed = true;
        }
      }
    }
  }
  for (int& label : labels) {
    if (label >= 0) label = merged_into[static_cast<std::size_t>(label)];
  }
  FinishClusters(&labels, options.min_points, &report);
  report.time_ms = MillisecondsSince(start);
  return report;
}

ClusteringReport ClusterOnGrid(const std::vector<Eigen::Vector3d>& points_in_world,
                               const GridClusteringOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  const auto start = std::chrono::steady_clock::now();
  ClusteringReport report;
  report.method = "grid";
  // Cell key: 21 bits per axis (cells of a few mm: +-1e6 cells is far beyond any cell).
  auto key_of = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    constexpr std::int64_t kOffset = 1 << 20;
    return static_cast<std::uint64_t>(((x + kOffset) << 42) | ((y + kOffset) << 21) | (z + kOffset));
  };
  struct Cell {
    std::int64_t x, y, z;
    std::vector<int> points;
    int component = -1;
  };
  std::unordered_map<std::uint64_t, std::size_t> cell_index;
  std::vector<Cell> cells;
  for (std::size_t i = 0; i < points_in_world.size(); ++i) {
    const Eigen::Vector3d& p = points_in_world[i];
    if (!(p.z() > options.min_height_mm && p.z() < options.max_height_mm) || !p.allFinite()) {
      ++report.n_outside_height_window;
      continue;
    }
    const auto cx = static_cast<std::int64_t>(std::floor(p.x() / options.cell_mm));
    const auto cy = static_cast<std::int64_t>(std::floor(p.y() / options.cell_mm));
    const auto cz = static_cast<std::int64_t>(std::floor(p.z() / options.height_cell_mm));
    const auto [it, inserted] = cell_index.try_emplace(key_of(cx, cy, cz), cells.size());
    if (inserted) cells.push_back({cx, cy, cz, {}, -1});
    cells[it->second].points.push_back(static_cast<int>(i));
  }
  // Connected components of the dense cells (within reach_cells in x, y; one cell in z).
  int num_components = 0;
  std::vector<std::size_t> stack;
  for (std::size_t seed = 0; seed < cells.size(); ++seed) {
    if (cells[seed].component >= 0 ||
        static_cast<int>(cells[seed].points.size()) < options.min_points_per_cell) {
      continue;
    }
    cells[seed].component = num_components;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const Cell& cell = cells[stack.back()];
      stack.pop_back();
      const std::int64_t reach = options.reach_cells;
      for (std::int64_t dx = -reach; dx <= reach; ++dx) {
        for (std::int64_t dy = -reach; dy <= reach; ++dy) {
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            const auto found = cell_index.find(key_of(cell.x + dx, cell.y + dy, cell.z + dz));
            if (found == cell_index.end()) continue;
            Cell& neighbour = cells[found->second];
            if (neighbour.component >= 0 ||
                static_cast<int>(neighbour.points.size()) < options.min_points_per_cell) {
              continue;
            }
            neighbour.component = num_components;
            stack.push_back(found->second);
          }
        }
      }
    }
    ++num_components;
  }
  std::vector<int> labels(points_in_world.size(), -1);
  for (const Cell& cell : cells) {
    if (cell.component < 0) {
      report.n_in_small_clusters += static_cast<int>(cell.points.size());
      continue;
    }
    for (int i : cell.points) labels[static_cast<std::size_t>(i)] = cell.component;
  }
  FinishClusters(&labels, options.min_points, &report);
  report.time_ms = MillisecondsSince(start);
  return report;
}

}  // namespace hnnstereo::vision
