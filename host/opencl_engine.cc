#include "host/opencl_engine.h"

#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "host/hopfield_energy.h"

namespace hnnstereo::hnn {
namespace {

using Clock = std::chrono::steady_clock;

double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

constexpr int kLocalSize = 64;  // power of two, for segment_sum; PoCL vectorises across it

cl::NDRange RoundedRange(std::size_t n) {
  const std::size_t groups = (n + kLocalSize - 1) / kLocalSize;
  return cl::NDRange(std::max<std::size_t>(groups, 1) * kLocalSize);
}

struct EnergyParams {  // mirrors EnergyParams in kernels/hopfield.cl
  cl_float A, B, C, D;
  cl_float W1, W2, T, lambda;
  cl_float theta, weight_offset, attenuation_centre, attenuation_slope;
};

// All networks of a batch concatenated into one block-diagonal network.
struct CombinedNetwork {
  NetworkLayout layout;
  std::vector<cl_float2> left_point, right_point, feature_point;
  std::vector<float> correlation, bias, V, u;
  std::vector<int> network_of_neuron;
  std::vector<int> network_offsets;  // n_networks + 1, neuron ranges
  std::vector<std::int64_t> connections;  // per network
};

template <typename T>
cl::Buffer MakeBuffer(const cl::Context& context, cl_mem_flags flags, std::vector<T>& data) {
  if (data.empty()) data.resize(1);  // OpenCL forbids zero-sized buffers
  return cl::Buffer(context, flags | CL_MEM_COPY_HOST_PTR, sizeof(T) * data.size(), data.data());
}

}  // namespace

std::string KernelBuildOptions(const EnergyOptions& energy, const DynamicsOptions& dynamics) {
  return "-DOBJECTIVE=" + std::to_string(static_cast<int>(energy.objective)) +
         " -DCOMPAT_TYPE=" + std::to_string(static_cast<int>(energy.compatibility)) +
         " -DDISTANCE_ATTENUATION=" + std::to_string(energy.distance_attenuation ? 1 : 0) +
         " -DDISCRETE=" + std::to_string(dynamics.activation == Activation::kDiscrete ? 1 : 0);
}

namespace {

// A batch of networks on the device: the combined layout, its buffers and the kernels.
class DeviceNetwork {
 public:
  DeviceNetwork(ocl::Runtime& runtime, const ProblemBatch& problems, const EnergyOptions& energy,
                const DynamicsOptions& dynamics, std::size_t memory_budget_bytes)
      : runtime_(runtime), queue_(runtime.queue()) {
    if (auto error = energy.Check(); !error.empty()) throw std::invalid_argument(error);
    if (auto error = dynamics.Check(); !error.empty()) throw std::invalid_argument(error);
    Combine(problems, energy, dynamics, memory_budget_bytes);
    Upload(energy, dynamics);
  }

  const CombinedNetwork& network() const { return net_; }
  int n_networks() const { return static_cast<int>(net_.network_offsets.size()) - 1; }

  void BuildWeights() {
    queue_.enqueueNDRangeKernel(build_weights_, cl::NullRange, neuron_range_, local_);
  }
  // line_sums then neuron_field: the field and energy terms of the current state.
  void Field() {
    queue_.enqueueNDRangeKernel(line_sums_, cl::NullRange, line_range_, local_);
    queue_.enqueueNDRangeKernel(neuron_field_, cl::NullRange, neuron_range_, local_);
  }
  void Euler() { queue_.enqueueNDRangeKernel(neuron_euler_, cl::NullRange, neuron_range_, local_); }
  // Per-network energies of the state the last Field() saw (blocking).
  std::vector<float> Energies() {
    std::vector<float> energies(static_cast<std::size_t>(n_networks()));
    queue_.enqueueNDRangeKernel(segment_sum_, cl::NullRange, segment_range_, local_);
    queue_.enqueueReadBuffer(network_energy_, CL_TRUE, 0, sizeof(float) * energies.size(),
                             energies.data());
    return energies;
  }
  void SetActive(const std::vector<int>& active) {
    queue_.enqueueWriteBuffer(active_, CL_TRUE, 0, sizeof(int) * active.size(), active.data());
  }
  void WriteState(const std::vector<float>& V) {
    queue_.enqueueWriteBuffer(V_, CL_TRUE, 0, sizeof(float) * V.size(), V.data());
  }
  std::vector<float> Read(const cl::Buffer& buffer, std::size_t count) {
    std::vector<float> out(std::max<std::size_t>(count, 1));
    queue_.enqueueReadBuffer(buffer, CL_TRUE, 0, sizeof(float) * out.size(), out.data());
    out.resize(count);
    return out;
  }
  std::vector<float> ReadState() { return Read(V_, static_cast<std::size_t>(net_.layout.n_neurons)); }
  std::vector<float> ReadPotential() { return Read(u_, static_cast<std::size_t>(net_.layout.n_neurons)); }
  std::vector<float> ReadWeights() {
    return Read(weights_, static_cast<std::size_t>(net_.layout.n_connections()));
  }
  std::vector<float> ReadField() { return Read(field_, static_cast<std::size_t>(net_.layout.n_neurons)); }
  void Finish() { queue_.finish(); }

 private:
  void Combine(const ProblemBatch& problems, const EnergyOptions& energy,
               const DynamicsOptions& dynamics, std::size_t memory_budget_bytes) {
    NetworkLayout& L = net_.layout;
    L.row_offsets = {0};
    L.column_offsets = {0};
    L.feature_neighbour_offsets = {0};
    L.weight_offsets = {0};
    net_.network_offsets = {0};
    std::size_t total_bytes = 0;
    for (std::size_t p = 0; p < problems.size(); ++p) {
      const MatchingProblem& problem = problems[p];
      const NetworkLayout part = BuildLayout(problem, energy, memory_budget_bytes);
      total_bytes += EstimateSize(part).total_bytes;
      CheckMemoryBudget(total_bytes, memory_budget_bytes, "the batch of networks", part);
      const int neuron_base = L.n_neurons, row_base = L.n_rows;
      const std::int64_t weight_base = L.weight_offsets.back();
      const int neighbour_base = static_cast<int>(L.feature_neighbours.size());
      for (int a = 0; a < part.n_neurons; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        L.neuron_row.push_back(part.neuron_row[ua] + row_base);
        L.neuron_column.push_back(part.neuron_column[ua] + L.n_columns);
        L.weight_offsets.push_back(part.weight_offsets[ua + 1] + weight_base);
        const Candidate& c = problem.candidates[ua];
        const Eigen::Vector2f& left = problem.left_points[static_cast<std::size_t>(c.left)];
        net_.left_point.push_back({{left.x(), left.y()}});
        net_.right_point.push_back({{c.right_point.x(), c.right_point.y()}});
        net_.correlation.push_back(c.correlation);
        net_.bias.push_back(
            static_cast<float>(Bias(c.epipolar_distance_px, part.column_uniqueness, energy)));
        net_.network_of_neuron.push_back(static_cast<int>(p));
      }
      for (int i = 0; i < part.n_rows; ++i) {
        const auto ui = static_cast<std::size_t>(i);
        L.row_offsets.push_back(part.row_offsets[ui + 1] + neuron_base);
        L.feature_neighbour_offsets.push_back(part.feature_neighbour_offsets[ui + 1] +
                                              neighbour_base);
        const Eigen::Vector2f& point = problem.left_points[ui];
        net_.feature_point.push_back({{point.x(), point.y()}});
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
      net_.network_offsets.push_back(L.n_neurons);
      net_.connections.push_back(part.n_connections());
      // Column uniqueness is a property of the network kind; a batch must agree.
      if (p == 0) L.column_uniqueness = part.column_uniqueness;
      if (part.column_uniqueness != L.column_uniqueness) {
        throw std::invalid_argument(
            "a batch must not mix feature-vs-feature and feature-vs-disparity networks");
      }
      for (double v : InitialActivations(problem, dynamics)) {
        net_.V.push_back(static_cast<float>(v));
        net_.u.push_back(static_cast<float>(dynamics.activation == Activation::kContinuous
                                                ? InverseActivation(v, dynamics.alpha)
                                                : v - 0.5));
      }
    }
  }

  void Upload(const EnergyOptions& energy, const DynamicsOptions& dynamics) {
    const NetworkLayout& L = net_.layout;
    const auto n = static_cast<std::size_t>(L.n_neurons);
    const cl::Context& context = runtime_.context();
    const cl::Program& program = runtime_.Program("hopfield", KernelBuildOptions(energy, dynamics));
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
    energy_terms_ = cl::Buffer(context, CL_MEM_READ_WRITE, sizeof(float) * std::max<std::size_t>(n, 1));
    row_sums_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                           sizeof(float) * std::max<std::size_t>(static_cast<std::size_t>(L.n_rows), 1));
    column_sums_ = cl::Buffer(
        context, CL_MEM_READ_WRITE,
        sizeof(float) * std::max<std::size_t>(static_cast<std::size_t>(L.n_columns), 1));
    std::vector<int> active(static_cast<std::size_t>(n_networks()), 1);
    active_ = MakeBuffer(context, CL_MEM_READ_WRITE, active);
    network_energy_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                                 sizeof(float) * static_cast<std::size_t>(n_networks()));

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
    line_range_ = RoundedRange(static_cast<std::size_t>(L.n_rows) + static_cast<std::size_t>(L.n_columns));
    segment_range_ = cl::NDRange(static_cast<std::size_t>(n_networks()) * kLocalSize);
  }

  template <typename... Args>
  static void SetArgs(cl::Kernel& kernel, const Args&... args) {
    cl_uint index = 0;
    (kernel.setArg(index++, args), ...);
  }

  struct HostCopies {
    std::vector<int> neuron_row, neuron_column, row_offsets, column_offsets, column_neurons,
        neighbour_offsets, neighbours;
    std::vector<cl_long> weight_offsets;
  };

  ocl::Runtime& runtime_;
  cl::CommandQueue& queue_;
  CombinedNetwork net_;
  HostCopies host_copies_;
  cl::Buffer neuron_row_, neuron_column_, row_offsets_, column_offsets_, column_neurons_,
      neighbour_offsets_, neighbours_, weight_offsets_, left_point_, right_point_, feature_point_,
      correlation_, bias_, network_of_neuron_, network_offsets_, weights_, V_, u_, field_,
      energy_terms_, row_sums_, column_sums_, active_, network_energy_;
  cl::Kernel build_weights_, line_sums_, neuron_field_, neuron_euler_, segment_sum_;
  cl::NDRange neuron_range_, line_range_, segment_range_;
  const cl::NDRange local_{kLocalSize};

 public:
  const cl::Buffer& field_buffer() const { return field_; }
};

}  // namespace

SolveReport OpenClEngine::Solve(const MatchingProblem& problem, const EnergyOptions& energy,
                                const DynamicsOptions& dynamics, std::size_t memory_budget_bytes) {
  return SolveBatch(ProblemBatch{problem}, energy, dynamics, memory_budget_bytes).front();
}

std::vector<float> OpenClEngine::BuildWeights(const MatchingProblem& problem,
                                              const EnergyOptions& energy) {
  try {
    DeviceNetwork device(runtime_, ProblemBatch{problem}, energy, DynamicsOptions{},
                         kDefaultMemoryBudgetBytes);
    device.BuildWeights();
    return device.ReadWeights();
  } catch (const cl::Error& e) {
    throw ocl::OpenClError(e.what(), e.err());
  }
}

std::vector<float> OpenClEngine::Field(const MatchingProblem& problem, const EnergyOptions& energy,
                                       const std::vector<double>& V, double* energy_out) {
  try {
    DeviceNetwork device(runtime_, ProblemBatch{problem}, energy, DynamicsOptions{},
                         kDefaultMemoryBudgetBytes);
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
    DeviceNetwork device(runtime_, problems, energy, dynamics, memory_budget_bytes);
    const CombinedNetwork& net = device.network();
    for (std::size_t p = 0; p < problems.size(); ++p) {
      reports[p].engine = "opencl";
      reports[p].device = runtime_.description();
      reports[p].n_neurons = net.network_offsets[p + 1] - net.network_offsets[p];
      reports[p].n_connections = net.connections[p];
    }
    auto start = Clock::now();
    device.BuildWeights();
    device.Finish();
    const double weights_ms = MillisecondsSince(start);

    start = Clock::now();
    std::vector<int> active(problems.size(), 1);
    std::vector<double> last_energy(problems.size(), 0.0);
    std::vector<int> stable(problems.size(), 0);
    std::size_t n_active = problems.size();
    for (int step = 0;; ++step) {
      device.Field();
      if (step % dynamics.energy_interval == 0 || step == dynamics.max_steps) {
        const std::vector<float> energies = device.Energies();
        bool active_changed = false;
        for (std::size_t p = 0; p < problems.size(); ++p) {
          if (!active[p]) continue;
          SolveReport& report = reports[p];
          const double E = energies[p];
          const double tolerance = dynamics.energy_tolerance * std::max(1, report.n_neurons);
          if (step == 0) report.energy_initial = E;
          report.energy_trace.push_back(E);
          report.energy_trace_iterations.push_back(step);
          if (step > 0) stable[p] = std::abs(E - last_energy[p]) <= tolerance ? stable[p] + 1 : 0;
          last_energy[p] = E;
          report.energy_final = E;
          report.iterations = step;
          if (stable[p] >= dynamics.stable_checks || step >= dynamics.max_steps) {
            report.converged = stable[p] >= dynamics.stable_checks;
            active[p] = 0;
            active_changed = true;
            --n_active;
          }
        }
        if (n_active == 0) break;
        if (active_changed) device.SetActive(active);
      }
      device.Euler();
    }
    const std::vector<float> final_V = device.ReadState();
    const std::vector<float> final_u = device.ReadPotential();
    const double solve_ms = MillisecondsSince(start);
    for (std::size_t p = 0; p < problems.size(); ++p) {
      SolveReport& report = reports[p];
      report.termination = report.converged ? "converged" : "iteration limit";
      report.weights_ms = weights_ms;
      report.solve_ms = solve_ms;
      report.activation.assign(final_V.begin() + net.network_offsets[p],
                               final_V.begin() + net.network_offsets[p + 1]);
      report.potential.assign(final_u.begin() + net.network_offsets[p],
                              final_u.begin() + net.network_offsets[p + 1]);
    }
  } catch (const cl::Error& e) {
    throw ocl::OpenClError(e.what(), e.err());
  }
  return reports;
}

}  // namespace hnnstereo::hnn
