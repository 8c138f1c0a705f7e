#pragma once
// What an engine did: iterations, energies, timings and the final activations.

#include <cstdint>
#include <string>
#include <vector>

namespace hnnstereo::hnn {

enum class EngineKind { kThesis, kCpu, kOpenCL };

/// Device time of one kind of OpenCL command, from profiling events (OpenClEngineOptions::profile).
struct KernelTime {
  std::string command;     ///< kernel function name, or "read energies" / "read decision changes"
  std::string phase;       ///< "build" (weights) or "solve" (the dynamics)
  int count = 0;           ///< commands enqueued
  double device_ms = 0.0;  ///< sum of CL_PROFILING_COMMAND_END - START over them
};

struct SolveReport {
  std::string engine;                 ///< "thesis", "cpu" or "opencl"
  std::string device;                 ///< "host CPU" or the OpenCL device name
  int n_neurons = 0;
  std::int64_t n_connections = 0;     ///< stored compatibility weights
  int iterations = 0;                 ///< Euler steps (parallel) or single-neuron updates (thesis)
  bool converged = false;             ///< the |dE| rule ended the run (not the limit)
  std::string termination;            ///< "converged" or "iteration limit"
  double energy_initial = 0.0;        ///< eq. 6.10 at the initial state
  double energy_final = 0.0;          ///< eq. 6.10 at the final state
  std::vector<double> energy_trace;   ///< energy at each check (parallel) / every update (thesis)
  std::vector<int> energy_trace_iterations;  ///< the iteration of each trace entry
  std::vector<double> activation;     ///< final V per neuron (match confidence)
  /// Final potential u per neuron (V = g(u)); the thesis engine's last net input. Ranks
  /// neurons where activations saturate.
  std::vector<double> potential;
  /// Thesis engine only: E plus the continuous network's integral term after every update
  /// (the Lyapunov function of asynchronous updates; equals E for discrete neurons).
  std::vector<double> lyapunov_trace;
  /// OpenCL engine: how the weights were held ("csr", "blocked-float", "blocked-half",
  /// "on-the-fly"), the bytes one step reads from memory under that layout's model (weights,
  /// neighbour lists and state; docs/benchmark.md), kernel launches and blocking reads.
  std::string weight_storage;
  /// OpenCL row blocks: where the solve loop ran ("host": a launch per step and a round trip
  /// per check; "device": one launch, OpenClEngineOptions::SolveLoop); empty otherwise.
  std::string solve_loop;
  /// The device loop's work-groups (OpenClEngineOptions::resident_groups, as chosen); 0 for
  /// the host loop.
  int solve_groups = 0;
  double step_bytes = 0.0;
  int launches = 0;
  int blocking_reads = 0;
  /// OpenCL engine with OpenClEngineOptions::profile: device time per command (empty otherwise).
  /// The solve's host gap is solve_ms minus the sum of its "solve" entries: launch latency,
  /// blocking-read round trips and the host's convergence bookkeeping.
  std::vector<KernelTime> kernel_times;
  double network_ms = 0.0;            ///< the layout (neighbour lists) and, on a device, its buffers
  double weights_ms = 0.0;            ///< weight construction
  double solve_ms = 0.0;              ///< the dynamics to convergence
};

}  // namespace hnnstereo::hnn
