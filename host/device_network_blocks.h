#pragma once
// The OpenCL engine's row-block layouts (WeightStorage::kBlockedFloat, kBlockedHalf and
// kOnTheFly): every row padded to ROW_PAD slots, the weights between two rows one dense block
// (or none, recomputed each step), one fused launch a step or the whole loop in one launch
// (kernels/hopfield.cl, "Row-blocked engine"). Internal to the engine.

#include <cstddef>
#include <vector>

#include "host/device_network.h"

namespace hnnstereo::hnn::device {

/// A layout for the combined network: the storage and the row blocks' shape.
struct StorageChoice {
  WeightStorage storage = WeightStorage::kCsr;
  int row_pad = 4;     ///< slots a row is padded to (ROW_PAD): a multiple of 4
  int block_cols = 4;  ///< neighbour slots a weight block stores (BLOCK_COLS): row_pad or 3
};

/// `asked`, or for kAuto: half-precision row blocks when padding every row to ROW_PAD slots at
/// most doubles the stored weights, else CSR; on a GPU also only for rows of at most 8 slots
/// (wider rows leave the card idle where CSR's work-item per neuron keeps it busy;
/// docs/engine.md, "Weight storage").
StorageChoice ChooseStorage(const NetworkLayout& layout, bool gpu, WeightStorage asked);

class BlockedNetwork : public DeviceNetwork {
 public:
  /// Uploads the padded network, builds its kernels and picks its solve loop (engine options);
  /// throws when the blocks exceed the memory budget.
  BlockedNetwork(ocl::Runtime& runtime, CombinedNetwork net, const StorageChoice& choice,
                 const EnergyOptions& energy, const DynamicsOptions& dynamics,
                 const OpenClEngineOptions& engine, std::size_t memory_budget_bytes);

  /// The whole solve: the block build, then the host loop (SolveOnHost) or the device loop
  /// (SolveOnDevice) as resident() says.
  void Solve(const DynamicsOptions& dynamics, std::vector<SolveReport>* reports);

  WeightStorage storage() const { return choice_.storage; }
  /// Whether the solve loop runs on the device (solve_blocked_resident).
  bool resident() const { return resident_; }
  /// The bytes one step reads: every block (4 or 2 B a slot pair), one neighbour index per
  /// block and V of each neighbour row (ROW_PAD floats, from cache: counted once per row); on
  /// the fly no weights but each slot's right point and correlation (12 B). Every step also
  /// moves 20 B a slot (V and u read and written, the bias read) and 12 B a row (its count and
  /// neighbour offset read, its energy term written).
  double StepBytes() const;

 private:
  // The row blocks' state buffers (V and u of both parities, by slot).
  struct BlockedState {
    std::vector<float> V[2], u[2];
  };
  // What the device loop reports: its outcome, trace and the state it stopped on.
  struct ResidentOutcome {
    int steps = 0;
    bool converged = false;
    int stop_parity = 0;
    std::vector<float> energy_trace;  // the energy at every check
    int groups = 1;                   // the work-groups that ran it
    BlockedState state;               // V and u as it stopped, in state.V/u[stop_parity]
  };
  // How the fused step is spread: rows per work-item, or a work-group per row.
  struct StepShape {
    bool row_per_group = false;
    int rows_per_item = 1;
  };

  std::size_t BlockBytes(std::size_t memory_budget_bytes) const;
  void UploadSlots();
  void SetUpBlockBuild(const cl::Program& program, const EnergyParams& params,
                       const EnergyOptions& energy, const OpenClEngineOptions& engine);
  StepShape ChooseStepShape(const OpenClEngineOptions& engine) const;
  void SetUpStep(const cl::Program& program, const EnergyParams& params,
                 const EnergyOptions& energy, const DynamicsOptions& dynamics,
                 const StepShape& shape);
  int ResidentGroups(const OpenClEngineOptions& engine) const;
  bool ChooseResident(const OpenClEngineOptions& engine, const StepShape& shape,
                      int groups) const;
  void SetUpResident(const cl::Program& program, const EnergyParams& params,
                     const EnergyOptions& energy, const DynamicsOptions& dynamics,
                     const StepShape& shape, int groups);

  void BuildBlocks();
  void Step(int parity, bool check);
  void CheckState(const DynamicsOptions& dynamics, std::vector<float>* energies,
                  std::vector<int>* changes);
  void EnqueueStateReads(const bool (&needed)[2], BlockedState* state);
  void ReadBlockedState(const std::vector<int>& stop_parity, std::vector<float>* V,
                        std::vector<float>* u);
  void StateByNeuron(const std::vector<int>& stop_parity, const BlockedState& state,
                     std::vector<float>* V, std::vector<float>* u) const;
  ResidentOutcome SolveResident();
  void SolveOnHost(const DynamicsOptions& dynamics, std::vector<SolveReport>* reports);
  void SolveOnDevice(const DynamicsOptions& dynamics, std::vector<SolveReport>* reports);

  StorageChoice choice_;
  int weights_mode_ = 0;  // WEIGHTS in kernels/hopfield.cl: 0 float, 1 half, 2 on the fly
  std::size_t slot_count_ = 1;
  // Host copies of the slot layout: counts per row, column slots, row ranges per network.
  struct HostBlocked {
    std::vector<int> row_count, column_slots, network_row_offsets;
  };
  HostBlocked host_blocked_;
  std::vector<int> row_network_;
  cl::Buffer row_count_, column_slots_, slot_right_, slot_correlation_, slot_bias_, slot_column_,
      network_of_row_, blocks_, row_energy_, V_state_[2], u_state_[2], block_row_;
  cl::Kernel build_blocks_, step_[2], column_sums_blocked_[2];
  cl::NDRange column_range_, step_range_, step_local_{1}, build_range_;
  std::vector<int> zero_changes_;  // written to changes_ before a deciding step (kept alive)
  bool by_decisions_ = false;
  // The solve loop on the device (SolveLoop::kDevice).
  bool resident_ = false;
  std::size_t resident_checks_ = 0;
  bool resident_launched_ = false;
  int resident_groups_ = 1, resident_ranges_ = 1, resident_column_ranges_ = 0;
  cl::Buffer resident_result_, range_rows_, range_changes_, range_claims_, loop_control_,
      column_range_columns_, column_claims_;
  cl::Kernel resident_loop_;
};

}  // namespace hnnstereo::hnn::device
