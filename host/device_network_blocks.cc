#include "host/device_network_blocks.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace hnnstereo::hnn::device {
namespace {

// The fused step kernels' `check` argument (STEP_BLOCKED_PARAMS in kernels/hopfield.cl: the
// network's 20, the state's 5, decisions and changes); the group step's local buffer follows.
constexpr cl_uint kStepCheckArg = 27;

int MaxRowCount(const NetworkLayout& L) {
  int most = 0;
  for (int i = 0; i < L.n_rows; ++i) {
    most = std::max(most, L.row_offsets[static_cast<std::size_t>(i) + 1] -
                              L.row_offsets[static_cast<std::size_t>(i)]);
  }
  return most;
}

}  // namespace

StorageChoice ChooseStorage(const NetworkLayout& L, bool gpu, WeightStorage asked) {
  StorageChoice choice;
  const int most = MaxRowCount(L);
  choice.row_pad = std::max(4, (most + 3) / 4 * 4);
  // Rows of at most 3 neurons (hnn-default's K = 3) store 3 x 4 blocks (BLOCK_COLS).
  choice.block_cols = choice.row_pad == 4 && most <= 3 ? 3 : choice.row_pad;
  const double blocked =
      static_cast<double>(L.feature_neighbours.size()) * choice.row_pad * choice.block_cols;
  if (asked != WeightStorage::kAuto) {
    choice.storage = asked;
  } else if (gpu && choice.row_pad > 8) {
    choice.storage = WeightStorage::kCsr;
  } else {
    choice.storage =
        blocked <= 2.0 * std::max<double>(1.0, static_cast<double>(L.n_connections()))
            ? WeightStorage::kBlockedHalf
            : WeightStorage::kCsr;
  }
  return choice;
}

BlockedNetwork::BlockedNetwork(ocl::Runtime& runtime, CombinedNetwork net,
                               const StorageChoice& choice, const EnergyOptions& energy,
                               const DynamicsOptions& dynamics, const OpenClEngineOptions& engine,
                               std::size_t memory_budget_bytes)
    : DeviceNetwork(runtime, std::move(net), engine.profile), choice_(choice) {
  weights_mode_ = choice_.storage == WeightStorage::kBlockedFloat  ? 0
                  : choice_.storage == WeightStorage::kBlockedHalf ? 1
                                                                   : 2;
  const std::size_t block_bytes = BlockBytes(memory_budget_bytes);
  const std::string options = KernelBuildOptions(energy, dynamics) +
                              " -DROW_PAD=" + std::to_string(choice_.row_pad) +
                              " -DBLOCK_COLS=" + std::to_string(choice_.block_cols) +
                              " -DWEIGHTS=" + std::to_string(weights_mode_);
  const cl::Program& program = runtime_.Program("hopfield", options);
  UploadSlots();
  // Every block is written by the build before a step reads it: a reused buffer will do.
  blocks_ = runtime_.ScratchBuffer("weight blocks", block_bytes);
  const EnergyParams params = Params(energy);
  SetUpBlockBuild(program, params, energy, engine);
  const StepShape shape = ChooseStepShape(engine);
  SetUpStep(program, params, energy, dynamics, shape);
  const int groups = ResidentGroups(engine);
  resident_ = ChooseResident(engine, shape, groups);
  if (resident_) SetUpResident(program, params, energy, dynamics, shape, groups);
}

// The stored blocks' bytes (none on the fly); throws when they exceed the memory budget.
std::size_t BlockedNetwork::BlockBytes(std::size_t memory_budget_bytes) const {
  const std::size_t n_blocks = net_.layout.feature_neighbours.size();
  const std::size_t block_bytes =
      weights_mode_ == 2
          ? 0
          : n_blocks * static_cast<std::size_t>(choice_.row_pad * choice_.block_cols) *
                (weights_mode_ == 1 ? 2u : 4u);
  if (block_bytes > memory_budget_bytes) {
    throw MemoryBudgetExceeded(
        "the row-blocked weights need " + std::to_string(block_bytes >> 20) +
        " MB, over the memory budget of " + std::to_string(memory_budget_bytes >> 20) +
        " MB; use tighter gating, --max-features, or on-the-fly weights",
        block_bytes, memory_budget_bytes);
  }
  return block_bytes;
}

// The network as padded slots (slot i * ROW_PAD + k: neuron k of row i; padded slots hold the
// row's left point, V = 0 and are never written), its columns as slots, the rows of each
// network, and the state and work buffers on the device.
void BlockedNetwork::UploadSlots() {
  const NetworkLayout& L = net_.layout;
  const cl::Context& context = runtime_.context();
  const int row_pad = choice_.row_pad;
  slot_count_ = std::max<std::size_t>(1, static_cast<std::size_t>(L.n_rows) *
                                             static_cast<std::size_t>(row_pad));
  std::vector<cl_float2> slot_right(slot_count_);
  std::vector<float> slot_correlation(slot_count_, 0.0f), slot_bias(slot_count_, 0.0f);
  std::vector<float> V0(slot_count_, 0.0f), u0(slot_count_, -1.0f);
  std::vector<int> slot_column(slot_count_, 0);
  host_blocked_.row_count.assign(static_cast<std::size_t>(std::max(L.n_rows, 1)), 0);
  row_network_.assign(static_cast<std::size_t>(std::max(L.n_rows, 1)), 0);
  for (int i = 0; i < L.n_rows; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const int first = L.row_offsets[ui], count = L.row_offsets[ui + 1] - first;
    host_blocked_.row_count[ui] = count;
    for (int k = 0; k < row_pad; ++k) {
      const std::size_t slot =
          ui * static_cast<std::size_t>(row_pad) + static_cast<std::size_t>(k);
      slot_right[slot] = net_.feature_point[ui];
      if (k >= count) continue;
      const auto a = static_cast<std::size_t>(first + k);
      slot_right[slot] = net_.right_point[a];
      slot_correlation[slot] = net_.correlation[a];
      slot_bias[slot] = net_.bias[a];
      slot_column[slot] = L.neuron_column[a];
      V0[slot] = net_.V[a];
      u0[slot] = net_.u[a];
      row_network_[ui] = net_.network_of_neuron[a];
    }
  }
  host_blocked_.column_slots.clear();
  for (int a : L.column_neurons) {
    const int i = L.neuron_row[static_cast<std::size_t>(a)];
    host_blocked_.column_slots.push_back(i * row_pad + a -
                                         L.row_offsets[static_cast<std::size_t>(i)]);
  }
  host_blocked_.network_row_offsets = {0};
  for (std::size_t p = 0; p + 1 < net_.network_offsets.size(); ++p) {
    int rows = host_blocked_.network_row_offsets.back();
    while (rows < L.n_rows &&
           L.row_offsets[static_cast<std::size_t>(rows)] < net_.network_offsets[p + 1]) {
      ++rows;
    }
    host_blocked_.network_row_offsets.push_back(rows);
  }
  const cl_mem_flags ro = CL_MEM_READ_ONLY;
  std::vector<cl_float2> feature_point = net_.feature_point;
  feature_point_ = MakeBuffer(context, ro, feature_point);
  row_count_ = MakeBuffer(context, ro, host_blocked_.row_count);
  // The layout's own lists, not copies (26 MB of neighbours on all of Aloe).
  neighbour_offsets_ = MakeReadOnlyBuffer(context, L.feature_neighbour_offsets);
  neighbours_ = MakeReadOnlyBuffer(context, L.feature_neighbours);
  column_offsets_ = MakeReadOnlyBuffer(context, L.column_offsets);
  column_slots_ = MakeBuffer(context, ro, host_blocked_.column_slots);
  slot_right_ = MakeBuffer(context, ro, slot_right);
  slot_correlation_ = MakeBuffer(context, ro, slot_correlation);
  slot_bias_ = MakeBuffer(context, ro, slot_bias);
  slot_column_ = MakeBuffer(context, ro, slot_column);
  std::vector<int> row_network = row_network_;
  network_of_row_ = MakeBuffer(context, ro, row_network);
  network_offsets_ = MakeBuffer(context, ro, host_blocked_.network_row_offsets);
  std::vector<int> active(static_cast<std::size_t>(n_networks()), 1);
  active_ = MakeBuffer(context, CL_MEM_READ_WRITE, active);
  for (int b = 0; b < 2; ++b) {
    std::vector<float> V = V0, u = u0;
    V_state_[b] = MakeBuffer(context, CL_MEM_READ_WRITE, V);
    u_state_[b] = MakeBuffer(context, CL_MEM_READ_WRITE, u);
  }
  const std::size_t rows = static_cast<std::size_t>(std::max(L.n_rows, 1));
  row_energy_ = cl::Buffer(context, CL_MEM_READ_WRITE, sizeof(float) * rows);
  column_sums_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                            sizeof(float) * static_cast<std::size_t>(std::max(L.n_columns, 1)));
  network_energy_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                               sizeof(float) * static_cast<std::size_t>(n_networks()));
}

// The block build: one work-item per row for the default objective on a CPU device
// (build_weight_blocks_vec4, explicitly vectorised, each symmetric block pair computed once),
// else one per weight (build_weight_blocks_flat: a GPU, the other objectives, or when asked).
void BlockedNetwork::SetUpBlockBuild(const cl::Program& program, const EnergyParams& params,
                                     const EnergyOptions& energy,
                                     const OpenClEngineOptions& engine) {
  if (weights_mode_ == 2) return;  // on the fly: nothing to build
  const NetworkLayout& L = net_.layout;
  const cl::Context& context = runtime_.context();
  const std::size_t n_blocks = L.feature_neighbours.size();
  const bool vec4 =
      energy.objective == Objective::kGeometrySimilarity && !energy.distance_attenuation;
  const bool per_weight =
      !vec4 || engine.block_build == OpenClEngineOptions::BlockBuild::kPerWeight ||
      (engine.block_build == OpenClEngineOptions::BlockBuild::kAuto && runtime_.is_gpu());
  if (per_weight) {
    // Block t's row from block_row.
    std::vector<int> block_row(std::max<std::size_t>(n_blocks, 1), 0);
    for (int i = 0; i < L.n_rows; ++i) {
      for (int t = L.feature_neighbour_offsets[static_cast<std::size_t>(i)];
           t < L.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]; ++t) {
        block_row[static_cast<std::size_t>(t)] = i;
      }
    }
    block_row_ = MakeBuffer(context, CL_MEM_READ_ONLY, block_row);
    const auto n_weights = static_cast<cl_long>(n_blocks) * choice_.row_pad * choice_.block_cols;
    build_blocks_ = cl::Kernel(program, "build_weight_blocks_flat");
    SetArgs(build_blocks_, n_weights, block_row_, neighbours_, row_count_, slot_right_,
            slot_correlation_, feature_point_, params, blocks_);
    build_range_ = RoundedRange(static_cast<std::size_t>(std::max<cl_long>(n_weights, 1)));
    return;
  }
  build_blocks_ = cl::Kernel(program, "build_weight_blocks_vec4");
  SetArgs(build_blocks_, static_cast<cl_int>(L.n_rows), row_count_, neighbour_offsets_,
          neighbours_, slot_right_, slot_correlation_, feature_point_, params, blocks_);
  build_range_ = RoundedRange(static_cast<std::size_t>(std::max(L.n_rows, 1)));
}

// A GPU (or BlockStep::kRowPerGroup): one work-group of kStepGroup lanes per row. Else rows per
// work-item: one on a GPU (work-groups of 64), on a CPU device a run of rows per work-group of
// one work-item, which PoCL runs as a loop with the explicit vector loads.
BlockedNetwork::StepShape BlockedNetwork::ChooseStepShape(
    const OpenClEngineOptions& engine) const {
  const bool gpu = runtime_.is_gpu();
  StepShape shape;
  shape.row_per_group = engine.block_step == OpenClEngineOptions::BlockStep::kRowPerGroup ||
                        (engine.block_step == OpenClEngineOptions::BlockStep::kAuto && gpu);
  shape.rows_per_item = shape.row_per_group ? 1 : engine.rows_per_item;
  if (shape.rows_per_item <= 0) {
    shape.rows_per_item = gpu ? 1 : std::clamp(net_.layout.n_rows / 256, 1, 64);
  }
  return shape;
}

// The fused step kernels of both parities (state b read, 1 - b written), the column sums and
// segment_sum, and their ranges. The step also makes the kDecisions check (decide_row).
void BlockedNetwork::SetUpStep(const cl::Program& program, const EnergyParams& params,
                               const EnergyOptions& energy, const DynamicsOptions& dynamics,
                               const StepShape& shape) {
  const NetworkLayout& L = net_.layout;
  const bool gpu = runtime_.is_gpu();
  const std::size_t rows = static_cast<std::size_t>(std::max(L.n_rows, 1));
  const auto rows_per_item = static_cast<std::size_t>(shape.rows_per_item);
  const std::size_t items = (rows + rows_per_item - 1) / rows_per_item;
  const std::size_t step_local = shape.row_per_group ? kStepGroup : gpu ? 64 : 1;
  step_local_ = cl::NDRange(step_local);
  step_range_ = shape.row_per_group
                    ? cl::NDRange(rows * kStepGroup)
                    : cl::NDRange((items + step_local - 1) / step_local * step_local);
  const cl_float two_B = static_cast<cl_float>(2.0 * energy.B);
  const cl_float two_C = static_cast<cl_float>(L.column_uniqueness ? 2.0 * energy.C : 0.0);
  SetUpDecisionBuffers();
  zero_changes_.assign(static_cast<std::size_t>(n_networks()), 0);
  by_decisions_ = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
  for (int b = 0; b < 2; ++b) {
    step_[b] = cl::Kernel(program, shape.row_per_group ? "neuron_step_blocked_group"
                                                       : "neuron_step_blocked");
    SetArgs(step_[b], static_cast<cl_int>(L.n_rows), static_cast<cl_int>(shape.rows_per_item),
            row_count_, neighbour_offsets_, neighbours_, blocks_, slot_right_, slot_correlation_,
            feature_point_, params, slot_bias_, slot_column_, column_sums_, two_B, two_C,
            network_of_row_, active_, static_cast<cl_float>(dynamics.time_step),
            static_cast<cl_float>(1.0 / dynamics.tau), static_cast<cl_float>(dynamics.alpha),
            V_state_[b], u_state_[b], V_state_[1 - b], u_state_[1 - b], row_energy_, decisions_,
            changes_, cl_int{0});
    if (shape.row_per_group) {  // the lanes' partial inputs: kStepGroup x ROW_PAD floats
      step_[b].setArg(kStepCheckArg + 1,
                      cl::Local(sizeof(float) * static_cast<std::size_t>(kStepGroup) *
                                static_cast<std::size_t>(choice_.row_pad)));
    }
    column_sums_blocked_[b] = cl::Kernel(program, "column_sums_blocked");
    SetArgs(column_sums_blocked_[b], static_cast<cl_int>(L.n_columns), column_offsets_,
            column_slots_, V_state_[b], column_sums_);
  }
  segment_sum_ = cl::Kernel(program, "segment_sum");
  SetArgs(segment_sum_, network_offsets_, row_energy_, network_energy_,
          cl::Local(sizeof(float) * kLocalSize));
  column_range_ = RoundedRange(static_cast<std::size_t>(std::max(L.n_columns, 1)));
  segment_range_ = cl::NDRange(static_cast<std::size_t>(n_networks()) * kLocalSize);
}

// The device loop's work-groups: as asked, else one per core with kResidentRowsPerGroup rows
// each at least. One on a GPU whatever was asked: OpenCL 1.2 does not make one work-group's
// global writes visible to another's, and NVIDIA's driver shows several groups stale state.
int BlockedNetwork::ResidentGroups(const OpenClEngineOptions& engine) const {
  if (runtime_.is_gpu()) return 1;
  if (engine.resident_groups > 0) return engine.resident_groups;
  const auto units = runtime_.device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
  return std::clamp(net_.layout.n_rows / kResidentRowsPerGroup, 1, static_cast<int>(units));
}

// SolveLoop::kDevice for one network on the per-item step; kAuto on a CPU device when the
// rows spread over several groups (the steps without their launches and round trips), or with
// one group for stored blocks whose step reads at most ResidentMaxStepBytes.
bool BlockedNetwork::ChooseResident(const OpenClEngineOptions& engine, const StepShape& shape,
                                    int groups) const {
  const bool can_reside = n_networks() == 1 && !shape.row_per_group;
  if (!can_reside) return false;
  if (engine.solve_loop == OpenClEngineOptions::SolveLoop::kDevice) return true;
  if (engine.solve_loop != OpenClEngineOptions::SolveLoop::kAuto || runtime_.is_gpu()) {
    return false;
  }
  const bool spread = groups > 1 && net_.layout.n_rows >= 2 * kResidentRowsPerGroup;
  const auto units = runtime_.device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
  return spread || (choice_.storage != WeightStorage::kOnTheFly &&
                    StepBytes() <= ResidentMaxStepBytes(units));
}

// solve_blocked_resident's buffers and arguments: its result (outcome, energy trace, final V
// and u), the ranges of rows (and of columns, with column uniqueness) the groups claim, and
// the claims and loop control as the kernel expects them at its one launch.
void BlockedNetwork::SetUpResident(const cl::Program& program, const EnergyParams& params,
                                   const EnergyOptions& energy, const DynamicsOptions& dynamics,
                                   const StepShape& shape, int groups) {
  const NetworkLayout& L = net_.layout;
  const cl::Context& context = runtime_.context();
  const auto n_checks = static_cast<std::size_t>(
      std::max(dynamics.max_steps, 0) / std::max(dynamics.energy_interval, 1) + 2);
  resident_result_ =
      cl::Buffer(context, CL_MEM_READ_WRITE, sizeof(float) * (4 + n_checks + 2 * slot_count_));
  resident_checks_ = n_checks;
  resident_groups_ = groups;
  std::vector<int> range_rows =
      ResidentRanges(L.feature_neighbour_offsets, L.n_rows, groups * kResidentRangesPerGroup);
  resident_ranges_ = static_cast<int>(range_rows.size()) - 1;
  range_rows_ = MakeBuffer(context, CL_MEM_READ_ONLY, range_rows);
  range_changes_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                              sizeof(cl_int) * static_cast<std::size_t>(resident_ranges_));
  std::vector<cl_int> no_claims(static_cast<std::size_t>(resident_ranges_), -1);
  range_claims_ = MakeBuffer(context, CL_MEM_READ_WRITE, no_claims);
  std::vector<cl_int> control(4, 0);
  loop_control_ = MakeBuffer(context, CL_MEM_READ_WRITE, control);
  std::vector<int> column_ranges{0, 0};
  if (L.column_uniqueness && L.n_columns > 0) {
    column_ranges =
        ResidentRanges(L.column_offsets, L.n_columns, groups * kResidentRangesPerGroup);
  }
  resident_column_ranges_ = L.column_uniqueness ? static_cast<int>(column_ranges.size()) - 1 : 0;
  column_range_columns_ = MakeBuffer(context, CL_MEM_READ_ONLY, column_ranges);
  std::vector<cl_int> no_column_claims(column_ranges.size(), -1);
  column_claims_ = MakeBuffer(context, CL_MEM_READ_WRITE, no_column_claims);
  const cl_float two_B = static_cast<cl_float>(2.0 * energy.B);
  const cl_float two_C = static_cast<cl_float>(L.column_uniqueness ? 2.0 * energy.C : 0.0);
  resident_loop_ = cl::Kernel(program, "solve_blocked_resident");
  SetArgs(resident_loop_, static_cast<cl_int>(L.n_rows), static_cast<cl_int>(shape.rows_per_item),
          row_count_, neighbour_offsets_, neighbours_, blocks_, slot_right_, slot_correlation_,
          feature_point_, params, slot_bias_, slot_column_, column_sums_, two_B, two_C,
          network_of_row_, active_, static_cast<cl_float>(dynamics.time_step),
          static_cast<cl_float>(1.0 / dynamics.tau), static_cast<cl_float>(dynamics.alpha),
          V_state_[0], u_state_[0], V_state_[1], u_state_[1], row_energy_, decisions_,
          range_changes_, static_cast<cl_int>(dynamics.max_steps),
          static_cast<cl_int>(std::max(dynamics.energy_interval, 1)),
          static_cast<cl_int>(dynamics.stable_checks), static_cast<cl_int>(by_decisions_),
          static_cast<cl_float>(dynamics.energy_tolerance * std::max(1, L.n_neurons)),
          static_cast<cl_float>(dynamics.decision_tolerance * std::max(1, L.n_rows)),
          resident_result_, static_cast<cl_int>(n_checks), range_rows_,
          static_cast<cl_int>(resident_ranges_), range_claims_, loop_control_, column_offsets_,
          column_slots_, column_sums_, column_range_columns_,
          static_cast<cl_int>(resident_column_ranges_), column_claims_);
}

double BlockedNetwork::StepBytes() const {
  const NetworkLayout& L = net_.layout;
  const double rows = L.n_rows, row_pad = choice_.row_pad;
  const double neighbours = static_cast<double>(L.feature_neighbours.size());
  if (choice_.storage == WeightStorage::kOnTheFly) {
    return 4.0 * neighbours + 32.0 * rows * row_pad + 12.0 * rows;
  }
  const double slot_pair = choice_.storage == WeightStorage::kBlockedHalf ? 2.0 : 4.0;
  return slot_pair * neighbours * row_pad * choice_.block_cols + 4.0 * neighbours +
         20.0 * rows * row_pad + 12.0 * rows;
}

void BlockedNetwork::BuildBlocks() {
  if (choice_.storage == WeightStorage::kOnTheFly) return;
  Launch(build_blocks_, build_range_, local_);
  ++launches_;
}

// One fused step from state buffer `parity` into the other; column sums first when the
// network has column uniqueness. `check`: a convergence check follows, so under the
// kDecisions rule the step also counts the rows whose decision changed (decide_row).
void BlockedNetwork::Step(int parity, bool check) {
  if (net_.layout.column_uniqueness) {
    Launch(column_sums_blocked_[parity], column_range_, local_);
    ++launches_;
  }
  const bool decide = check && by_decisions_;
  if (decide) {
    queue_.enqueueWriteBuffer(changes_, CL_FALSE, 0, sizeof(int) * zero_changes_.size(),
                              zero_changes_.data());
  }
  step_[parity].setArg(kStepCheckArg, cl_int{decide ? 1 : 0});
  Launch(step_[parity], step_range_, step_local_);
  ++launches_;
}

// The convergence check in one host round trip: per-network energies (segment_sum over the row
// energies the step wrote) and, under the kDecisions rule, the rows whose decision changed,
// which the step before counted. The energies are read without blocking; the blocking read of
// the changes behind them on the in-order queue waits for both.
void BlockedNetwork::CheckState(const DynamicsOptions& dynamics, std::vector<float>* energies,
                                std::vector<int>* changes) {
  const bool decisions = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
  energies->assign(static_cast<std::size_t>(n_networks()), 0.0f);
  Launch(segment_sum_, segment_range_, local_);
  ++launches_;
  queue_.enqueueReadBuffer(network_energy_, decisions ? CL_FALSE : CL_TRUE, 0,
                           sizeof(float) * energies->size(), energies->data(), nullptr,
                           Record("read energies"));
  if (!decisions) {
    ++blocking_reads_;
    changes->clear();
    return;
  }
  changes->assign(static_cast<std::size_t>(n_networks()), 0);
  ReadDecisionChanges(changes);
}

// Enqueues reads of the state buffers b with needed[b], without blocking.
void BlockedNetwork::EnqueueStateReads(const bool (&needed)[2], BlockedState* state) {
  for (int b = 0; b < 2; ++b) {
    if (!needed[b]) continue;
    state->V[b].resize(slot_count_);
    state->u[b].resize(slot_count_);
    queue_.enqueueReadBuffer(V_state_[b], CL_FALSE, 0, sizeof(float) * slot_count_,
                             state->V[b].data());
    queue_.enqueueReadBuffer(u_state_[b], CL_FALSE, 0, sizeof(float) * slot_count_,
                             state->u[b].data());
  }
}

// Final V and u per neuron: network p is read from the state buffer it stopped on. Only the
// buffers some network stopped in are read, without blocking, then one wait: each blocking
// read costs a round trip to the device's threads.
void BlockedNetwork::ReadBlockedState(const std::vector<int>& stop_parity, std::vector<float>* V,
                                      std::vector<float>* u) {
  bool needed[2] = {false, false};
  for (const int b : stop_parity) needed[b == 0 ? 0 : 1] = true;
  BlockedState state;
  EnqueueStateReads(needed, &state);
  queue_.finish();
  ++blocking_reads_;
  StateByNeuron(stop_parity, state, V, u);
}

// V and u per neuron from the state buffers' copies (network p's from its stop parity).
void BlockedNetwork::StateByNeuron(const std::vector<int>& stop_parity,
                                   const BlockedState& state, std::vector<float>* V,
                                   std::vector<float>* u) const {
  const NetworkLayout& L = net_.layout;
  V->assign(static_cast<std::size_t>(L.n_neurons), 0.0f);
  u->assign(static_cast<std::size_t>(L.n_neurons), 0.0f);
  for (int i = 0; i < L.n_rows; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const int b = stop_parity[static_cast<std::size_t>(row_network_[ui])];
    for (int a = L.row_offsets[ui]; a < L.row_offsets[ui + 1]; ++a) {
      const std::size_t slot = ui * static_cast<std::size_t>(choice_.row_pad) +
                               static_cast<std::size_t>(a - L.row_offsets[ui]);
      (*V)[static_cast<std::size_t>(a)] = state.V[b][slot];
      (*u)[static_cast<std::size_t>(a)] = state.u[b][slot];
    }
  }
}

// The whole solve in one launch, then one blocking read of its result (outcome, trace and the
// state it stopped on). The claims and control are as the buffers were made: once a network.
// The loop waits for a user event, and its read is queued behind it before the event is set:
// on a CPU device the loop's groups take every core, so a read queued after the launch could
// wait for the queue's next wake-up after the loop had ended.
BlockedNetwork::ResidentOutcome BlockedNetwork::SolveResident() {
  if (resident_launched_) throw std::logic_error("the device solve loop runs once a network");
  resident_launched_ = true;
  cl::UserEvent gate(runtime_.context());
  const std::vector<cl::Event> after_gate{gate};
  std::vector<float> result_data(4 + resident_checks_ + 2 * slot_count_);
  cl::Event read;
  cl::Event* read_event = &read;
  try {
    queue_.enqueueNDRangeKernel(resident_loop_, cl::NullRange,
                                cl::NDRange(static_cast<std::size_t>(resident_groups_)),
                                cl::NDRange(1), &after_gate, Record("solve_blocked_resident"));
    ++launches_;
    if (profile_) read_event = Record("read result");
    queue_.enqueueReadBuffer(resident_result_, CL_FALSE, 0, sizeof(float) * result_data.size(),
                             result_data.data(), nullptr, read_event);
    queue_.flush();
  } catch (...) {
    gate.setStatus(CL_COMPLETE);  // a loop left waiting would hold up the queue for good
    throw;
  }
  gate.setStatus(CL_COMPLETE);
  read_event->wait();
  ++blocking_reads_;
  cl_int outcome[4];
  std::memcpy(outcome, result_data.data(), sizeof outcome);  // ints in float bits
  ResidentOutcome result;
  result.groups = resident_groups_;
  result.steps = outcome[0];
  result.converged = outcome[1] != 0;
  result.stop_parity = outcome[2] != 0 ? 1 : 0;
  const auto trace_begin = result_data.begin() + 4;
  const auto n_trace =
      std::min<std::size_t>(resident_checks_, static_cast<std::size_t>(std::max(outcome[3], 0)));
  result.energy_trace.assign(trace_begin, trace_begin + static_cast<std::ptrdiff_t>(n_trace));
  const auto state_begin = trace_begin + static_cast<std::ptrdiff_t>(resident_checks_);
  const auto n_slots = static_cast<std::ptrdiff_t>(slot_count_);
  result.state.V[result.stop_parity].assign(state_begin, state_begin + n_slots);
  result.state.u[result.stop_parity].assign(state_begin + n_slots, state_begin + 2 * n_slots);
  return result;
}

void BlockedNetwork::Solve(const DynamicsOptions& dynamics, std::vector<SolveReport>* reports) {
  if (resident_) {
    SolveOnDevice(dynamics, reports);
  } else {
    SolveOnHost(dynamics, reports);
  }
}

// One fused launch a step (plus column sums for feature networks); the energy is read every
// energy_interval steps. A network that stops at step s keeps its state V_s in the buffer the
// step read from: its rows are never written again, so it is read back from there.
void BlockedNetwork::SolveOnHost(const DynamicsOptions& dynamics,
                                 std::vector<SolveReport>* reports) {
  const std::size_t n = reports->size();
  Clock::time_point start;
  const double weights_ms = BuildWeightsThenStartSolve(*this, [&] { BuildBlocks(); }, &start);
  std::vector<int> active(n, 1), stable(n, 0), stop_parity(n, 0);
  std::vector<double> last_energy(n, 0.0);
  std::size_t n_active = n;
  int parity = 0;
  for (int step = 0;; ++step) {
    const bool check = step % dynamics.energy_interval == 0 || step == dynamics.max_steps;
    Step(parity, check);
    if (check) {
      const std::vector<int> before = active;
      std::vector<float> energies;
      std::vector<int> changes;
      CheckState(dynamics, &energies, &changes);
      const bool changed = CheckConvergence(step, energies, changes, rows_per_network(),
                                            dynamics, reports, &active, &last_energy, &stable,
                                            &n_active);
      for (std::size_t p = 0; p < n; ++p) {
        if (before[p] && !active[p]) stop_parity[p] = parity;
      }
      if (n_active == 0) break;
      if (changed) SetActive(active);
    }
    parity = 1 - parity;
  }
  std::vector<float> final_V, final_u;
  ReadBlockedState(stop_parity, &final_V, &final_u);
  FinishReports(final_V, final_u, net_, weights_ms, MillisecondsSince(start), reports);
}

// The whole loop on the device (solve_blocked_resident): one launch and one read; the report as
// SolveOnHost's (the same checks at the same steps).
void BlockedNetwork::SolveOnDevice(const DynamicsOptions& dynamics,
                                   std::vector<SolveReport>* reports) {
  Clock::time_point start;
  const double weights_ms = BuildWeightsThenStartSolve(*this, [&] { BuildBlocks(); }, &start);
  const ResidentOutcome outcome = SolveResident();
  SolveReport& report = reports->front();
  const int interval = std::max(dynamics.energy_interval, 1);
  std::size_t check = 0;
  for (int step = 0; step <= outcome.steps && check < outcome.energy_trace.size(); ++step) {
    if (step % interval != 0 && step != dynamics.max_steps) continue;
    report.energy_trace.push_back(outcome.energy_trace[check++]);
    report.energy_trace_iterations.push_back(step);
  }
  if (!report.energy_trace.empty()) {
    report.energy_initial = report.energy_trace.front();
    report.energy_final = report.energy_trace.back();
  }
  report.iterations = outcome.steps;
  report.converged = outcome.converged;
  report.solve_groups = outcome.groups;
  std::vector<float> final_V, final_u;
  StateByNeuron({outcome.stop_parity}, outcome.state, &final_V, &final_u);
  FinishReports(final_V, final_u, net_, weights_ms, MillisecondsSince(start), reports);
}

}  // namespace hnnstereo::hnn::device
