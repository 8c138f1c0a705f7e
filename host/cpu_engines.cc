#include "host/cpu_engines.h"

#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>

#include "host/hopfield_energy.h"
#include "common/timing.h"

namespace hnnstereo::hnn {
namespace {

using Clock = std::chrono::steady_clock;

using common::MillisecondsSince;

void CheckOptions(const EnergyOptions& energy, const DynamicsOptions& dynamics) {
  if (auto error = energy.Check(); !error.empty()) throw std::invalid_argument(error);
  if (auto error = dynamics.Check(); !error.empty()) throw std::invalid_argument(error);
}

}  // namespace

int UpdateRowDecisions(const NetworkLayout& layout, const std::vector<double>& u,
                       std::vector<int>* decisions) {
  int changed = 0;
  for (int i = 0; i < layout.n_rows; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    int best = -1;
    double best_u = 0.0;
    for (int a = layout.row_offsets[ui]; a < layout.row_offsets[ui + 1]; ++a) {
      const double ua = u[static_cast<std::size_t>(a)];
      if (best < 0 || ua > best_u) best = a - layout.row_offsets[ui], best_u = ua;
    }
    const int decision = best >= 0 && best_u > 0.0 ? best : -1;
    if (decision != (*decisions)[ui]) ++changed;
    (*decisions)[ui] = decision;
  }
  return changed;
}

namespace {

double IntegralTerm(const std::vector<double>& V, const DynamicsOptions& dynamics) {
  if (dynamics.activation == Activation::kDiscrete) return 0.0;
  double sum = 0.0;
  for (double v : V) sum += ActivationIntegral(v, dynamics.alpha);
  return sum;
}

}  // namespace

double LyapunovEnergy(const NetworkLayout& layout, const std::vector<double>& weights,
                      const std::vector<double>& biases, const std::vector<double>& V,
                      const EnergyOptions& energy, const DynamicsOptions& dynamics) {
  return Energy(layout, weights, biases, V, energy) + IntegralTerm(V, dynamics);
}

SolveReport SolveThesis(const MatchingProblem& problem, const EnergyOptions& energy,
                        const DynamicsOptions& dynamics, std::size_t memory_budget_bytes) {
  CheckOptions(energy, dynamics);
  SolveReport report;
  report.engine = "thesis";
  report.device = "host CPU (serial)";
  const auto network_start = Clock::now();
  const NetworkLayout layout = BuildLayout(problem, energy, memory_budget_bytes);
  report.network_ms = MillisecondsSince(network_start);
  const auto n = static_cast<std::size_t>(layout.n_neurons);
  report.n_neurons = layout.n_neurons;

  auto start = Clock::now();
  const std::vector<double> compatibility = BuildCompatibilityWeights(problem, layout, energy);
  const std::vector<float> W =
      BuildDenseWeights(problem, layout, compatibility, energy, memory_budget_bytes);
  const std::vector<double> biases = BuildBiases(problem, layout, energy);
  report.n_connections = static_cast<std::int64_t>(n * (n > 0 ? n - 1 : 0));
  report.weights_ms = MillisecondsSince(start);

  start = Clock::now();
  std::vector<double> V = InitialActivations(problem, dynamics);
  // The thesis computed the energy once, then tracked it incrementally (CHopfield::
  // updateEnergyValue): dE = -(V_new - V_old) h_a, exact because W is symmetric, W_aa = 0.
  double E = Energy(layout, compatibility, biases, V, energy);
  double integral = IntegralTerm(V, dynamics);
  report.energy_initial = E;
  std::mt19937_64 rng(dynamics.seed);
  std::uniform_int_distribution<std::size_t> pick(0, n > 0 ? n - 1 : 0);
  int consecutive_stable = 0;
  int updates = 0;
  // The net input each neuron saw at its last update (V = g(net input)); initially g^-1(V).
  std::vector<double> net_input(n);
  for (std::size_t a = 0; a < n; ++a) {
    net_input[a] = dynamics.activation == Activation::kContinuous
                       ? InverseActivation(V[a], dynamics.alpha)
                       : V[a] - 0.5;
  }
  report.energy_trace.reserve(static_cast<std::size_t>(std::min(dynamics.max_updates, 1 << 20)));
  while (n > 0 && updates < dynamics.max_updates && consecutive_stable < dynamics.stable_updates) {
    const std::size_t a = pick(rng);
    const float* row = &W[a * n];
    double h0 = 0.0, h1 = 0.0, h2 = 0.0, h3 = 0.0;
    std::size_t b = 0;
    for (; b + 4 <= n; b += 4) {
      h0 += row[b] * V[b];
      h1 += row[b + 1] * V[b + 1];
      h2 += row[b + 2] * V[b + 2];
      h3 += row[b + 3] * V[b + 3];
    }
    for (; b < n; ++b) h0 += row[b] * V[b];
    const double h = h0 + h1 + h2 + h3 + biases[a];
    const double previous = V[a];
    // The neuron settles to g(net input) (tau = 1, steady state of the Hopfield-Tank neuron).
    const double next = Activate(h, dynamics.activation, dynamics.alpha, previous);
    const double dE = -(next - previous) * h;
    if (dynamics.activation == Activation::kContinuous) {
      integral += ActivationIntegral(next, dynamics.alpha) -
                  ActivationIntegral(previous, dynamics.alpha);
    }
    V[a] = next;
    net_input[a] = h;
    E += dE;
    ++updates;
    consecutive_stable = std::abs(dE) < dynamics.update_tolerance ? consecutive_stable + 1 : 0;
    report.energy_trace.push_back(E);
    report.energy_trace_iterations.push_back(updates);
    report.lyapunov_trace.push_back(E + integral);
  }
  report.solve_ms = MillisecondsSince(start);
  report.iterations = updates;
  report.converged = consecutive_stable >= dynamics.stable_updates;
  report.termination = report.converged ? "converged" : "iteration limit";
  // Recompute from scratch: the incremental sum drifts by rounding over many updates.
  report.energy_final = Energy(layout, compatibility, biases, V, energy);
  report.activation = std::move(V);
  report.potential = std::move(net_input);
  return report;
}

SolveReport SolveCpu(const MatchingProblem& problem, const EnergyOptions& energy,
                     const DynamicsOptions& dynamics, std::size_t memory_budget_bytes) {
  CheckOptions(energy, dynamics);
  SolveReport report;
  report.engine = "cpu";
  report.device = "host CPU (reference, double)";
  const auto network_start = Clock::now();
  const NetworkLayout layout = BuildLayout(problem, energy, memory_budget_bytes);
  report.network_ms = MillisecondsSince(network_start);
  report.n_neurons = layout.n_neurons;
  report.n_connections = layout.n_connections();

  auto start = Clock::now();
  const std::vector<double> weights = BuildCompatibilityWeights(problem, layout, energy);
  const std::vector<double> biases = BuildBiases(problem, layout, energy);
  report.weights_ms = MillisecondsSince(start);

  start = Clock::now();
  std::vector<double> V = InitialActivations(problem, dynamics);
  std::vector<double> u(V.size());
  for (std::size_t a = 0; a < V.size(); ++a) {
    u[a] = dynamics.activation == Activation::kContinuous ? InverseActivation(V[a], dynamics.alpha)
                                                          : V[a] - 0.5;
  }
  const double tolerance = dynamics.energy_tolerance * std::max(1, layout.n_neurons);
  const bool by_decisions = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
  std::vector<int> decisions(static_cast<std::size_t>(layout.n_rows), -2);
  double last_check_energy = 0.0;
  int stable = 0;
  int step = 0;
  for (;; ++step) {
    // Hopfield-Tank, explicit Euler: u += dt (-u / tau + sum_b W_ab V_b + I_a), V = g(u).
    const std::vector<double> input = SynapticInput(layout, weights, V, energy);
    const bool check = step % dynamics.energy_interval == 0 || step == dynamics.max_steps;
    if (check) {
      double E = 0.0;
      for (std::size_t a = 0; a < V.size(); ++a) E -= V[a] * (0.5 * input[a] + biases[a]);
      if (step == 0) report.energy_initial = E;
      report.energy_trace.push_back(E);
      report.energy_trace_iterations.push_back(step);
      if (by_decisions) {
        const int changed = UpdateRowDecisions(layout, u, &decisions);
        if (step > 0) {
          stable = changed <= dynamics.decision_tolerance * std::max(1, layout.n_rows) ? stable + 1 : 0;
        }
      } else if (step > 0) {
        stable = std::abs(E - last_check_energy) <= tolerance ? stable + 1 : 0;
      }
      last_check_energy = E;
      report.energy_final = E;
      if (stable >= dynamics.stable_checks) {
        report.converged = true;
        break;
      }
      if (step >= dynamics.max_steps) break;
    }
    for (std::size_t a = 0; a < V.size(); ++a) {
      u[a] += dynamics.time_step * (-u[a] / dynamics.tau + input[a] + biases[a]);
      V[a] = Activate(u[a], dynamics.activation, dynamics.alpha, V[a]);
    }
  }
  report.iterations = step;
  report.termination = report.converged ? "converged" : "iteration limit";
  report.solve_ms = MillisecondsSince(start);
  report.activation = std::move(V);
  report.potential = std::move(u);
  return report;
}

}  // namespace hnnstereo::hnn
