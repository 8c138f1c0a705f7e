#include "host/hopfield_network.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <thread>

#include "host/hopfield_energy.h"
#include "common/point_grid.h"

namespace hnnstereo::hnn {
namespace {

std::string FormatBytes(double bytes) {
  char text[64];
  if (bytes >= 1e9) {
    std::snprintf(text, sizeof(text), "%.2f GB", bytes / 1e9);
  } else {
    std::snprintf(text, sizeof(text), "%.1f MB", bytes / 1e6);
  }
  return text;
}

MatchGeometry GeometryOf(const MatchingProblem& problem, int neuron) {
  const Candidate& c = problem.candidates[static_cast<std::size_t>(neuron)];
  return {problem.left_points[static_cast<std::size_t>(c.left)].cast<double>(),
          c.right_point.cast<double>(), static_cast<double>(c.correlation)};
}

// Left features within `radius` of each left feature (itself included), by grid hashing.
void FindFeatureNeighbours(const MatchingProblem& problem, double radius,
                           std::vector<std::int32_t>* offsets,
                           std::vector<std::int32_t>* neighbours) {
  const int n = problem.n_left();
  offsets->assign(static_cast<std::size_t>(n) + 1, 0);
  neighbours->clear();
  if (problem.dense) {
    neighbours->reserve(static_cast<std::size_t>(n) * static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) neighbours->push_back(j);
      (*offsets)[static_cast<std::size_t>(i) + 1] = static_cast<std::int32_t>(neighbours->size());
    }
    return;
  }
  // A flat uniform grid (cell side >= radius, so a feature's neighbours lie in its 3 x 3 cells),
  // features bucketed by a counting sort that keeps index order. Two passes over the symmetric
  // relation: count each feature's neighbours, then visit features j in increasing order and
  // append j to the list of every feature within the radius: every list comes out sorted by j
  // without a sort (the layout's order; on all of Teddy's 21,664 features this is ~5x faster
  // than hashing the cells and sorting each list).
  if (n == 0) return;
  const PointGrid grid(problem.left_points, radius);
  const double radius2 = radius * radius;
  // Calls visit(i) for every feature i within the radius of feature j (j itself included).
  // About half the features of the 3 x 3 cells are within: the candidates are first compacted
  // without a branch (a data-dependent branch here mispredicts half the time), then visited.
  auto for_each_within = [&](int j, std::vector<std::int32_t>& within, auto&& visit) {
    const auto& p = problem.left_points[static_cast<std::size_t>(j)];
    const int cx = grid.CellX(p.x()), cy = grid.CellY(p.y());
    std::size_t m = 0;
    for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, grid.ny - 1); ++y) {
      const std::size_t first = grid.RowBegin(y, std::max(cx - 1, 0));
      const std::size_t last = grid.RowEnd(y, std::min(cx + 1, grid.nx - 1));
      if (within.size() < m + (last - first)) within.resize(2 * (m + (last - first)));
      for (std::size_t t = first; t < last; ++t) {
        const int i = grid.items[t];
        within[m] = i;
        m += (problem.left_points[static_cast<std::size_t>(i)] - p).cast<double>().squaredNorm() <=
             radius2;
      }
    }
    for (std::size_t k = 0; k < m; ++k) visit(within[k]);
  };
  // The j range in parts, one thread each: part p counts (then writes) the j of its range into
  // the slots of each list after those of parts < p, so the lists stay sorted and no two threads
  // write one slot.
  const int n_parts = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1,
                                 std::max(1, n / 2048));
  auto first_j = [&](int part) { return static_cast<int>(static_cast<std::int64_t>(n) * part / n_parts); };
  std::vector<std::vector<std::int32_t>> part_count(static_cast<std::size_t>(n_parts));
  auto in_parallel = [&](auto&& work) {
    std::vector<std::thread> threads;
    for (int part = 1; part < n_parts; ++part) threads.emplace_back(work, part);
    work(0);
    for (std::thread& thread : threads) thread.join();
  };
  in_parallel([&](int part) {
    std::vector<std::int32_t>& count = part_count[static_cast<std::size_t>(part)];
    count.assign(static_cast<std::size_t>(n), 0);
    std::vector<std::int32_t> within;
    for (int j = first_j(part); j < first_j(part + 1); ++j) {
      for_each_within(j, within, [&](int i) { ++count[static_cast<std::size_t>(i)]; });
    }
  });
  for (int i = 0; i < n; ++i) {
    std::int32_t total = 0;
    for (int part = 0; part < n_parts; ++part) {
      std::int32_t& count = part_count[static_cast<std::size_t>(part)][static_cast<std::size_t>(i)];
      const std::int32_t here = count;
      count = (*offsets)[static_cast<std::size_t>(i)] + total;  // now: the part's first slot
      total += here;
    }
    (*offsets)[static_cast<std::size_t>(i) + 1] = (*offsets)[static_cast<std::size_t>(i)] + total;
  }
  neighbours->resize(static_cast<std::size_t>(offsets->back()));
  in_parallel([&](int part) {
    std::vector<std::int32_t>& fill = part_count[static_cast<std::size_t>(part)];
    std::vector<std::int32_t> within;
    for (int j = first_j(part); j < first_j(part + 1); ++j) {
      for_each_within(j, within, [&](int i) {
        (*neighbours)[static_cast<std::size_t>(fill[static_cast<std::size_t>(i)]++)] = j;
      });
    }
  });
}

}  // namespace

std::string MatchingProblem::Check() const {
  const int n_left_features = n_left();
  for (std::size_t a = 0; a < candidates.size(); ++a) {
    const Candidate& c = candidates[a];
    if (c.left < 0 || c.left >= n_left_features) {
      return "candidate " + std::to_string(a) + " has left index " + std::to_string(c.left) +
             " outside [0, " + std::to_string(n_left_features) + ")";
    }
    if (c.column < 0 || c.column >= n_columns) {
      return "candidate " + std::to_string(a) + " has column " + std::to_string(c.column) +
             " outside [0, " + std::to_string(n_columns) + ")";
    }
    if (!std::isfinite(c.epipolar_distance_px) || !std::isfinite(c.correlation) ||
        !c.right_point.allFinite()) {
      return "candidate " + std::to_string(a) + " has a non-finite value";
    }
    if (a > 0) {
      const Candidate& p = candidates[a - 1];
      if (p.left > c.left || (p.left == c.left && p.column >= c.column)) {
        return "candidates must be sorted by (left, column) without duplicates (at " +
               std::to_string(a) + ")";
      }
    }
  }
  for (const auto& p : left_points) {
    if (!p.allFinite()) return "a left feature has a non-finite coordinate";
  }
  return {};
}

void CheckMemoryBudget(std::size_t bytes, std::size_t memory_budget_bytes, const std::string& what,
                       const NetworkLayout& layout) {
  if (bytes <= memory_budget_bytes) return;
  throw MemoryBudgetExceeded(
      what + " needs " + FormatBytes(static_cast<double>(bytes)) + " (" +
      std::to_string(layout.n_neurons) + " neurons from " + std::to_string(layout.n_rows) +
      " left features x " + std::to_string(layout.n_columns) + " columns, " +
      std::to_string(layout.n_connections()) + " connections), over the memory budget of " +
      FormatBytes(static_cast<double>(memory_budget_bytes)) +
      "; tighten the gating (--max-disparity, --top-k, --max-features, --support-radius, no "
      "--dense) or raise --memory-budget-mb",
      bytes, memory_budget_bytes);
}

NetworkLayout BuildLayout(const MatchingProblem& problem, const EnergyOptions& options,
                          std::size_t memory_budget_bytes) {
  if (const std::string problem_error = problem.Check(); !problem_error.empty()) {
    throw std::invalid_argument("inconsistent matching problem: " + problem_error);
  }
  if (const std::string option_error = options.Check(); !option_error.empty()) {
    throw std::invalid_argument(option_error);
  }
  NetworkLayout layout;
  layout.n_neurons = problem.n_neurons();
  layout.n_rows = problem.n_left();
  layout.n_columns = problem.n_columns;
  layout.column_uniqueness = problem.kind == NetworkKind::kFeatureVsFeature;
  const auto n = static_cast<std::size_t>(layout.n_neurons);

  // Before building anything proportional to connections, estimate them from row sizes.
  layout.row_offsets.assign(static_cast<std::size_t>(layout.n_rows) + 1, 0);
  layout.neuron_row.resize(n);
  layout.neuron_column.resize(n);
  for (std::size_t a = 0; a < n; ++a) {
    layout.neuron_row[a] = problem.candidates[a].left;
    layout.neuron_column[a] = problem.candidates[a].column;
    ++layout.row_offsets[static_cast<std::size_t>(problem.candidates[a].left) + 1];
  }
  for (int i = 0; i < layout.n_rows; ++i) {
    layout.row_offsets[static_cast<std::size_t>(i) + 1] +=
        layout.row_offsets[static_cast<std::size_t>(i)];
  }
  if (problem.dense) {
    const std::size_t dense_bytes = n * n * (sizeof(float) + sizeof(double));
    layout.weight_offsets.assign(2, 0);
    layout.weight_offsets[1] = static_cast<std::int64_t>(n * n);
    CheckMemoryBudget(dense_bytes, memory_budget_bytes, "the dense (all-pairs) network", layout);
  }

  layout.column_offsets.assign(static_cast<std::size_t>(layout.n_columns) + 1, 0);
  for (std::size_t a = 0; a < n; ++a) {
    ++layout.column_offsets[static_cast<std::size_t>(layout.neuron_column[a]) + 1];
  }
  for (int k = 0; k < layout.n_columns; ++k) {
    layout.column_offsets[static_cast<std::size_t>(k) + 1] +=
        layout.column_offsets[static_cast<std::size_t>(k)];
  }
  layout.column_neurons.resize(n);
  std::vector<std::int32_t> fill(layout.column_offsets.begin(), layout.column_offsets.end() - 1);
  for (std::size_t a = 0; a < n; ++a) {
    layout.column_neurons[static_cast<std::size_t>(fill[static_cast<std::size_t>(
        layout.neuron_column[a])]++)] = static_cast<std::int32_t>(a);
  }

  FindFeatureNeighbours(problem, options.support_radius_px, &layout.feature_neighbour_offsets,
                        &layout.feature_neighbours);
  // Connections per row, then per neuron.
  std::vector<std::int64_t> row_connections(static_cast<std::size_t>(layout.n_rows), 0);
  for (int i = 0; i < layout.n_rows; ++i) {
    std::int64_t count = 0;
    for (int t = layout.feature_neighbour_offsets[static_cast<std::size_t>(i)];
         t < layout.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]; ++t) {
      const int j = layout.feature_neighbours[static_cast<std::size_t>(t)];
      count += layout.row_offsets[static_cast<std::size_t>(j) + 1] -
               layout.row_offsets[static_cast<std::size_t>(j)];
    }
    row_connections[static_cast<std::size_t>(i)] = count;
  }
  layout.weight_offsets.assign(n + 1, 0);
  for (std::size_t a = 0; a < n; ++a) {
    layout.weight_offsets[a + 1] =
        layout.weight_offsets[a] +
        row_connections[static_cast<std::size_t>(layout.neuron_row[a])];
  }
  CheckMemoryBudget(EstimateSize(layout).total_bytes, memory_budget_bytes, "the network", layout);
  return layout;
}

NetworkSize EstimateSize(const NetworkLayout& layout) {
  NetworkSize size;
  size.n_neurons = layout.n_neurons;
  size.n_connections = layout.n_connections();
  size.weight_bytes = static_cast<std::size_t>(size.n_connections) * sizeof(float);
  // Host double reference copy + device float copy + per-neuron state and layout.
  size.total_bytes = static_cast<std::size_t>(size.n_connections) * (sizeof(float) + sizeof(double)) +
                     static_cast<std::size_t>(layout.n_neurons) * 64 +
                     layout.feature_neighbours.size() * sizeof(std::int32_t);
  size.dense_matrix_bytes = static_cast<std::size_t>(layout.n_neurons) *
                            static_cast<std::size_t>(layout.n_neurons) * sizeof(float);
  return size;
}

std::vector<double> BuildCompatibilityWeights(const MatchingProblem& problem,
                                              const NetworkLayout& layout,
                                              const EnergyOptions& options) {
  std::vector<double> weights(static_cast<std::size_t>(layout.n_connections()), 0.0);
  std::vector<MatchGeometry> geometry(static_cast<std::size_t>(layout.n_neurons));
  for (int a = 0; a < layout.n_neurons; ++a) geometry[static_cast<std::size_t>(a)] = GeometryOf(problem, a);
  for (int a = 0; a < layout.n_neurons; ++a) {
    const int i = layout.neuron_row[static_cast<std::size_t>(a)];
    std::int64_t position = layout.weight_offsets[static_cast<std::size_t>(a)];
    const MatchGeometry& ga = geometry[static_cast<std::size_t>(a)];
    for (int t = layout.feature_neighbour_offsets[static_cast<std::size_t>(i)];
         t < layout.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]; ++t) {
      const int j = layout.feature_neighbours[static_cast<std::size_t>(t)];
      const double left_distance = (problem.left_points[static_cast<std::size_t>(i)] -
                                    problem.left_points[static_cast<std::size_t>(j)])
                                       .cast<double>()
                                       .norm();
      for (int b = layout.row_offsets[static_cast<std::size_t>(j)];
           b < layout.row_offsets[static_cast<std::size_t>(j) + 1]; ++b, ++position) {
        if (b == a) continue;  // no self-connection (eq. 6.11)
        weights[static_cast<std::size_t>(position)] =
            CompatibilityWeight(ga, geometry[static_cast<std::size_t>(b)], left_distance, options);
      }
    }
  }
  return weights;
}

std::vector<double> BuildBiases(const MatchingProblem& problem, const NetworkLayout& layout,
                                const EnergyOptions& options) {
  std::vector<double> biases(static_cast<std::size_t>(layout.n_neurons));
  for (std::size_t a = 0; a < biases.size(); ++a) {
    biases[a] = Bias(problem.candidates[a].epipolar_distance_px, layout.column_uniqueness, options);
  }
  return biases;
}

std::vector<double> InitialActivations(const MatchingProblem& problem,
                                       const DynamicsOptions& options) {
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> gaussian(0.0, options.initial_noise);
  std::vector<double> V(static_cast<std::size_t>(problem.n_neurons()));
  for (std::size_t a = 0; a < V.size(); ++a) {
    switch (options.initial_state) {
      case InitialState::kAllOff: V[a] = 0.0; break;
      case InitialState::kAllOn: V[a] = 1.0; break;
      case InitialState::kRandomBinary: V[a] = uniform(rng) < 0.5 ? 0.0 : 1.0; break;
      case InitialState::kRandomContinuous: V[a] = uniform(rng); break;
      case InitialState::kConstant: V[a] = options.initial_value; break;
      case InitialState::kConstantNoise:
        V[a] = std::clamp(options.initial_value + gaussian(rng), 0.0, 1.0);
        break;
      case InitialState::kCorrelation:
        V[a] = 0.5 * (static_cast<double>(problem.candidates[a].correlation) + 1.0);
        break;
    }
  }
  return V;
}

std::vector<float> BuildDenseWeights(const MatchingProblem& problem, const NetworkLayout& layout,
                                     const std::vector<double>& compatibility_weights,
                                     const EnergyOptions& options,
                                     std::size_t memory_budget_bytes) {
  (void)problem;
  const auto n = static_cast<std::size_t>(layout.n_neurons);
  CheckMemoryBudget(n * n * sizeof(float) + compatibility_weights.size() * sizeof(double),
                    memory_budget_bytes, "the thesis engine's dense weight matrix", layout);
  std::vector<float> W(n * n, 0.0f);
  for (std::size_t a = 0; a < n; ++a) {
    const int i = layout.neuron_row[a];
    std::int64_t position = layout.weight_offsets[a];
    for (int t = layout.feature_neighbour_offsets[static_cast<std::size_t>(i)];
         t < layout.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]; ++t) {
      const int j = layout.feature_neighbours[static_cast<std::size_t>(t)];
      for (int b = layout.row_offsets[static_cast<std::size_t>(j)];
           b < layout.row_offsets[static_cast<std::size_t>(j) + 1]; ++b, ++position) {
        W[a * n + static_cast<std::size_t>(b)] =
            static_cast<float>(compatibility_weights[static_cast<std::size_t>(position)]);
      }
    }
    // Uniqueness terms of eq. 6.11: -2B within the row, -2C within the column.
    for (int b = layout.row_offsets[static_cast<std::size_t>(i)];
         b < layout.row_offsets[static_cast<std::size_t>(i) + 1]; ++b) {
      W[a * n + static_cast<std::size_t>(b)] -= static_cast<float>(2.0 * options.B);
    }
    if (layout.column_uniqueness) {
      const int k = layout.neuron_column[a];
      for (int t = layout.column_offsets[static_cast<std::size_t>(k)];
           t < layout.column_offsets[static_cast<std::size_t>(k) + 1]; ++t) {
        W[a * n + static_cast<std::size_t>(layout.column_neurons[static_cast<std::size_t>(t)])] -=
            static_cast<float>(2.0 * options.C);
      }
    }
    W[a * n + a] = 0.0f;
  }
  return W;
}

void LineSums(const NetworkLayout& layout, const std::vector<double>& V,
              std::vector<double>* row_sums, std::vector<double>* column_sums) {
  row_sums->assign(static_cast<std::size_t>(layout.n_rows), 0.0);
  column_sums->assign(static_cast<std::size_t>(layout.n_columns), 0.0);
  for (int i = 0; i < layout.n_rows; ++i) {
    double sum = 0.0;
    for (int a = layout.row_offsets[static_cast<std::size_t>(i)];
         a < layout.row_offsets[static_cast<std::size_t>(i) + 1]; ++a) {
      sum += V[static_cast<std::size_t>(a)];
    }
    (*row_sums)[static_cast<std::size_t>(i)] = sum;
  }
  for (int k = 0; k < layout.n_columns; ++k) {
    double sum = 0.0;
    for (int t = layout.column_offsets[static_cast<std::size_t>(k)];
         t < layout.column_offsets[static_cast<std::size_t>(k) + 1]; ++t) {
      sum += V[static_cast<std::size_t>(layout.column_neurons[static_cast<std::size_t>(t)])];
    }
    (*column_sums)[static_cast<std::size_t>(k)] = sum;
  }
}

std::vector<double> SynapticInput(const NetworkLayout& layout, const std::vector<double>& weights,
                                  const std::vector<double>& V, const EnergyOptions& options) {
  std::vector<double> row_sums, column_sums;
  LineSums(layout, V, &row_sums, &column_sums);
  const double column_weight = layout.column_uniqueness ? 2.0 * options.C : 0.0;
  std::vector<double> input(static_cast<std::size_t>(layout.n_neurons));
  for (int a = 0; a < layout.n_neurons; ++a) {
    const auto ua = static_cast<std::size_t>(a);
    const int i = layout.neuron_row[ua];
    std::int64_t position = layout.weight_offsets[ua];
    double sum = 0.0;
    for (int t = layout.feature_neighbour_offsets[static_cast<std::size_t>(i)];
         t < layout.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]; ++t) {
      const int j = layout.feature_neighbours[static_cast<std::size_t>(t)];
      for (int b = layout.row_offsets[static_cast<std::size_t>(j)];
           b < layout.row_offsets[static_cast<std::size_t>(j) + 1]; ++b, ++position) {
        sum += weights[static_cast<std::size_t>(position)] * V[static_cast<std::size_t>(b)];
      }
    }
    sum -= 2.0 * options.B * (row_sums[static_cast<std::size_t>(i)] - V[ua]);
    sum -= column_weight *
           (column_sums[static_cast<std::size_t>(layout.neuron_column[ua])] - V[ua]);
    input[ua] = sum;
  }
  return input;
}

double Energy(const NetworkLayout& layout, const std::vector<double>& weights,
              const std::vector<double>& biases, const std::vector<double>& V,
              const EnergyOptions& options) {
  const std::vector<double> input = SynapticInput(layout, weights, V, options);
  double energy = 0.0;
  for (std::size_t a = 0; a < V.size(); ++a) energy -= V[a] * (0.5 * input[a] + biases[a]);
  return energy;
}

}  // namespace hnnstereo::hnn
