#pragma once
// The OpenCL engine's internals (not part of the library's interface): a batch of networks on
// the device, the part common to both weight layouts - the combined network, the command queue
// and its profile, the per-network convergence bookkeeping. The layouts themselves:
// host/device_network_csr.h (per-neuron weights) and host/device_network_blocks.h (row blocks).

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"
#include "host/opencl_engine.h"
#include "common/timing.h"
#include "host/opencl_runtime.h"
#include "host/solve_report.h"

namespace hnnstereo::hnn::device {

using Clock = std::chrono::steady_clock;

using common::MillisecondsSince;

inline constexpr int kLocalSize = 64;  // power of two, for segment_sum; PoCL vectorises across it

/// A global range of at least n work-items (one, if n is 0) in whole groups of kLocalSize.
cl::NDRange RoundedRange(std::size_t n);

struct EnergyParams {  // mirrors EnergyParams in kernels/hopfield.cl
  cl_float A, B, C, D;
  cl_float W1, W2, T, lambda;
  cl_float theta, weight_offset, attenuation_centre, attenuation_slope;
};
/// The energy's coefficients as the kernels take them (float).
EnergyParams Params(const EnergyOptions& energy);

/// All networks of a batch concatenated into one block-diagonal network.
struct CombinedNetwork {
  NetworkLayout layout;
  std::vector<cl_float2> left_point, right_point, feature_point;
  std::vector<float> correlation, bias, V, u;
  std::vector<int> network_of_neuron;
  std::vector<int> network_offsets;  // n_networks + 1, neuron ranges
  std::vector<std::int64_t> connections;  // per network
};

/// The batch's layouts, data and initial states, one network after another; throws when the
/// options are invalid, the batch mixes network kinds or exceeds the memory budget.
CombinedNetwork CombineNetworks(const ProblemBatch& problems, const EnergyOptions& energy,
                                const DynamicsOptions& dynamics, std::size_t memory_budget_bytes);

/// A device copy of `data` (an empty vector is first given one element: OpenCL forbids
/// zero-sized buffers).
template <typename T>
cl::Buffer MakeBuffer(const cl::Context& context, cl_mem_flags flags, std::vector<T>& data) {
  if (data.empty()) data.resize(1);
  return cl::Buffer(context, flags | CL_MEM_COPY_HOST_PTR, sizeof(T) * data.size(), data.data());
}

/// A read-only copy of `data` on the device without a host copy first (an empty vector gives one
/// zero element); the OpenCL call takes a non-const pointer to the data it only reads.
template <typename T>
cl::Buffer MakeReadOnlyBuffer(const cl::Context& context, const std::vector<T>& data) {
  const T zero{};
  const T* source = data.empty() ? &zero : data.data();
  return cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                    sizeof(T) * std::max<std::size_t>(data.size(), 1), const_cast<T*>(source));
}

/// Sets a kernel's arguments in order.
template <typename... Args>
void SetArgs(cl::Kernel& kernel, const Args&... args) {
  cl_uint index = 0;
  (kernel.setArg(index++, args), ...);
}

/// A batch of networks on the device: the combined network, the queue (profiled or not), the
/// buffers both layouts share and the kDecisions stop rule's buffers.
class DeviceNetwork {
 public:
  DeviceNetwork(ocl::Runtime& runtime, CombinedNetwork net, bool profile);

  const CombinedNetwork& network() const { return net_; }
  int n_networks() const { return static_cast<int>(net_.network_offsets.size()) - 1; }
  const std::vector<int>& rows_per_network() const { return rows_per_network_; }
  int launches() const { return launches_; }
  int blocking_reads() const { return blocking_reads_; }

  /// Enqueues `kernel`; with profiling on, keeps its event under the kernel's name.
  void Launch(cl::Kernel& kernel, const cl::NDRange& global, const cl::NDRange& local);
  /// With profiling on, the slot for the event of the next command named `what`; else nullptr.
  cl::Event* Record(std::string what);
  /// Commands from here on count as the solve's (the ones before as the weight build's).
  void StartSolveProfile() { solve_first_event_ = events_.size(); }
  /// Device time per command name from the profiling events (CL_PROFILING_COMMAND_START/END),
  /// build and solve apart; empty without profiling. Call after Finish().
  std::vector<KernelTime> ProfiledTimes() const;
  /// Which networks still step (1) or are frozen (0).
  void SetActive(const std::vector<int>& active);
  void Finish() { queue_.finish(); }

 protected:
  /// Rows per network and the kDecisions buffers (decisions_, changes_); returns each row's
  /// network (the first network whose neuron range ends beyond the row's start).
  std::vector<int> SetUpDecisionBuffers();
  /// Blocking read of the rows whose decision changed, per network, into `changes`.
  void ReadDecisionChanges(std::vector<int>* changes);

  ocl::Runtime& runtime_;
  const bool profile_;
  cl::CommandQueue queue_;  // the runtime's, or with CL_QUEUE_PROFILING_ENABLE when profiling
  std::vector<std::pair<std::string, cl::Event>> events_;  // profiling: every recorded command
  std::size_t solve_first_event_ = 0;
  CombinedNetwork net_;
  int launches_ = 0, blocking_reads_ = 0;
  const cl::NDRange local_{kLocalSize};
  // Shared by both layouts' kernels.
  cl::Buffer feature_point_, neighbour_offsets_, neighbours_, column_offsets_, network_offsets_,
      column_sums_, active_, network_energy_;
  cl::Kernel segment_sum_;
  cl::NDRange segment_range_;
  // kDecisions stop rule.
  std::vector<int> rows_per_network_;
  cl::Buffer decisions_, changes_;
};

/// The convergence bookkeeping shared by the solve loops: records the energy of every active
/// network at `step`, and deactivates those whose test passed (thesis: |dE| below the tolerance
/// for `stable_checks` consecutive checks) or that reached the step limit. Returns whether any
/// network stopped at this check.
bool CheckConvergence(int step, const std::vector<float>& energies,
                      const std::vector<int>& decision_changes,
                      const std::vector<int>& rows_per_network, const DynamicsOptions& dynamics,
                      std::vector<SolveReport>* reports, std::vector<int>* active,
                      std::vector<double>* last_energy, std::vector<int>* stable,
                      std::size_t* n_active);

/// Fills each network's final state (its neuron range of V and u) and the batch's times.
void FinishReports(const std::vector<float>& final_V, const std::vector<float>& final_u,
                   const CombinedNetwork& net, double weights_ms, double solve_ms,
                   std::vector<SolveReport>* reports);

/// Runs the weight build to completion (its wall time is returned), then starts the solve's
/// clock and its share of the profile.
template <typename Build>
double BuildWeightsThenStartSolve(DeviceNetwork& device, Build build,
                                  Clock::time_point* solve_start) {
  const auto start = Clock::now();
  build();
  device.Finish();
  const double weights_ms = MillisecondsSince(start);
  device.StartSolveProfile();
  *solve_start = Clock::now();
  return weights_ms;
}

}  // namespace hnnstereo::hnn::device
