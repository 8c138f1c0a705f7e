#pragma once
// A built Hopfield network: the connection layout, the stored compatibility weights and the
// biases. The layout groups connections by left feature, which makes dense (thesis) and sparse
// networks one structure:
//   neuron a in row i (left feature i) is connected to every neuron b of every left feature j in
//   feature_neighbours(i) (features within the support radius; all features when dense), b != a.
//   Its weights are stored contiguously from weight_offsets[a], in the order (j, then b), with a
//   zero in the slot of a itself. Row and column uniqueness come from sums (never stored).

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"

namespace hnnstereo::hnn {

/// Bytes in a megabyte, the unit of `--memory-budget-mb` (MiB: 2^20).
inline constexpr std::size_t kBytesPerMegabyte = std::size_t{1} << 20;
/// Default memory budget for a network (bytes): 2048 MB, the one default of every command, the
/// facade and Python (MatcherOptions::memory_budget_bytes).
inline constexpr std::size_t kDefaultMemoryBudgetBytes = 2048 * kBytesPerMegabyte;

struct NetworkLayout {
  int n_neurons = 0;
  int n_rows = 0;     ///< left features
  int n_columns = 0;  ///< right features or disparity levels
  bool column_uniqueness = true;
  std::vector<std::int32_t> neuron_row;          ///< left feature of each neuron
  std::vector<std::int32_t> neuron_column;       ///< column of each neuron
  std::vector<std::int32_t> row_offsets;         ///< n_rows + 1: neurons of row i
  std::vector<std::int32_t> column_offsets;      ///< n_columns + 1, into column_neurons
  std::vector<std::int32_t> column_neurons;      ///< neurons grouped by column
  std::vector<std::int32_t> feature_neighbour_offsets;  ///< n_rows + 1
  std::vector<std::int32_t> feature_neighbours;         ///< left features within the radius
  std::vector<std::int64_t> weight_offsets;      ///< n_neurons + 1
  std::int64_t n_connections() const { return weight_offsets.empty() ? 0 : weight_offsets.back(); }
};

/// Sizes of a network before anything large is allocated.
struct NetworkSize {
  std::int64_t n_neurons = 0;
  std::int64_t n_connections = 0;     ///< stored compatibility weights
  std::size_t weight_bytes = 0;       ///< float weights
  std::size_t total_bytes = 0;        ///< weights, layout and state
  std::size_t dense_matrix_bytes = 0; ///< a full N x N float matrix (thesis engine)
};

/// Builds the layout (cheap, O(neurons + feature pairs)). Throws std::invalid_argument when the
/// problem is inconsistent, and std::runtime_error when the network would exceed
/// `memory_budget_bytes` (naming the sizes and suggesting tighter gating).
NetworkLayout BuildLayout(const MatchingProblem& problem, const EnergyOptions& options,
                          std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

NetworkSize EstimateSize(const NetworkLayout& layout);

/// What a network over the memory budget throws: the one-line reason, and the bytes it needs
/// against the budget (a matcher may then choose fewer features, vision::MatchStereo).
class MemoryBudgetExceeded : public std::runtime_error {
 public:
  MemoryBudgetExceeded(const std::string& reason, std::size_t needed, std::size_t budget)
      : std::runtime_error(reason), needed_bytes(needed), budget_bytes(budget) {}
  std::size_t needed_bytes, budget_bytes;
};

/// Throws MemoryBudgetExceeded naming the sizes when `bytes` exceeds the budget.
void CheckMemoryBudget(std::size_t bytes, std::size_t memory_budget_bytes, const std::string& what,
                       const NetworkLayout& layout);

/// CPU reference of the weight-construction kernel: the stored compatibility weights (eq. 6.11
/// without the uniqueness terms), in layout order, computed in double.
std::vector<double> BuildCompatibilityWeights(const MatchingProblem& problem,
                                              const NetworkLayout& layout,
                                              const EnergyOptions& options);

/// Biases I_a (eq. 6.12).
std::vector<double> BuildBiases(const MatchingProblem& problem, const NetworkLayout& layout,
                                const EnergyOptions& options);

/// Initial activations per the thesis's modes (seeded).
std::vector<double> InitialActivations(const MatchingProblem& problem,
                                       const DynamicsOptions& options);

/// The full dense N x N weight matrix W (eq. 6.11, uniqueness included, zero diagonal), row-major,
/// as the thesis stored it. Checked against the memory budget first.
std::vector<float> BuildDenseWeights(const MatchingProblem& problem, const NetworkLayout& layout,
                                     const std::vector<double>& compatibility_weights,
                                     const EnergyOptions& options,
                                     std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

/// Row sums (per left feature) and column sums of V.
void LineSums(const NetworkLayout& layout, const std::vector<double>& V,
              std::vector<double>* row_sums, std::vector<double>* column_sums);

/// The synaptic input sum_b W_ab V_b of every neuron, from stored weights plus line sums.
std::vector<double> SynapticInput(const NetworkLayout& layout, const std::vector<double>& weights,
                                  const std::vector<double>& V, const EnergyOptions& options);

/// E = -1/2 sum W V V - sum I V (eq. 6.10), in double.
double Energy(const NetworkLayout& layout, const std::vector<double>& weights,
              const std::vector<double>& biases, const std::vector<double>& V,
              const EnergyOptions& options);

}  // namespace hnnstereo::hnn
