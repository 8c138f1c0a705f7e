#include "host/device_network.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "host/hopfield_energy.h"

namespace hnnstereo::hnn::device {

cl::NDRange RoundedRange(std::size_t n) {
  const std::size_t groups = (n + kLocalSize - 1) / kLocalSize;
  return cl::NDRange(std::max<std::size_t>(groups, 1) * kLocalSize);
}

EnergyParams Params(const EnergyOptions& energy) {
  EnergyParams params{};
  params.A = static_cast<float>(energy.A);
  params.B = static_cast<float>(energy.B);
  params.C = static_cast<float>(energy.C);
  params.D = static_cast<float>(energy.D);
  params.W1 = static_cast<float>(energy.W1);
  params.W2 = static_cast<float>(energy.W2);
  params.T = static_cast<float>(energy.T);
  params.lambda = static_cast<float>(energy.lambda);
  params.theta = static_cast<float>(energy.theta);
  params.weight_offset = static_cast<float>(energy.weight_offset);
  params.attenuation_centre = static_cast<float>(energy.attenuation_centre_px);
  params.attenuation_slope = static_cast<float>(energy.attenuation_slope);
  return params;
}

namespace {

// A later network's layout after the ones before it: its neurons, rows, columns and
// neighbour lists offset by theirs.
void AppendLayout(const NetworkLayout& part, NetworkLayout* combined) {
  NetworkLayout& L = *combined;
  const int neuron_base = L.n_neurons, row_base = L.n_rows;
  const std::int64_t weight_base = L.weight_offsets.back();
  const int neighbour_base = static_cast<int>(L.feature_neighbours.size());
  for (int a = 0; a < part.n_neurons; ++a) {
    const auto ua = static_cast<std::size_t>(a);
    L.neuron_row.push_back(part.neuron_row[ua] + row_base);
    L.neuron_column.push_back(part.neuron_column[ua] + L.n_columns);
    L.weight_offsets.push_back(part.weight_offsets[ua + 1] + weight_base);
  }
  for (int i = 0; i < part.n_rows; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    L.row_offsets.push_back(part.row_offsets[ui + 1] + neuron_base);
    L.feature_neighbour_offsets.push_back(part.feature_neighbour_offsets[ui + 1] +
                                          neighbour_base);
  }
  for (int j : part.feature_neighbours) L.feature_neighbours.push_back(j + row_base);
  for (int k = 0; k < part.n_columns; ++k) {
    L.column_offsets.push_back(part.column_offsets[static_cast<std::size_t>(k) + 1] +
                               neuron_base);
  }
  for (int a : part.column_neurons) L.column_neurons.push_back(a + neuron_base);
  L.n_neurons += part.n_neurons;
  L.n_rows += part.n_rows;
  L.n_columns += part.n_columns;
}

// Network p's per-neuron data (points, correlation, bias, network index) after the ones before.
void AppendNeuronData(const MatchingProblem& problem, const NetworkLayout& part, int p,
                      const EnergyOptions& energy, CombinedNetwork* net) {
  for (int a = 0; a < part.n_neurons; ++a) {
    const Candidate& c = problem.candidates[static_cast<std::size_t>(a)];
    const Eigen::Vector2f& left = problem.left_points[static_cast<std::size_t>(c.left)];
    net->left_point.push_back({{left.x(), left.y()}});
    net->right_point.push_back({{c.right_point.x(), c.right_point.y()}});
    net->correlation.push_back(c.correlation);
    net->bias.push_back(
        static_cast<float>(Bias(c.epipolar_distance_px, part.column_uniqueness, energy)));
    net->network_of_neuron.push_back(p);
  }
  for (const Eigen::Vector2f& point : problem.left_points) {
    net->feature_point.push_back({{point.x(), point.y()}});
  }
}

// V and u of the network's initial state, after those of the networks before it.
void AppendInitialState(const MatchingProblem& problem, const DynamicsOptions& dynamics,
                        CombinedNetwork* net) {
  for (double v : InitialActivations(problem, dynamics)) {
    net->V.push_back(static_cast<float>(v));
    net->u.push_back(static_cast<float>(dynamics.activation == Activation::kContinuous
                                            ? InverseActivation(v, dynamics.alpha)
                                            : v - 0.5));
  }
}

}  // namespace

CombinedNetwork CombineNetworks(const ProblemBatch& problems, const EnergyOptions& energy,
                                const DynamicsOptions& dynamics, std::size_t memory_budget_bytes) {
  if (auto error = energy.Check(); !error.empty()) throw std::invalid_argument(error);
  if (auto error = dynamics.Check(); !error.empty()) throw std::invalid_argument(error);
  CombinedNetwork net;
  NetworkLayout& L = net.layout;
  L.row_offsets = {0};
  L.column_offsets = {0};
  L.feature_neighbour_offsets = {0};
  L.weight_offsets = {0};
  net.network_offsets = {0};
  std::size_t total_bytes = 0;
  for (std::size_t p = 0; p < problems.size(); ++p) {
    const MatchingProblem& problem = problems[p];
    NetworkLayout part = BuildLayout(problem, energy, memory_budget_bytes);
    total_bytes += EstimateSize(part).total_bytes;
    CheckMemoryBudget(total_bytes, memory_budget_bytes, "the batch of networks", part);
    AppendNeuronData(problem, part, static_cast<int>(p), energy, &net);
    net.connections.push_back(part.n_connections());
    // Column uniqueness is a property of the network kind; a batch must agree.
    if (p == 0) L.column_uniqueness = part.column_uniqueness;
    if (part.column_uniqueness != L.column_uniqueness) {
      throw std::invalid_argument(
          "a batch must not mix feature-vs-feature and feature-vs-disparity networks");
    }
    if (p == 0) {
      L = std::move(part);  // the first network's layout as it is: nothing to offset
    } else {
      AppendLayout(part, &L);
    }
    net.network_offsets.push_back(L.n_neurons);
    AppendInitialState(problem, dynamics, &net);
  }
  return net;
}

DeviceNetwork::DeviceNetwork(ocl::Runtime& runtime, CombinedNetwork net, bool profile)
    : runtime_(runtime),
      profile_(profile),
      queue_(profile ? cl::CommandQueue(runtime.context(), runtime.device(),
                                        CL_QUEUE_PROFILING_ENABLE)
                     : runtime.queue()),
      net_(std::move(net)) {}

void DeviceNetwork::Launch(cl::Kernel& kernel, const cl::NDRange& global,
                           const cl::NDRange& local) {
  cl::Event* event = nullptr;
  if (profile_) event = Record(kernel.getInfo<CL_KERNEL_FUNCTION_NAME>());
  queue_.enqueueNDRangeKernel(kernel, cl::NullRange, global, local, nullptr, event);
}

cl::Event* DeviceNetwork::Record(std::string what) {
  if (!profile_) return nullptr;
  events_.emplace_back(std::move(what), cl::Event());
  return &events_.back().second;
}

std::vector<KernelTime> DeviceNetwork::ProfiledTimes() const {
  std::vector<KernelTime> times;
  for (std::size_t e = 0; e < events_.size(); ++e) {
    const std::string phase = e < solve_first_event_ ? "build" : "solve";
    // Not a structured binding: clang before 16 cannot capture one in the lambda below.
    const std::string& name = events_[e].first;
    const cl::Event& event = events_[e].second;
    const cl_ulong begin = event.getProfilingInfo<CL_PROFILING_COMMAND_START>();
    const cl_ulong end = event.getProfilingInfo<CL_PROFILING_COMMAND_END>();
    auto it = std::find_if(times.begin(), times.end(), [&](const KernelTime& t) {
      return t.command == name && t.phase == phase;
    });
    if (it == times.end()) {
      times.push_back({name, phase, 0, 0.0});
      it = std::prev(times.end());
    }
    ++it->count;
    it->device_ms += end > begin ? static_cast<double>(end - begin) * 1e-6 : 0.0;
  }
  return times;
}

void DeviceNetwork::SetActive(const std::vector<int>& active) {
  queue_.enqueueWriteBuffer(active_, CL_TRUE, 0, sizeof(int) * active.size(), active.data());
}

std::vector<int> DeviceNetwork::SetUpDecisionBuffers() {
  const NetworkLayout& L = net_.layout;
  const cl::Context& context = runtime_.context();
  std::vector<int> network_of_row(static_cast<std::size_t>(std::max(L.n_rows, 1)), 0);
  rows_per_network_.assign(static_cast<std::size_t>(n_networks()), 0);
  for (int i = 0; i < L.n_rows; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    int p = 0;
    while (p + 1 < n_networks() &&
           L.row_offsets[ui] >= net_.network_offsets[static_cast<std::size_t>(p) + 1]) {
      ++p;
    }
    network_of_row[ui] = p;
    ++rows_per_network_[static_cast<std::size_t>(p)];
  }
  std::vector<int> decisions(network_of_row.size(), -2);
  std::vector<int> changes(static_cast<std::size_t>(n_networks()), 0);
  decisions_ = MakeBuffer(context, CL_MEM_READ_WRITE, decisions);
  changes_ = MakeBuffer(context, CL_MEM_READ_WRITE, changes);
  return network_of_row;
}

void DeviceNetwork::ReadDecisionChanges(std::vector<int>* changes) {
  queue_.enqueueReadBuffer(changes_, CL_TRUE, 0, sizeof(int) * changes->size(), changes->data(),
                           nullptr, Record("read decision changes"));
  ++blocking_reads_;
}

bool CheckConvergence(int step, const std::vector<float>& energies,
                      const std::vector<int>& decision_changes,
                      const std::vector<int>& rows_per_network, const DynamicsOptions& dynamics,
                      std::vector<SolveReport>* reports, std::vector<int>* active,
                      std::vector<double>* last_energy, std::vector<int>* stable,
                      std::size_t* n_active) {
  const bool by_decisions = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
  bool changed = false;
  for (std::size_t p = 0; p < reports->size(); ++p) {
    if (!(*active)[p]) continue;
    SolveReport& report = (*reports)[p];
    const double E = energies[p];
    const double tolerance = dynamics.energy_tolerance * std::max(1, report.n_neurons);
    if (step == 0) report.energy_initial = E;
    report.energy_trace.push_back(E);
    report.energy_trace_iterations.push_back(step);
    if (step > 0) {
      const bool settled =
          by_decisions ? decision_changes[p] <= dynamics.decision_tolerance *
                                                    std::max(1, rows_per_network[p])
                       : std::abs(E - (*last_energy)[p]) <= tolerance;
      (*stable)[p] = settled ? (*stable)[p] + 1 : 0;
    }
    (*last_energy)[p] = E;
    report.energy_final = E;
    report.iterations = step;
    if ((*stable)[p] >= dynamics.stable_checks || step >= dynamics.max_steps) {
      report.converged = (*stable)[p] >= dynamics.stable_checks;
      (*active)[p] = 0;
      changed = true;
      --*n_active;
    }
  }
  return changed;
}

void FinishReports(const std::vector<float>& final_V, const std::vector<float>& final_u,
                   const CombinedNetwork& net, double weights_ms, double solve_ms,
                   std::vector<SolveReport>* reports) {
  for (std::size_t p = 0; p < reports->size(); ++p) {
    SolveReport& report = (*reports)[p];
    report.termination = report.converged ? "converged" : "iteration limit";
    report.weights_ms = weights_ms;
    report.solve_ms = solve_ms;
    report.activation.assign(final_V.begin() + net.network_offsets[p],
                             final_V.begin() + net.network_offsets[p + 1]);
    report.potential.assign(final_u.begin() + net.network_offsets[p],
                            final_u.begin() + net.network_offsets[p + 1]);
  }
}

}  // namespace hnnstereo::hnn::device
