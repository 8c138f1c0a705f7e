#pragma once
// The OpenCL engine's CSR layout (WeightStorage::kCsr): every neuron's weights contiguous (its
// row of W over its neighbour rows' neurons), one work-item per neuron, three launches a step
// (line_sums, neuron_field, neuron_euler in kernels/hopfield.cl). Internal to the engine.

#include <vector>

#include "host/device_network.h"

namespace hnnstereo::hnn::device {

class CsrNetwork : public DeviceNetwork {
 public:
  /// Uploads the network and builds its kernels (the weights are built by BuildWeights()).
  CsrNetwork(ocl::Runtime& runtime, CombinedNetwork net, const EnergyOptions& energy,
             const DynamicsOptions& dynamics, bool profile);

  /// The whole solve: the weight build, then the host loop of steps and convergence checks.
  void Solve(const DynamicsOptions& dynamics, std::vector<SolveReport>* reports);

  /// The bytes one step reads: every weight (4 B), the neighbour lists per neuron and V[b] per
  /// connection (gathered, mostly from cache: counted once per neuron).
  double StepBytes() const;

  void BuildWeights() { Launch(build_weights_, neuron_range_, local_); }
  /// line_sums then neuron_field: the field and energy terms of the current state.
  void Field();
  void Euler() { Launch(neuron_euler_, neuron_range_, local_); }
  /// Per-network energies of the state the last Field() saw (blocking).
  std::vector<float> Energies();
  /// Rows whose decision changed since the last call, per network (row_decisions at the
  /// state u; kDecisions stop rule, empty otherwise).
  std::vector<int> DecisionChanges(const DynamicsOptions& dynamics);
  void WriteState(const std::vector<float>& V);
  std::vector<float> ReadState() { return Read(V_, n_neurons()); }
  std::vector<float> ReadPotential() { return Read(u_, n_neurons()); }
  std::vector<float> ReadWeights() {
    return Read(weights_, static_cast<std::size_t>(net_.layout.n_connections()));
  }
  std::vector<float> ReadField() { return Read(field_, n_neurons()); }

 private:
  std::size_t n_neurons() const { return static_cast<std::size_t>(net_.layout.n_neurons); }
  std::vector<float> Read(const cl::Buffer& buffer, std::size_t count);
  void UploadLayout();
  void MakeKernels(const cl::Program& program, const EnergyOptions& energy,
                   const DynamicsOptions& dynamics);
  void SetUpDecisions(const cl::Program& program);

  // The layout's lists as the kernels take them (weight offsets as cl_long).
  struct HostCopies {
    std::vector<int> neuron_row, neuron_column, row_offsets, column_offsets, column_neurons,
        neighbour_offsets, neighbours;
    std::vector<cl_long> weight_offsets;
  };
  HostCopies host_copies_;
  cl::Buffer neuron_row_, neuron_column_, row_offsets_, column_neurons_, weight_offsets_,
      left_point_, right_point_, correlation_, bias_, network_of_neuron_, weights_, V_, u_,
      field_, energy_terms_, row_sums_;
  cl::Kernel build_weights_, line_sums_, neuron_field_, neuron_euler_;
  cl::NDRange neuron_range_, line_range_;
  // row_decisions over rows given as (first neuron, count).
  cl::Buffer row_first_, row_size_, decision_network_;
  cl::Kernel row_decisions_;
  cl::NDRange decision_range_;
};

}  // namespace hnnstereo::hnn::device
