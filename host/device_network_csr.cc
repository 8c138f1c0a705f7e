#include "host/device_network_csr.h"

#include <algorithm>

namespace hnnstereo::hnn::device {

CsrNetwork::CsrNetwork(ocl::Runtime& runtime, CombinedNetwork net, const EnergyOptions& energy,
                       const DynamicsOptions& dynamics, bool profile)
    : DeviceNetwork(runtime, std::move(net), profile) {
  const cl::Program& program = runtime_.Program("hopfield", KernelBuildOptions(energy, dynamics));
  UploadLayout();
  MakeKernels(program, energy, dynamics);
  SetUpDecisions(program);
}

// The layout, the per-neuron data, the state and the work buffers on the device.
void CsrNetwork::UploadLayout() {
  const NetworkLayout& L = net_.layout;
  const auto n = static_cast<std::size_t>(L.n_neurons);
  const cl::Context& context = runtime_.context();
  const cl_mem_flags ro = CL_MEM_READ_ONLY;
  host_copies_.neuron_row = L.neuron_row;
  host_copies_.neuron_column = L.neuron_column;
  host_copies_.row_offsets = L.row_offsets;
  host_copies_.column_offsets = L.column_offsets;
  host_copies_.column_neurons = L.column_neurons;
  host_copies_.neighbour_offsets = L.feature_neighbour_offsets;
  host_copies_.neighbours = L.feature_neighbours;
  host_copies_.weight_offsets.assign(L.weight_offsets.begin(), L.weight_offsets.end());
  neuron_row_ = MakeBuffer(context, ro, host_copies_.neuron_row);
  neuron_column_ = MakeBuffer(context, ro, host_copies_.neuron_column);
  row_offsets_ = MakeBuffer(context, ro, host_copies_.row_offsets);
  column_offsets_ = MakeBuffer(context, ro, host_copies_.column_offsets);
  column_neurons_ = MakeBuffer(context, ro, host_copies_.column_neurons);
  neighbour_offsets_ = MakeBuffer(context, ro, host_copies_.neighbour_offsets);
  neighbours_ = MakeBuffer(context, ro, host_copies_.neighbours);
  weight_offsets_ = MakeBuffer(context, ro, host_copies_.weight_offsets);
  left_point_ = MakeBuffer(context, ro, net_.left_point);
  right_point_ = MakeBuffer(context, ro, net_.right_point);
  feature_point_ = MakeBuffer(context, ro, net_.feature_point);
  correlation_ = MakeBuffer(context, ro, net_.correlation);
  bias_ = MakeBuffer(context, ro, net_.bias);
  network_of_neuron_ = MakeBuffer(context, ro, net_.network_of_neuron);
  network_offsets_ = MakeBuffer(context, ro, net_.network_offsets);
  weights_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                        sizeof(float) * std::max<std::int64_t>(L.n_connections(), 1));
  std::vector<float> V0 = net_.V, u0 = net_.u;
  V_ = MakeBuffer(context, CL_MEM_READ_WRITE, V0);
  u_ = MakeBuffer(context, CL_MEM_READ_WRITE, u0);
  field_ = cl::Buffer(context, CL_MEM_READ_WRITE, sizeof(float) * std::max<std::size_t>(n, 1));
  energy_terms_ =
      cl::Buffer(context, CL_MEM_READ_WRITE, sizeof(float) * std::max<std::size_t>(n, 1));
  row_sums_ = cl::Buffer(
      context, CL_MEM_READ_WRITE,
      sizeof(float) * std::max<std::size_t>(static_cast<std::size_t>(L.n_rows), 1));
  column_sums_ = cl::Buffer(
      context, CL_MEM_READ_WRITE,
      sizeof(float) * std::max<std::size_t>(static_cast<std::size_t>(L.n_columns), 1));
  std::vector<int> active(static_cast<std::size_t>(n_networks()), 1);
  active_ = MakeBuffer(context, CL_MEM_READ_WRITE, active);
  network_energy_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                               sizeof(float) * static_cast<std::size_t>(n_networks()));
}

// build_weights, line_sums, neuron_field, neuron_euler and segment_sum with their arguments.
void CsrNetwork::MakeKernels(const cl::Program& program, const EnergyOptions& energy,
                             const DynamicsOptions& dynamics) {
  const NetworkLayout& L = net_.layout;
  const auto n = static_cast<std::size_t>(L.n_neurons);
  const EnergyParams params = Params(energy);
  build_weights_ = cl::Kernel(program, "build_weights");
  SetArgs(build_weights_, static_cast<cl_int>(n), left_point_, right_point_, correlation_,
          neuron_row_, feature_point_, row_offsets_, neighbour_offsets_, neighbours_,
          weight_offsets_, params, weights_);
  line_sums_ = cl::Kernel(program, "line_sums");
  SetArgs(line_sums_, static_cast<cl_int>(L.n_rows), static_cast<cl_int>(L.n_columns),
          row_offsets_, column_offsets_, column_neurons_, V_, row_sums_, column_sums_);
  neuron_field_ = cl::Kernel(program, "neuron_field");
  SetArgs(neuron_field_, static_cast<cl_int>(n), neuron_row_, neuron_column_, row_offsets_,
          neighbour_offsets_, neighbours_, weight_offsets_, weights_, bias_, row_sums_,
          column_sums_, static_cast<cl_float>(2.0 * energy.B),
          static_cast<cl_float>(L.column_uniqueness ? 2.0 * energy.C : 0.0), network_of_neuron_,
          active_, V_, field_, energy_terms_);
  neuron_euler_ = cl::Kernel(program, "neuron_euler");
  SetArgs(neuron_euler_, static_cast<cl_int>(n), network_of_neuron_, active_,
          static_cast<cl_float>(dynamics.time_step), static_cast<cl_float>(1.0 / dynamics.tau),
          static_cast<cl_float>(dynamics.alpha), field_, u_, V_);
  segment_sum_ = cl::Kernel(program, "segment_sum");
  SetArgs(segment_sum_, network_offsets_, energy_terms_, network_energy_,
          cl::Local(sizeof(float) * kLocalSize));
  neuron_range_ = RoundedRange(n);
  line_range_ = RoundedRange(static_cast<std::size_t>(L.n_rows) +
                             static_cast<std::size_t>(L.n_columns));
  segment_range_ = cl::NDRange(static_cast<std::size_t>(n_networks()) * kLocalSize);
}

// The kDecisions buffers and the row_decisions kernel over rows given as (first neuron, count)
// at the state u.
void CsrNetwork::SetUpDecisions(const cl::Program& program) {
  const NetworkLayout& L = net_.layout;
  const cl::Context& context = runtime_.context();
  std::vector<int> network_of_row = SetUpDecisionBuffers();
  std::vector<int> row_size(network_of_row.size(), 0);
  for (int i = 0; i < L.n_rows; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    row_size[ui] = L.row_offsets[ui + 1] - L.row_offsets[ui];
  }
  std::vector<int> row_first(L.row_offsets.begin(),
                             L.row_offsets.end() - (L.n_rows > 0 ? 1 : 0));
  row_first.resize(row_size.size(), 0);
  row_first_ = MakeBuffer(context, CL_MEM_READ_ONLY, row_first);
  row_size_ = MakeBuffer(context, CL_MEM_READ_ONLY, row_size);
  decision_network_ = MakeBuffer(context, CL_MEM_READ_ONLY, network_of_row);
  row_decisions_ = cl::Kernel(program, "row_decisions");
  SetArgs(row_decisions_, static_cast<cl_int>(L.n_rows), row_first_, row_size_,
          decision_network_, active_, u_, decisions_, changes_);
  decision_range_ = RoundedRange(row_size.size());
}

double CsrNetwork::StepBytes() const {
  const NetworkLayout& L = net_.layout;
  const double neurons = L.n_neurons;
  return 4.0 * static_cast<double>(L.n_connections()) + 12.0 * neurons + 8.0 * neurons;
}

void CsrNetwork::Field() {
  Launch(line_sums_, line_range_, local_);
  Launch(neuron_field_, neuron_range_, local_);
}

std::vector<float> CsrNetwork::Energies() {
  std::vector<float> energies(static_cast<std::size_t>(n_networks()));
  Launch(segment_sum_, segment_range_, local_);
  queue_.enqueueReadBuffer(network_energy_, CL_TRUE, 0, sizeof(float) * energies.size(),
                           energies.data(), nullptr, Record("read energies"));
  return energies;
}

std::vector<int> CsrNetwork::DecisionChanges(const DynamicsOptions& dynamics) {
  if (dynamics.stop_rule != DynamicsOptions::StopRule::kDecisions) return {};
  std::vector<int> changes(static_cast<std::size_t>(n_networks()), 0);
  queue_.enqueueWriteBuffer(changes_, CL_FALSE, 0, sizeof(int) * changes.size(), changes.data());
  Launch(row_decisions_, decision_range_, local_);
  ++launches_;
  ReadDecisionChanges(&changes);
  return changes;
}

void CsrNetwork::WriteState(const std::vector<float>& V) {
  queue_.enqueueWriteBuffer(V_, CL_TRUE, 0, sizeof(float) * V.size(), V.data());
}

std::vector<float> CsrNetwork::Read(const cl::Buffer& buffer, std::size_t count) {
  std::vector<float> out(std::max<std::size_t>(count, 1));
  queue_.enqueueReadBuffer(buffer, CL_TRUE, 0, sizeof(float) * out.size(), out.data());
  out.resize(count);
  return out;
}

void CsrNetwork::Solve(const DynamicsOptions& dynamics, std::vector<SolveReport>* reports) {
  const std::size_t n = reports->size();
  Clock::time_point start;
  const double weights_ms = BuildWeightsThenStartSolve(*this, [&] { BuildWeights(); }, &start);
  std::vector<int> active(n, 1), stable(n, 0);
  std::vector<double> last_energy(n, 0.0);
  std::size_t n_active = n;
  for (int step = 0;; ++step) {
    Field();
    if (step % dynamics.energy_interval == 0 || step == dynamics.max_steps) {
      const std::vector<float> energies = Energies();
      const std::vector<int> changes = DecisionChanges(dynamics);
      const bool changed = CheckConvergence(step, energies, changes, rows_per_network(),
                                            dynamics, reports, &active, &last_energy, &stable,
                                            &n_active);
      if (n_active == 0) break;
      if (changed) SetActive(active);
    }
    Euler();
  }
  const std::vector<float> final_V = ReadState();
  const std::vector<float> final_u = ReadPotential();
  FinishReports(final_V, final_u, net_, weights_ms, MillisecondsSince(start), reports);
}

}  // namespace hnnstereo::hnn::device
