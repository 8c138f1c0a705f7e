#pragma once
// The OpenCL engine: weight construction, lockstep neuron updates (explicit Euler steps of the
// Hopfield-Tank equation - the analog chip imitated), row/column sums and energy reductions as
// kernels (kernels/hopfield.cl); many independent networks per launch.

#include <cstddef>
#include <vector>

#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"
#include "host/opencl_runtime.h"
#include "host/solve_report.h"

namespace hnnstereo::hnn {

class OpenClEngine {
 public:
  /// The runtime must outlive the engine.
  explicit OpenClEngine(ocl::Runtime& runtime) : runtime_(runtime) {}

  SolveReport Solve(const MatchingProblem& problem, const EnergyOptions& energy,
                    const DynamicsOptions& dynamics,
                    std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

  /// Solves independent networks together (block diagonal, one launch per kernel per step);
  /// each network stops (is frozen) when its own convergence test passes. The memory budget
  /// applies to the whole batch.
  std::vector<SolveReport> SolveBatch(const ProblemBatch& problems, const EnergyOptions& energy,
                                      const DynamicsOptions& dynamics,
                                      std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

  /// Kernel probes, for tests against the CPU reference and for benchmarks of single stages.
  /// The compatibility weights from the build_weights kernel, in layout order.
  std::vector<float> BuildWeights(const MatchingProblem& problem, const EnergyOptions& energy);
  /// One pass of line_sums + neuron_field + segment_sum at state V: the net input
  /// sum_b W_ab V_b + I_a of every neuron, and the energy E(V) (eq. 6.10) in `energy_out`.
  std::vector<float> Field(const MatchingProblem& problem, const EnergyOptions& energy,
                           const std::vector<double>& V, double* energy_out);

 private:
  ocl::Runtime& runtime_;
};

/// The -D build options that specialise kernels/hopfield.cl for these options.
std::string KernelBuildOptions(const EnergyOptions& energy, const DynamicsOptions& dynamics);

}  // namespace hnnstereo::hnn
