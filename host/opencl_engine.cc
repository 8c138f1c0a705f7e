#include "host/opencl_engine.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "host/device_network.h"
#include "host/device_network_blocks.h"
#include "host/device_network_csr.h"

namespace hnnstereo::hnn {
namespace {

using device::Clock;
using device::MillisecondsSince;

// The batch's reports as the device network left them: its profile, layout, launches and reads.
template <typename Network>
void FillDeviceReports(const Network& device, WeightStorage storage, const char* solve_loop,
                       double network_ms, std::vector<SolveReport>* reports) {
  const std::vector<KernelTime> kernel_times = device.ProfiledTimes();
  for (SolveReport& report : *reports) {
    report.kernel_times = kernel_times;  // the batch's, shared
    report.weight_storage = std::string(WeightStorageName(storage));
    if (solve_loop) report.solve_loop = solve_loop;
    report.step_bytes = device.StepBytes();
    report.launches = device.launches();
    report.blocking_reads = device.blocking_reads();
    report.network_ms = network_ms;  // the batch's, shared
  }
}

}  // namespace

std::string_view WeightStorageName(WeightStorage storage) {
  switch (storage) {
    case WeightStorage::kAuto: return "auto";
    case WeightStorage::kCsr: return "csr";
    case WeightStorage::kBlockedFloat: return "blocked-float";
    case WeightStorage::kBlockedHalf: return "blocked-half";
    case WeightStorage::kOnTheFly: return "on-the-fly";
  }
  return "auto";
}

namespace {
constexpr WeightStorage kAllStorages[] = {WeightStorage::kAuto, WeightStorage::kCsr,
                                          WeightStorage::kBlockedFloat, WeightStorage::kBlockedHalf,
                                          WeightStorage::kOnTheFly};
}  // namespace

std::optional<WeightStorage> ParseWeightStorage(std::string_view name) {
  for (WeightStorage s : kAllStorages) {
    if (WeightStorageName(s) == name) return s;
  }
  return std::nullopt;
}

std::string WeightStorageNames() {
  std::string names;
  for (WeightStorage s : kAllStorages) {
    if (!names.empty()) names += ", ";
    names += WeightStorageName(s);
  }
  return names;
}

std::optional<OpenClEngineOptions::SolveLoop> ParseSolveLoop(std::string_view name) {
  if (name == "auto") return OpenClEngineOptions::SolveLoop::kAuto;
  if (name == "host") return OpenClEngineOptions::SolveLoop::kHost;
  if (name == "device") return OpenClEngineOptions::SolveLoop::kDevice;
  return std::nullopt;
}

double ResidentMaxStepBytes(unsigned compute_units) {
  // With C cores the host loop's step costs about o + W / C (o: a launch and its share of the
  // round trips, W: the step's work on one core), the device loop's W: they cross at
  // W = o C / (C - 1), which is kResidentMaxStepBytes at C = 2.
  if (compute_units <= 1) return std::numeric_limits<double>::infinity();
  const double c = static_cast<double>(compute_units);
  return kResidentMaxStepBytes * c / (2.0 * (c - 1.0));
}

std::vector<int> ResidentRanges(const std::vector<int>& neighbour_offsets, int n_rows, int ranges) {
  // A row's cost in blocks: its neighbour blocks, and its finish (the uniqueness term, the
  // activation, the energy term: about eight blocks' time on a CPU device).
  constexpr double kRowFinish = 8.0;
  const auto cost_before = [&](int i) {
    return static_cast<double>(neighbour_offsets[static_cast<std::size_t>(i)] -
                               neighbour_offsets[0]) +
           kRowFinish * i;
  };
  const int quads = (std::max(n_rows, 0) + 3) / 4;
  ranges = std::clamp(ranges, 1, std::max(quads, 1));
  const double total = cost_before(n_rows);
  std::vector<int> cuts{0};
  for (int g = 1; g < ranges; ++g) {
    // The first multiple of four rows whose cost before it reaches g / ranges of the total.
    const double target = total * g / ranges;
    int quad = cuts.back() / 4;
    while (quad < quads && cost_before(std::min(4 * quad, n_rows)) < target) ++quad;
    const int cut = std::min(4 * quad, n_rows);
    if (cut > cuts.back() && cut < n_rows) cuts.push_back(cut);
  }
  cuts.push_back(std::max(n_rows, 0));
  return cuts;
}

std::string KernelBuildOptions(const EnergyOptions& energy, const DynamicsOptions& dynamics) {
  return "-DOBJECTIVE=" + std::to_string(static_cast<int>(energy.objective)) +
         " -DCOMPAT_TYPE=" + std::to_string(static_cast<int>(energy.compatibility)) +
         " -DDISTANCE_ATTENUATION=" + std::to_string(energy.distance_attenuation ? 1 : 0) +
         " -DDISCRETE=" + std::to_string(dynamics.activation == Activation::kDiscrete ? 1 : 0);
}

SolveReport OpenClEngine::Solve(const MatchingProblem& problem, const EnergyOptions& energy,
                                const DynamicsOptions& dynamics, std::size_t memory_budget_bytes) {
  return SolveBatch(ProblemBatch{problem}, energy, dynamics, memory_budget_bytes).front();
}

double OpenClEngine::WarmUp(const EnergyOptions& energy, const DynamicsOptions& dynamics,
                           NetworkKind kind) {
  const auto start = Clock::now();
  // Three left features in a row, two candidates each: every kernel of the solve runs once.
  MatchingProblem problem;
  problem.kind = kind;
  problem.n_columns = 4;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector2f left(10.0f + 2.0f * static_cast<float>(i), 5.0f);
    problem.left_points.push_back(left);
    for (int k = 0; k < 2; ++k) {
      problem.candidates.push_back({i, i + k, Eigen::Vector2f(left.x() - 3.0f - static_cast<float>(k), 5.0f),
                                    0.0f, 0.5f});
    }
  }
  DynamicsOptions short_run = dynamics;
  short_run.max_steps = std::min(dynamics.max_steps, dynamics.energy_interval);
  // Both solve loops (the real network may take either under SolveLoop::kAuto): the host
  // loop's kernels and the one-launch loop's.
  for (const auto loop :
       {OpenClEngineOptions::SolveLoop::kHost, OpenClEngineOptions::SolveLoop::kDevice}) {
    OpenClEngineOptions options = options_;
    options.solve_loop = loop;
    OpenClEngine(runtime_, options).Solve(problem, energy, short_run);
  }
  return MillisecondsSince(start);
}

std::vector<float> OpenClEngine::BuildWeights(const MatchingProblem& problem,
                                              const EnergyOptions& energy) {
  try {
    const DynamicsOptions dynamics;
    device::CsrNetwork device(runtime_,
                              device::CombineNetworks(ProblemBatch{problem}, energy, dynamics,
                                                      kDefaultMemoryBudgetBytes),
                              energy, dynamics, false);
    device.BuildWeights();
    return device.ReadWeights();
  } catch (const cl::Error& e) {
    throw ocl::OpenClError(e.what(), e.err());
  }
}

std::vector<float> OpenClEngine::Field(const MatchingProblem& problem, const EnergyOptions& energy,
                                       const std::vector<double>& V, double* energy_out) {
  try {
    const DynamicsOptions dynamics;
    device::CsrNetwork device(runtime_,
                              device::CombineNetworks(ProblemBatch{problem}, energy, dynamics,
                                                      kDefaultMemoryBudgetBytes),
                              energy, dynamics, false);
    device.BuildWeights();
    device.WriteState(std::vector<float>(V.begin(), V.end()));
    device.Field();
    const std::vector<float> energies = device.Energies();
    if (energy_out) *energy_out = energies.front();
    return device.ReadField();
  } catch (const cl::Error& e) {
    throw ocl::OpenClError(e.what(), e.err());
  }
}

std::vector<SolveReport> OpenClEngine::SolveBatch(const ProblemBatch& problems,
                                                  const EnergyOptions& energy,
                                                  const DynamicsOptions& dynamics,
                                                  std::size_t memory_budget_bytes) {
  if (problems.empty()) return {};
  std::vector<SolveReport> reports(problems.size());
  try {
    const auto network_start = Clock::now();
    device::CombinedNetwork net =
        device::CombineNetworks(problems, energy, dynamics, memory_budget_bytes);
    for (std::size_t p = 0; p < problems.size(); ++p) {
      reports[p].engine = "opencl";
      reports[p].device = runtime_.description();
      reports[p].n_neurons = net.network_offsets[p + 1] - net.network_offsets[p];
      reports[p].n_connections = net.connections[p];
    }
    const device::StorageChoice choice =
        device::ChooseStorage(net.layout, runtime_.is_gpu(), options_.storage);
    if (choice.storage == WeightStorage::kCsr) {
      device::CsrNetwork csr(runtime_, std::move(net), energy, dynamics, options_.profile);
      const double network_ms = MillisecondsSince(network_start);
      csr.Solve(dynamics, &reports);
      csr.Finish();
      FillDeviceReports(csr, choice.storage, nullptr, network_ms, &reports);
    } else {
      device::BlockedNetwork blocked(runtime_, std::move(net), choice, energy, dynamics, options_,
                                     memory_budget_bytes);
      const double network_ms = MillisecondsSince(network_start);
      blocked.Solve(dynamics, &reports);
      blocked.Finish();
      FillDeviceReports(blocked, choice.storage, blocked.resident() ? "device" : "host",
                        network_ms, &reports);
    }
  } catch (const cl::Error& e) {
    throw ocl::OpenClError(e.what(), e.err());
  }
  return reports;
}

}  // namespace hnnstereo::hnn
