#pragma once
// The OpenCL engine: weight construction, lockstep neuron updates (explicit Euler steps of the
// Hopfield-Tank equation - the analog chip imitated), row/column sums and energy reductions as
// kernels (kernels/hopfield.cl); many independent networks per launch.

#include <cstddef>
#include <optional>
#include <string_view>
#include <vector>

#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"
#include "host/opencl_runtime.h"
#include "host/solve_report.h"

namespace hnnstereo::hnn {

/// Work-items per row of the GPU's blocked step (OpenClEngineOptions::BlockStep): one warp.
inline constexpr int kStepGroup = 32;
/// SolveLoop::kAuto runs the loop with one work-group (one core) on a 2-core CPU device for steps
/// that read at most this many bytes (the step-bytes model of SolveReport::step_bytes): the
/// crossover with the host loop measured there lies between 1.5 and 2.4 MB (docs/engine.md).
/// With a group per core the device loop takes every size.
inline constexpr double kResidentMaxStepBytes = 2.0e6;

/// SolveLoop::kDevice with automatic groups gives each work-group at least this many rows.
inline constexpr int kResidentRowsPerGroup = 128;
/// The device loop cuts the rows into this many ranges per work-group (the groups take them
/// step by step; solve_blocked_resident in kernels/hopfield.cl).
inline constexpr int kResidentRangesPerGroup = 8;

/// How the OpenCL engine holds the compatibility weights (docs/engine.md, "Weight storage").
enum class WeightStorage {
  kAuto,          ///< row blocks (half) when padding wastes < 2x (on a GPU: and rows of <= 8
                  ///< slots), else CSR
  kCsr,           ///< per-neuron contiguous weights, one work-item per neuron, 3 launches a step
  kBlockedFloat,  ///< ROW_PAD x ROW_PAD float blocks per row pair, one fused launch a step
  kBlockedHalf,   ///< the same blocks in half precision (vload_half), float accumulation
  kOnTheFly,      ///< no stored weights: recomputed every step from per-neuron data
};
std::string_view WeightStorageName(WeightStorage storage);
std::optional<WeightStorage> ParseWeightStorage(std::string_view name);
/// Every storage's name, comma-separated ("auto, csr, ..."), for help texts and errors.
std::string WeightStorageNames();

struct OpenClEngineOptions {
  WeightStorage storage = WeightStorage::kAuto;
  /// Row-blocked kernels: rows per work-item (0 = automatic: 1 on a GPU, about n_rows / 256 on
  /// a CPU device, where PoCL runs one work-item per work-group with explicit vector loads).
  int rows_per_item = 0;
  /// Row blocks: how the weight blocks are built. kAuto: a work-item per row for the default
  /// objective on a CPU device (build_weight_blocks_vec4), else a work-item per weight
  /// (build_weight_blocks_flat); kPerWeight forces the latter anywhere (a CPU test covers it).
  enum class BlockBuild { kAuto, kPerRow, kPerWeight };
  BlockBuild block_build = BlockBuild::kAuto;
  /// Row blocks: how the fused step is spread. kAuto: one work-group of kStepGroup work-items
  /// per row on a GPU (neuron_step_blocked_group: neighbouring lanes read neighbouring blocks),
  /// runs of whole rows per work-item on a CPU device (neuron_step_blocked); kRowPerGroup
  /// forces the GPU's kernel anywhere (so a CPU test covers it).
  enum class BlockStep { kAuto, kRowPerItem, kRowPerGroup };
  BlockStep block_step = BlockStep::kAuto;
  /// Row blocks: where the solve loop runs. kHost: a launch per step and a host round trip per
  /// convergence check (SolveBlocked). kDevice: the whole loop in one launch of resident_groups
  /// work-groups (kernel solve_blocked_resident, column sums included; one network, else
  /// kHost). kAuto: kDevice on a CPU device for a single network when it gets two groups or
  /// more (the steps spread over the cores as the host loop's
  /// launches do, without their launches and round trips: docs/engine.md); with one group only
  /// for stored blocks whose step reads at most ResidentMaxStepBytes(its compute units); else
  /// kHost. Never on a GPU by default: a work-item a core would leave the card idle.
  enum class SolveLoop { kAuto, kHost, kDevice };
  SolveLoop solve_loop = SolveLoop::kAuto;
  /// The device loop's work-groups (one work-item each, a thread of its own on a CPU device),
  /// which take the ranges of rows of each step in turn (kernel solve_blocked_resident). 0 =
  /// automatic: one per compute unit on a CPU device, fewer for networks of under
  /// kResidentRowsPerGroup rows a group, one on a GPU. Any count gives the same result, bit
  /// for bit; groups that never run at once (PoCL with one thread) are harmless.
  int resident_groups = 0;
  /// Time every kernel and convergence-check read on the device (a queue with
  /// CL_QUEUE_PROFILING_ENABLE, one event per command): SolveReport::kernel_times, `bench
  /// --profile`. Off by default: events cost host time on every launch.
  bool profile = false;
};

class OpenClEngine {
 public:
  /// The runtime must outlive the engine.
  explicit OpenClEngine(ocl::Runtime& runtime, OpenClEngineOptions options = {})
      : runtime_(runtime), options_(options) {}

  SolveReport Solve(const MatchingProblem& problem, const EnergyOptions& energy,
                    const DynamicsOptions& dynamics,
                    std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

  /// Solves independent networks together (block diagonal, one launch per kernel per step);
  /// each network stops (is frozen) when its own convergence test passes. The memory budget
  /// applies to the whole batch.
  std::vector<SolveReport> SolveBatch(const ProblemBatch& problems, const EnergyOptions& energy,
                                      const DynamicsOptions& dynamics,
                                      std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

  /// Builds the kernels for these options and runs them once on a tiny network, so that the
  /// first real solve pays no compilation (PoCL compiles each kernel per local size at its
  /// first launch; the program binary comes from the on-disk cache when it is warm). `serve`
  /// and `pick --robot` call it before their first trigger. Returns the milliseconds it took.
  double WarmUp(const EnergyOptions& energy, const DynamicsOptions& dynamics,
                NetworkKind kind = NetworkKind::kFeatureVsDisparity);
  /// Kernel probes, for tests against the CPU reference and for benchmarks of single stages.
  /// The compatibility weights from the build_weights kernel, in layout order.
  std::vector<float> BuildWeights(const MatchingProblem& problem, const EnergyOptions& energy);
  /// One pass of line_sums + neuron_field + segment_sum at state V: the net input
  /// sum_b W_ab V_b + I_a of every neuron, and the energy E(V) (eq. 6.10) in `energy_out`.
  std::vector<float> Field(const MatchingProblem& problem, const EnergyOptions& energy,
                           const std::vector<double>& V, double* energy_out);

 private:
  ocl::Runtime& runtime_;
  OpenClEngineOptions options_;
};

/// "auto", "host", "device" <-> OpenClEngineOptions::SolveLoop (the --solve-loop flags).
std::optional<OpenClEngineOptions::SolveLoop> ParseSolveLoop(std::string_view name);

/// The device loop's ranges of rows: `ranges` + 1 cuts of [0, n_rows) at multiples of four rows
/// (four 4-slot rows finish as one vector) of about equal work, a row costing its neighbour
/// blocks (neighbour_offsets[i + 1] - neighbour_offsets[i]) plus eight for its finish. Fewer
/// ranges when the rows do not go round.
std::vector<int> ResidentRanges(const std::vector<int>& neighbour_offsets, int n_rows, int ranges);

/// SolveLoop::kAuto's limit on a CPU device of `compute_units` cores: kResidentMaxStepBytes on
/// two, less on more (the host loop's steps spread over the cores; unlimited on one).
double ResidentMaxStepBytes(unsigned compute_units);

/// The -D build options that specialise kernels/hopfield.cl for these options.
std::string KernelBuildOptions(const EnergyOptions& energy, const DynamicsOptions& dynamics);

}  // namespace hnnstereo::hnn
