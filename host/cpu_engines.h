#pragma once
// CPU engines over the same problem and energy:
//  - thesis: serial asynchronous random single-neuron updates on dense weights, as the thesis
//    software ran it (stop after `stable_updates` consecutive |dE| < tolerance, or max_updates);
//  - cpu: plain C++ of the parallel Hopfield-Tank dynamics (explicit Euler, all neurons in
//    lockstep), in double: the reference the OpenCL kernels are tested against.

#include <cstddef>

#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"
#include "host/solve_report.h"

namespace hnnstereo::hnn {

SolveReport SolveThesis(const MatchingProblem& problem, const EnergyOptions& energy,
                        const DynamicsOptions& dynamics,
                        std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

SolveReport SolveCpu(const MatchingProblem& problem, const EnergyOptions& energy,
                     const DynamicsOptions& dynamics,
                     std::size_t memory_budget_bytes = kDefaultMemoryBudgetBytes);

/// The Lyapunov energy of the continuous network under asynchronous updates: E plus Hopfield's
/// integral term (for discrete activations, E itself). Used by tests of energy descent.
double LyapunovEnergy(const NetworkLayout& layout, const std::vector<double>& weights,
                      const std::vector<double>& biases, const std::vector<double>& V,
                      const EnergyOptions& energy, const DynamicsOptions& dynamics);

/// The decision of every row (the index within the row of its neuron with the largest u when
/// that u > 0, else -1) written into `decisions` (n_rows); returns how many rows changed. The
/// kDecisions stop rule (DynamicsOptions::StopRule) counts these changes between checks.
int UpdateRowDecisions(const NetworkLayout& layout, const std::vector<double>& u,
                       std::vector<int>* decisions);

}  // namespace hnnstereo::hnn
