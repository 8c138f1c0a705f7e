#include "host/opencl_engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "host/hopfield_energy.h"
#include "common/timing.h"

namespace hnnstereo::hnn {
namespace {

using Clock = std::chrono::steady_clock;

using common::MillisecondsSince;

constexpr int kLocalSize = 64;  // power of two, for segment_sum; PoCL vectorises across it
// The fused step kernels' `check` argument (STEP_BLOCKED_PARAMS in kernels/hopfield.cl: the
// network's 20, the state's 5, decisions and changes); the group step's local buffer follows.
constexpr cl_uint kStepCheckArg = 27;

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

// A read-only copy of `data` on the device without a host copy first (an empty vector gives one
// zero element); the OpenCL call takes a non-const pointer to the data it only reads.
template <typename T>
cl::Buffer MakeReadOnlyBuffer(const cl::Context& context, const std::vector<T>& data) {
  const T zero{};
  const T* source = data.empty() ? &zero : data.data();
  return cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                    sizeof(T) * std::max<std::size_t>(data.size(), 1), const_cast<T*>(source));
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
  // W = o C / (C - 1), which is kResidentMaxStepBytes at C = 2 (measured there).
  if (compute_units <= 1) return std::numeric_limits<double>::infinity();
  const double c = static_cast<double>(compute_units);
  return kResidentMaxStepBytes * c / (2.0 * (c - 1.0));
}

std::vector<int> ResidentRanges(const std::vector<int>& neighbour_offsets, int n_rows, int ranges) {
  // A row's cost in blocks: its neighbour blocks, and its finish (the uniqueness term, the
  // activation, the energy term: about eight blocks' time on the 2-core VM).
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

namespace {

// A batch of networks on the device: the combined layout, its buffers and the kernels.
class DeviceNetwork {
 public:
  DeviceNetwork(ocl::Runtime& runtime, const ProblemBatch& problems, const EnergyOptions& energy,
                const DynamicsOptions& dynamics, std::size_t memory_budget_bytes,
                const OpenClEngineOptions& engine = {WeightStorage::kCsr, 0})
      : runtime_(runtime),
        profile_(engine.profile),
        queue_(engine.profile ? cl::CommandQueue(runtime.context(), runtime.device(),
                                                 CL_QUEUE_PROFILING_ENABLE)
                              : runtime.queue()) {
    if (auto error = energy.Check(); !error.empty()) throw std::invalid_argument(error);
    if (auto error = dynamics.Check(); !error.empty()) throw std::invalid_argument(error);
    Combine(problems, energy, dynamics, memory_budget_bytes);
    storage_ = ResolveStorage(engine.storage);
    if (storage_ == WeightStorage::kCsr) {
      Upload(energy, dynamics);
    } else {
      UploadBlocked(energy, dynamics, engine, memory_budget_bytes);
    }
  }

  WeightStorage storage() const { return storage_; }
  const std::vector<int>& rows_per_network() const { return rows_per_network_; }

  // Rows whose decision changed since the last call, per network (kDecisions stop rule; empty
  // otherwise). `parity` < 0: the CSR state u; else the blocked state buffer the step read.
  // The row blocks' step made the check itself (Step(parity, true)); CSR launches row_decisions.
  std::vector<int> DecisionChanges(const DynamicsOptions& dynamics, int parity) {
    if (dynamics.stop_rule != DynamicsOptions::StopRule::kDecisions) return {};
    std::vector<int> changes(static_cast<std::size_t>(n_networks()), 0);
    if (parity < 0) {
      queue_.enqueueWriteBuffer(changes_, CL_FALSE, 0, sizeof(int) * changes.size(),
                                changes.data());
      Launch(decisions_csr_, decision_range_, local_);
      ++launches_;
    }
    queue_.enqueueReadBuffer(changes_, CL_TRUE, 0, sizeof(int) * changes.size(), changes.data(),
                             nullptr, Record("read decision changes"));
    ++blocking_reads_;
    return changes;
  }
  // Enqueues `kernel`; with profiling on, keeps its event under the kernel's name.
  void Launch(cl::Kernel& kernel, const cl::NDRange& global, const cl::NDRange& local) {
    cl::Event* event = nullptr;
    if (profile_) event = Record(kernel.getInfo<CL_KERNEL_FUNCTION_NAME>());
    queue_.enqueueNDRangeKernel(kernel, cl::NullRange, global, local, nullptr, event);
  }
  // With profiling on, the slot for the event of the next command named `what`; else nullptr.
  cl::Event* Record(std::string what) {
    if (!profile_) return nullptr;
    events_.emplace_back(std::move(what), cl::Event());
    return &events_.back().second;
  }
  // Commands from here on count as the solve's (the ones before as the weight build's).
  void StartSolveProfile() { solve_first_event_ = events_.size(); }
  // Device time per command name from the profiling events (CL_PROFILING_COMMAND_START/END),
  // build and solve apart; empty without profiling. Call after Finish().
  std::vector<KernelTime> ProfiledTimes() const {
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
  int launches() const { return launches_; }
  int blocking_reads() const { return blocking_reads_; }

  // The bytes one step reads under each layout's model: CSR reads every weight (4 B), the
  // neighbour lists per neuron and V[b] per connection (gathered, mostly from cache: counted
  // once per neuron); blocked reads every block (4 or 2 B a slot pair), one neighbour index per
  // block and V of each neighbour row (ROW_PAD floats, from cache: counted once per row; a
  // block is BLOCK_COLS x ROW_PAD slots, kernels/hopfield.cl);
  // on the fly reads no weights, only V of each neighbour row and the per-slot data. Both row
  // layouts also move, every step, 20 B a slot (V and u read, V and u written, the bias read)
  // and 12 B a row (its neuron count and neighbour offset read, its energy term written). The
  // bias and the row terms were left out before (16 B a slot, no row term: a step's bytes
  // undercounted by a tenth on a 1,000-feature network, by 1 % on all of Teddy).
  double StepBytes() const {
    const NetworkLayout& L = net_.layout;
    const double neurons = L.n_neurons, rows = L.n_rows;
    const double neighbours = static_cast<double>(L.feature_neighbours.size());
    switch (storage_) {
      case WeightStorage::kCsr:
        return 4.0 * static_cast<double>(L.n_connections()) + 12.0 * neurons + 8.0 * neurons;
      case WeightStorage::kBlockedFloat:
      case WeightStorage::kBlockedHalf: {
        const double slot_pair = storage_ == WeightStorage::kBlockedHalf ? 2.0 : 4.0;
        return slot_pair * neighbours * row_pad_ * block_cols_ + 4.0 * neighbours +
               20.0 * rows * row_pad_ + 12.0 * rows;
      }
      default:  // on the fly: also each slot's right point and correlation (12 B)
        return 4.0 * neighbours + 32.0 * rows * row_pad_ + 12.0 * rows;
    }
  }

  void BuildBlocks() {
    if (storage_ == WeightStorage::kOnTheFly) return;
    Launch(build_blocks_, build_range_, local_);
    ++launches_;
  }
  // One fused step from state buffer `parity` into the other; column sums first when the
  // network has column uniqueness. `check`: a convergence check follows, so under the
  // kDecisions rule the step also counts the rows whose decision changed (decide_row).
  void Step(int parity, bool check) {
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
  // The convergence check of the blocked solve in one host round trip: per-network energies
  // (segment_sum over the row energies the step wrote) and, under the kDecisions rule, the rows
  // whose decision changed, which the step before counted (Step(parity, true)). The energies
  // are read without blocking; the blocking read of the changes behind them on the in-order
  // queue waits for both.
  void CheckState(const DynamicsOptions& dynamics, int parity, std::vector<float>* energies,
                  std::vector<int>* changes) {
    const bool decisions = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
    energies->assign(static_cast<std::size_t>(n_networks()), 0.0f);
    Launch(segment_sum_, segment_range_, local_);
    ++launches_;
    queue_.enqueueReadBuffer(network_energy_, decisions ? CL_FALSE : CL_TRUE, 0,
                             sizeof(float) * energies->size(), energies->data(), nullptr,
                             Record("read energies"));
    if (!decisions) ++blocking_reads_;
    *changes = DecisionChanges(dynamics, parity);  // empty unless kDecisions
  }
  // The row blocks' state buffers (V and u of both parities, by slot).
  struct BlockedState {
    std::vector<float> V[2], u[2];
  };
  // Enqueues reads of the state buffers b with needed[b], without blocking.
  void EnqueueStateReads(const bool (&needed)[2], BlockedState* state) {
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
  // read costs a round trip to the device's threads (tens of microseconds on PoCL, a tenth of
  // a 2,000-feature solve).
  void ReadBlockedState(const std::vector<int>& stop_parity, std::vector<float>* V,
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
  void StateByNeuron(const std::vector<int>& stop_parity, const BlockedState& state,
                     std::vector<float>* V, std::vector<float>* u) const {
    const std::vector<float>* Vs = state.V;
    const std::vector<float>* us = state.u;
    const NetworkLayout& L = net_.layout;
    V->assign(static_cast<std::size_t>(L.n_neurons), 0.0f);
    u->assign(static_cast<std::size_t>(L.n_neurons), 0.0f);
    for (int i = 0; i < L.n_rows; ++i) {
      const int b = stop_parity[static_cast<std::size_t>(row_network_[static_cast<std::size_t>(i)])];
      for (int a = L.row_offsets[static_cast<std::size_t>(i)];
           a < L.row_offsets[static_cast<std::size_t>(i) + 1]; ++a) {
        const std::size_t slot = static_cast<std::size_t>(i) * static_cast<std::size_t>(row_pad_) +
                                 static_cast<std::size_t>(a - L.row_offsets[static_cast<std::size_t>(i)]);
        (*V)[static_cast<std::size_t>(a)] = Vs[b][slot];
        (*u)[static_cast<std::size_t>(a)] = us[b][slot];
      }
    }
  }

  const CombinedNetwork& network() const { return net_; }
  int n_networks() const { return static_cast<int>(net_.network_offsets.size()) - 1; }

  void BuildWeights() {
    Launch(build_weights_, neuron_range_, local_);
  }
  // line_sums then neuron_field: the field and energy terms of the current state.
  void Field() {
    Launch(line_sums_, line_range_, local_);
    Launch(neuron_field_, neuron_range_, local_);
  }
  void Euler() { Launch(neuron_euler_, neuron_range_, local_); }
  // Per-network energies of the state the last Field() saw (blocking).
  std::vector<float> Energies() {
    std::vector<float> energies(static_cast<std::size_t>(n_networks()));
    Launch(segment_sum_, segment_range_, local_);
    queue_.enqueueReadBuffer(network_energy_, CL_TRUE, 0, sizeof(float) * energies.size(),
                             energies.data(), nullptr, Record("read energies"));
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
  int MaxRowCount() const {
    const NetworkLayout& L = net_.layout;
    int most = 0;
    for (int i = 0; i < L.n_rows; ++i) {
      most = std::max(most, L.row_offsets[static_cast<std::size_t>(i) + 1] -
                                L.row_offsets[static_cast<std::size_t>(i)]);
    }
    return most;
  }

  // Auto: half-precision row blocks when padding every row to ROW_PAD slots at most doubles the
  // stored weights (the disparity network's top-K rows, the dense network), else CSR. Measured
  // on Teddy, all edges (docs/engine.md): half blocks 374 ms whole match, float 447 ms, CSR
  // 865 ms; the same matches.
  // On a GPU also only rows of at most 8 slots: measured on an H200 (docs/engine.md, "On a
  // GPU"), the dense 60 x 60 network's 60-slot blocks took 142-207 ms to solve against 4.2 ms
  // for CSR, whose one work-item per neuron keeps the card busy where 60 rows cannot.
  WeightStorage ResolveStorage(WeightStorage asked) {
    const int most = MaxRowCount();
    row_pad_ = std::max(4, (most + 3) / 4 * 4);
    // Rows of at most 3 neurons (hnn-default's K = 3) store 3 x 4 blocks (BLOCK_COLS).
    block_cols_ = row_pad_ == 4 && most <= 3 ? 3 : row_pad_;
    const NetworkLayout& L = net_.layout;
    const double blocked =
        static_cast<double>(L.feature_neighbours.size()) * row_pad_ * block_cols_;
    if (asked != WeightStorage::kAuto) return asked;
    if (runtime_.is_gpu() && row_pad_ > 8) return WeightStorage::kCsr;
    return blocked <= 2.0 * std::max<double>(1.0, static_cast<double>(L.n_connections()))
               ? WeightStorage::kBlockedHalf
               : WeightStorage::kCsr;
  }

  void UploadBlocked(const EnergyOptions& energy, const DynamicsOptions& dynamics,
                     const OpenClEngineOptions& engine, std::size_t memory_budget_bytes) {
    const NetworkLayout& L = net_.layout;
    int rows_per_item = engine.rows_per_item;
    const cl::Context& context = runtime_.context();
    const int weights_mode = storage_ == WeightStorage::kBlockedFloat ? 0
                             : storage_ == WeightStorage::kBlockedHalf ? 1 : 2;
    const std::size_t n_blocks = L.feature_neighbours.size();
    const std::size_t block_bytes =
        weights_mode == 2 ? 0
                          : n_blocks * static_cast<std::size_t>(row_pad_ * block_cols_) *
                                (weights_mode == 1 ? 2u : 4u);
    if (block_bytes > memory_budget_bytes) {
      throw std::runtime_error(
          "the row-blocked weights need " + std::to_string(block_bytes >> 20) +
          " MB, over the memory budget of " + std::to_string(memory_budget_bytes >> 20) +
          " MB; use tighter gating, --max-features, or on-the-fly weights");
    }
    const std::string options = KernelBuildOptions(energy, dynamics) +
                                " -DROW_PAD=" + std::to_string(row_pad_) +
                                " -DBLOCK_COLS=" + std::to_string(block_cols_) +
                                " -DWEIGHTS=" + std::to_string(weights_mode);
    const cl::Program& program = runtime_.Program("hopfield", options);
    slot_count_ = std::max<std::size_t>(1, static_cast<std::size_t>(L.n_rows) *
                                               static_cast<std::size_t>(row_pad_));
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
      for (int k = 0; k < row_pad_; ++k) {
        const std::size_t slot = ui * static_cast<std::size_t>(row_pad_) + static_cast<std::size_t>(k);
        // Padded slots: finite data (the left point itself), V = 0, never written.
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
    // Columns as padded slots (feature-vs-feature networks).
    host_blocked_.column_slots.clear();
    for (int a : L.column_neurons) {
      const int i = L.neuron_row[static_cast<std::size_t>(a)];
      host_blocked_.column_slots.push_back(i * row_pad_ + a - L.row_offsets[static_cast<std::size_t>(i)]);
    }
    host_blocked_.network_row_offsets = {0};
    for (std::size_t p = 0; p + 1 < net_.network_offsets.size(); ++p) {
      int rows = host_blocked_.network_row_offsets.back();
      while (rows < L.n_rows && L.row_offsets[static_cast<std::size_t>(rows)] < net_.network_offsets[p + 1]) ++rows;
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
    // Every block is written by the build before a step reads it: a reused buffer will do.
    blocks_ = runtime_.ScratchBuffer("weight blocks", block_bytes);

    const EnergyParams params = Params(energy);
    const bool gpu = runtime_.is_gpu();
    const bool per_weight =
        engine.block_build == OpenClEngineOptions::BlockBuild::kPerWeight ||
        (engine.block_build == OpenClEngineOptions::BlockBuild::kAuto && gpu);
    if (weights_mode != 2 && per_weight) {
      // A GPU: one work-item per weight (build_weight_blocks_flat); block t's row from block_row.
      std::vector<int> block_row(std::max<std::size_t>(n_blocks, 1), 0);
      for (int i = 0; i < L.n_rows; ++i) {
        for (int t = L.feature_neighbour_offsets[static_cast<std::size_t>(i)];
             t < L.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]; ++t) {
          block_row[static_cast<std::size_t>(t)] = i;
        }
      }
      block_row_ = MakeBuffer(context, ro, block_row);
      const auto n_weights = static_cast<cl_long>(n_blocks) * row_pad_ * block_cols_;
      build_blocks_ = cl::Kernel(program, "build_weight_blocks_flat");
      SetArgs(build_blocks_, n_weights, block_row_, neighbours_, row_count_, slot_right_,
              slot_correlation_, feature_point_, params, blocks_);
      build_range_ = RoundedRange(static_cast<std::size_t>(std::max<cl_long>(n_weights, 1)));
    } else if (weights_mode != 2) {
      // A CPU device: one work-item per row (measured faster here, docs/engine.md); the
      // default objective has an explicitly vectorised build.
      const bool vec4 = energy.objective == Objective::kGeometrySimilarity &&
                        !energy.distance_attenuation;
      build_blocks_ = cl::Kernel(program, vec4 ? "build_weight_blocks_vec4" : "build_weight_blocks");
      SetArgs(build_blocks_, static_cast<cl_int>(L.n_rows), row_count_, neighbour_offsets_,
              neighbours_, slot_right_, slot_correlation_, feature_point_, params, blocks_);
      build_range_ = RoundedRange(rows);
    }
    // Rows per work-item: a GPU wants one row per work-item in work-groups of 64; on a CPU
    // device PoCL runs each work-group of one work-item as a loop over its rows with the
    // explicit vector loads (no cross-work-item vectorisation to undo).
    // A GPU (or BlockStep::kRowPerGroup): one work-group of kStepGroup lanes per row instead.
    const bool row_per_group =
        engine.block_step == OpenClEngineOptions::BlockStep::kRowPerGroup ||
        (engine.block_step == OpenClEngineOptions::BlockStep::kAuto && gpu);
    if (row_per_group) rows_per_item = 1;
    if (rows_per_item <= 0) rows_per_item = gpu ? 1 : std::clamp(L.n_rows / 256, 1, 64);
    const std::size_t items = (rows + static_cast<std::size_t>(rows_per_item) - 1) /
                              static_cast<std::size_t>(rows_per_item);
    const std::size_t step_local = row_per_group ? kStepGroup : gpu ? 64 : 1;
    step_local_ = cl::NDRange(step_local);
    step_range_ = row_per_group ? cl::NDRange(rows * kStepGroup)
                                : cl::NDRange((items + step_local - 1) / step_local * step_local);
    const cl_float two_B = static_cast<cl_float>(2.0 * energy.B);
    const cl_float two_C = static_cast<cl_float>(L.column_uniqueness ? 2.0 * energy.C : 0.0);
    // The decisions check is made by the step itself (decide_row), into these buffers.
    SetUpDecisions(program, nullptr);
    by_decisions_ = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
    for (int b = 0; b < 2; ++b) {
      step_[b] = cl::Kernel(program, row_per_group ? "neuron_step_blocked_group"
                                                   : "neuron_step_blocked");
      SetArgs(step_[b], static_cast<cl_int>(L.n_rows), static_cast<cl_int>(rows_per_item),
              row_count_, neighbour_offsets_, neighbours_, blocks_, slot_right_, slot_correlation_,
              feature_point_, params, slot_bias_, slot_column_, column_sums_, two_B, two_C,
              network_of_row_, active_, static_cast<cl_float>(dynamics.time_step),
              static_cast<cl_float>(1.0 / dynamics.tau), static_cast<cl_float>(dynamics.alpha),
              V_state_[b], u_state_[b], V_state_[1 - b], u_state_[1 - b], row_energy_, decisions_,
              changes_, cl_int{0});
      if (row_per_group) {  // the lanes' partial inputs: kStepGroup x ROW_PAD floats
        step_[b].setArg(kStepCheckArg + 1,
                        cl::Local(sizeof(float) * static_cast<std::size_t>(kStepGroup) *
                                  static_cast<std::size_t>(row_pad_)));
      }
      column_sums_blocked_[b] = cl::Kernel(program, "column_sums_blocked");
      SetArgs(column_sums_blocked_[b], static_cast<cl_int>(L.n_columns), column_offsets_,
              column_slots_, V_state_[b], column_sums_);
    }
    segment_sum_ = cl::Kernel(program, "segment_sum");
    SetArgs(segment_sum_, network_offsets_, row_energy_, network_energy_,
            cl::Local(sizeof(float) * kLocalSize));
    row_range_ = RoundedRange(rows);
    column_range_ = RoundedRange(static_cast<std::size_t>(std::max(L.n_columns, 1)));
    segment_range_ = cl::NDRange(static_cast<std::size_t>(n_networks()) * kLocalSize);

    // The solve loop on the device (OpenClEngineOptions::SolveLoop): one network, the per-item
    // step (not the GPU's group step).
    const bool can_reside = n_networks() == 1 && !row_per_group;
    const auto units = runtime_.device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
    // The device loop's work-groups: one per core, each with its share of the rows.
    int groups = engine.resident_groups;
    if (groups <= 0) {
      groups = gpu ? 1 : std::clamp(L.n_rows / kResidentRowsPerGroup, 1, static_cast<int>(units));
    }
    // One on a GPU, whatever was asked: OpenCL 1.2 does not make one work-group's global writes
    // visible to another's, and on an H200 (NVIDIA's driver) several groups read stale state -
    // other steps and energies (sparse-5000: 29 and 301 steps with 32 and 132 groups against
    // 19) - where on a CPU device they are bit for bit one group's run (docs/engine.md).
    if (gpu) groups = 1;
    // kAuto on a CPU device: with a group per core the device loop steps as the host loop's
    // launches do, without their launch and round trips, so it takes every network it can
    // (Teddy 5,000 features: 2.2-2.3 ms against 3.2-3.3 on the host loop; all of Teddy the same
    // either way). With one group, stored blocks whose step fits one core's cache only: on the
    // fly computes every weight each step and needs the cores (Teddy 2,000 features: 49.7 ms
    // on the host loop against 86.2 ms in one launch of one work-item).
    const bool spread = groups > 1 && L.n_rows >= 2 * kResidentRowsPerGroup;
    resident_ =
        can_reside && (engine.solve_loop == OpenClEngineOptions::SolveLoop::kDevice ||
                       (engine.solve_loop == OpenClEngineOptions::SolveLoop::kAuto && !gpu &&
                        (spread || (storage_ != WeightStorage::kOnTheFly &&
                                    StepBytes() <= ResidentMaxStepBytes(units)))));
    if (resident_) {
      const auto n_checks = static_cast<std::size_t>(
          std::max(dynamics.max_steps, 0) / std::max(dynamics.energy_interval, 1) + 2);
      // The outcome, the energy trace and the final V and u: solve_blocked_resident's `result`.
      resident_result_ =
          cl::Buffer(context, CL_MEM_READ_WRITE, sizeof(float) * (4 + n_checks + 2 * slot_count_));
      resident_checks_ = n_checks;
      resident_groups_ = groups;
      // The ranges of rows the groups take (kResidentRangesPerGroup each).
      std::vector<int> range_rows =
          ResidentRanges(L.feature_neighbour_offsets, L.n_rows, groups * kResidentRangesPerGroup);
      resident_ranges_ = static_cast<int>(range_rows.size()) - 1;
      range_rows_ = MakeBuffer(context, CL_MEM_READ_ONLY, range_rows);
      range_changes_ = cl::Buffer(context, CL_MEM_READ_WRITE,
                                  sizeof(cl_int) * static_cast<std::size_t>(resident_ranges_));
      // The claims and the loop's control as the kernel expects them at its launch, made with
      // the buffers: no fills before the solve (a network's loop is launched once).
      std::vector<cl_int> no_claims(static_cast<std::size_t>(resident_ranges_), -1);
      range_claims_ = MakeBuffer(context, CL_MEM_READ_WRITE, no_claims);
      std::vector<cl_int> control(4, 0);
      loop_control_ = MakeBuffer(context, CL_MEM_READ_WRITE, control);
      // With column uniqueness, ranges of columns for the column sums of every step.
      std::vector<int> column_ranges{0, 0};
      if (L.column_uniqueness && L.n_columns > 0) {
        column_ranges =
            ResidentRanges(L.column_offsets, L.n_columns, groups * kResidentRangesPerGroup);
      }
      resident_column_ranges_ =
          L.column_uniqueness ? static_cast<int>(column_ranges.size()) - 1 : 0;
      column_range_columns_ = MakeBuffer(context, CL_MEM_READ_ONLY, column_ranges);
      std::vector<cl_int> no_column_claims(column_ranges.size(), -1);
      column_claims_ = MakeBuffer(context, CL_MEM_READ_WRITE, no_column_claims);
      const bool by_decisions = dynamics.stop_rule == DynamicsOptions::StopRule::kDecisions;
      resident_loop_ = cl::Kernel(program, "solve_blocked_resident");
      SetArgs(resident_loop_, static_cast<cl_int>(L.n_rows), static_cast<cl_int>(rows_per_item),
              row_count_, neighbour_offsets_, neighbours_, blocks_, slot_right_, slot_correlation_,
              feature_point_, params, slot_bias_, slot_column_, column_sums_, two_B, two_C,
              network_of_row_, active_, static_cast<cl_float>(dynamics.time_step),
              static_cast<cl_float>(1.0 / dynamics.tau), static_cast<cl_float>(dynamics.alpha),
              V_state_[0], u_state_[0], V_state_[1], u_state_[1], row_energy_, decisions_,
              range_changes_, static_cast<cl_int>(dynamics.max_steps),
              static_cast<cl_int>(std::max(dynamics.energy_interval, 1)),
              static_cast<cl_int>(dynamics.stable_checks), static_cast<cl_int>(by_decisions),
              static_cast<cl_float>(dynamics.energy_tolerance * std::max(1, L.n_neurons)),
              static_cast<cl_float>(dynamics.decision_tolerance * std::max(1, L.n_rows)),
              resident_result_, static_cast<cl_int>(n_checks), range_rows_,
              static_cast<cl_int>(resident_ranges_), range_claims_, loop_control_, column_offsets_,
              column_slots_, column_sums_, column_range_columns_,
              static_cast<cl_int>(resident_column_ranges_), column_claims_);
    }
  }

 public:
  // Whether the blocked solve loop runs on the device (solve_blocked_resident).
  bool resident() const { return resident_; }
  struct ResidentOutcome {
    int steps = 0;
    bool converged = false;
    int stop_parity = 0;
    std::vector<float> energy_trace;  // the energy at every check
    int groups = 1;                   // the work-groups that ran it
    BlockedState state;               // V and u as it stopped, in state.V/u[stop_parity]
  };
  // The whole solve in one launch, then one blocking read of its result (outcome, trace and the
  // state it stopped on). The claims and control are as the buffers were made: once a network.
  ResidentOutcome SolveResident() {
    if (resident_launched_) throw std::logic_error("the device solve loop runs once a network");
    resident_launched_ = true;
    // The loop waits for a user event, and its read is queued behind it before the event is set:
    // on a CPU device the loop's groups take every core while they run, so a host thread that
    // queued the read after the launch often got no core to do it on until the loop had ended,
    // and the read then waited for the queue's next wake-up (PoCL profiling events, Teddy's
    // 1,000-feature network: 25-45 us from the loop's end to the read's start, in a 0.4 ms solve).
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

 private:
  // Buffers of the kDecisions stop rule, and for CSR (`u_csr`: its state u) the row_decisions
  // kernel over rows given as (first neuron, count); the row blocks' step decides itself.
  void SetUpDecisions(const cl::Program& program, const cl::Buffer* u_csr) {
    const NetworkLayout& L = net_.layout;
    const cl::Context& context = runtime_.context();
    std::vector<int> row_size(static_cast<std::size_t>(std::max(L.n_rows, 1)), 0);
    std::vector<int> network_of_row(row_size.size(), 0);
    rows_per_network_.assign(static_cast<std::size_t>(n_networks()), 0);
    for (int i = 0; i < L.n_rows; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      row_size[ui] = L.row_offsets[ui + 1] - L.row_offsets[ui];
      // The network of a row: the first network whose neuron range ends beyond the row start.
      int p = 0;
      while (p + 1 < n_networks() && L.row_offsets[ui] >= net_.network_offsets[static_cast<std::size_t>(p) + 1]) ++p;
      network_of_row[ui] = p;
      ++rows_per_network_[static_cast<std::size_t>(p)];
    }
    std::vector<int> decisions(row_size.size(), -2);
    std::vector<int> changes(static_cast<std::size_t>(n_networks()), 0);
    decisions_ = MakeBuffer(context, CL_MEM_READ_WRITE, decisions);
    changes_ = MakeBuffer(context, CL_MEM_READ_WRITE, changes);
    zero_changes_.assign(changes.size(), 0);
    if (!u_csr) return;
    std::vector<int> row_first(L.row_offsets.begin(), L.row_offsets.end() - (L.n_rows > 0 ? 1 : 0));
    row_first.resize(row_size.size(), 0);
    row_first_ = MakeBuffer(context, CL_MEM_READ_ONLY, row_first);
    row_size_ = MakeBuffer(context, CL_MEM_READ_ONLY, row_size);
    decision_network_ = MakeBuffer(context, CL_MEM_READ_ONLY, network_of_row);
    decisions_csr_ = cl::Kernel(program, "row_decisions");
    SetArgs(decisions_csr_, static_cast<cl_int>(L.n_rows), row_first_, row_size_, decision_network_,
            active_, *u_csr, decisions_, changes_);
    decision_range_ = RoundedRange(row_size.size());
  }

  static EnergyParams Params(const EnergyOptions& energy) {
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

 public:
  // The network a row belongs to, for the batch.
  int RowNetwork(int i) const { return row_network_[static_cast<std::size_t>(i)]; }
  void SetActiveBlocked(const std::vector<int>& active) {
    queue_.enqueueWriteBuffer(active_, CL_TRUE, 0, sizeof(int) * active.size(), active.data());
  }

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
      NetworkLayout part = BuildLayout(problem, energy, memory_budget_bytes);
      total_bytes += EstimateSize(part).total_bytes;
      CheckMemoryBudget(total_bytes, memory_budget_bytes, "the batch of networks", part);
      for (int a = 0; a < part.n_neurons; ++a) {
        const Candidate& c = problem.candidates[static_cast<std::size_t>(a)];
        const Eigen::Vector2f& left = problem.left_points[static_cast<std::size_t>(c.left)];
        net_.left_point.push_back({{left.x(), left.y()}});
        net_.right_point.push_back({{c.right_point.x(), c.right_point.y()}});
        net_.correlation.push_back(c.correlation);
        net_.bias.push_back(
            static_cast<float>(Bias(c.epipolar_distance_px, part.column_uniqueness, energy)));
        net_.network_of_neuron.push_back(static_cast<int>(p));
      }
      for (const Eigen::Vector2f& point : problem.left_points) {
        net_.feature_point.push_back({{point.x(), point.y()}});
      }
      net_.connections.push_back(part.n_connections());
      // Column uniqueness is a property of the network kind; a batch must agree.
      if (p == 0) L.column_uniqueness = part.column_uniqueness;
      if (part.column_uniqueness != L.column_uniqueness) {
        throw std::invalid_argument(
            "a batch must not mix feature-vs-feature and feature-vs-disparity networks");
      }
      if (p == 0) {
        // The first network's layout as it is (nothing to offset): moved, not copied element
        // by element (0.5 ms of a 5,000-feature match; every solve but a batch has one).
        L = std::move(part);
      } else {
        AppendLayout(part);
      }
      net_.network_offsets.push_back(L.n_neurons);
      AppendInitialState(problem, dynamics);
    }
  }
  // A later network's layout after the ones before it: its neurons, rows, columns and
  // neighbour lists offset by theirs.
  void AppendLayout(const NetworkLayout& part) {
    NetworkLayout& L = net_.layout;
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
  // V and u of the network's initial state, after those of the networks before it.
  void AppendInitialState(const MatchingProblem& problem, const DynamicsOptions& dynamics) {
    for (double v : InitialActivations(problem, dynamics)) {
      net_.V.push_back(static_cast<float>(v));
      net_.u.push_back(static_cast<float>(dynamics.activation == Activation::kContinuous
                                              ? InverseActivation(v, dynamics.alpha)
                                              : v - 0.5));
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
    line_range_ = RoundedRange(static_cast<std::size_t>(L.n_rows) + static_cast<std::size_t>(L.n_columns));
    segment_range_ = cl::NDRange(static_cast<std::size_t>(n_networks()) * kLocalSize);
    SetUpDecisions(program, &u_);
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
  const bool profile_;
  cl::CommandQueue queue_;  // the runtime's, or with CL_QUEUE_PROFILING_ENABLE when profiling
  std::vector<std::pair<std::string, cl::Event>> events_;  // profiling: every recorded command
  std::size_t solve_first_event_ = 0;
  CombinedNetwork net_;
  HostCopies host_copies_;
  cl::Buffer neuron_row_, neuron_column_, row_offsets_, column_offsets_, column_neurons_,
      neighbour_offsets_, neighbours_, weight_offsets_, left_point_, right_point_, feature_point_,
      correlation_, bias_, network_of_neuron_, network_offsets_, weights_, V_, u_, field_,
      energy_terms_, row_sums_, column_sums_, active_, network_energy_;
  cl::Kernel build_weights_, line_sums_, neuron_field_, neuron_euler_, segment_sum_;
  cl::NDRange neuron_range_, line_range_, segment_range_;
  const cl::NDRange local_{kLocalSize};

  // Row-blocked state.
  struct HostBlocked {
    std::vector<int> row_count, column_slots, network_row_offsets;
  };
  WeightStorage storage_ = WeightStorage::kCsr;
  int row_pad_ = 4;
  int block_cols_ = 4;  ///< neighbour slots a weight block stores (BLOCK_COLS): row_pad_ or 3
  std::size_t slot_count_ = 1;
  int launches_ = 0, blocking_reads_ = 0;
  HostBlocked host_blocked_;
  std::vector<int> row_network_;
  cl::Buffer row_count_, column_slots_, slot_right_, slot_correlation_, slot_bias_, slot_column_,
      network_of_row_, blocks_, row_energy_, V_state_[2], u_state_[2], block_row_;
  cl::Kernel build_blocks_, step_[2], column_sums_blocked_[2];
  // The solve loop on the device (SolveLoop::kDevice).
  bool resident_ = false;
  std::size_t resident_checks_ = 0;
  bool resident_launched_ = false;
  int resident_groups_ = 1, resident_ranges_ = 1, resident_column_ranges_ = 0;
  cl::Buffer resident_result_, range_rows_, range_changes_, range_claims_, loop_control_,
      column_range_columns_, column_claims_;
  cl::Kernel resident_loop_;
  // kDecisions stop rule.
  std::vector<int> rows_per_network_;
  cl::Buffer row_first_, row_size_, decision_network_, decisions_, changes_;
  cl::Kernel decisions_csr_;
  std::vector<int> zero_changes_;  // written to changes_ before a deciding step (kept alive)
  bool by_decisions_ = false;
  cl::NDRange decision_range_;
  cl::NDRange row_range_, column_range_, step_range_, step_local_{1}, build_range_;

 public:
  const cl::Buffer& field_buffer() const { return field_; }
};

}  // namespace

namespace {

// The convergence bookkeeping shared by both solve loops: records the energy of every active
// network at `step`, and deactivates those whose test passed (thesis: |dE| below the tolerance
// for `stable_checks` consecutive checks) or that reached the step limit. Returns whether any
// network stopped at this check.
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

void Finish(const std::vector<float>& final_V, const std::vector<float>& final_u,
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

// Runs the weight build to completion (its wall time is returned), then starts the solve's
// clock and its share of the profile.
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

// CSR layout: line sums, field and Euler step as three launches a step (the original engine).
void SolveCsr(DeviceNetwork& device, const DynamicsOptions& dynamics,
              std::vector<SolveReport>* reports) {
  const std::size_t n = reports->size();
  Clock::time_point start;
  const double weights_ms = BuildWeightsThenStartSolve(
      device, [&] { device.BuildWeights(); }, &start);
  std::vector<int> active(n, 1), stable(n, 0);
  std::vector<double> last_energy(n, 0.0);
  std::size_t n_active = n;
  for (int step = 0;; ++step) {
    device.Field();
    if (step % dynamics.energy_interval == 0 || step == dynamics.max_steps) {
      const std::vector<float> energies = device.Energies();
      const std::vector<int> changes = device.DecisionChanges(dynamics, -1);
      const bool changed = CheckConvergence(step, energies, changes, device.rows_per_network(),
                                            dynamics, reports, &active, &last_energy, &stable,
                                            &n_active);
      if (n_active == 0) break;
      if (changed) device.SetActive(active);
    }
    device.Euler();
  }
  const std::vector<float> final_V = device.ReadState();
  const std::vector<float> final_u = device.ReadPotential();
  Finish(final_V, final_u, device.network(), weights_ms, MillisecondsSince(start), reports);
}

// Row blocks: one fused launch a step (plus column sums for feature networks); the energy is
// read every energy_interval steps. A network that stops at step s keeps its state V_s in the
// buffer the step read from: its rows are never written again, so it is read back from there.
void SolveBlocked(DeviceNetwork& device, const DynamicsOptions& dynamics,
                  std::vector<SolveReport>* reports) {
  const std::size_t n = reports->size();
  Clock::time_point start;
  const double weights_ms = BuildWeightsThenStartSolve(
      device, [&] { device.BuildBlocks(); }, &start);
  std::vector<int> active(n, 1), stable(n, 0), stop_parity(n, 0);
  std::vector<double> last_energy(n, 0.0);
  std::size_t n_active = n;
  int parity = 0;
  for (int step = 0;; ++step) {
    const bool check = step % dynamics.energy_interval == 0 || step == dynamics.max_steps;
    device.Step(parity, check);
    if (check) {
      const std::vector<int> before = active;
      std::vector<float> energies;
      std::vector<int> changes;
      device.CheckState(dynamics, parity, &energies, &changes);
      const bool changed = CheckConvergence(step, energies, changes, device.rows_per_network(),
                                            dynamics, reports, &active, &last_energy, &stable,
                                            &n_active);
      for (std::size_t p = 0; p < n; ++p) {
        if (before[p] && !active[p]) stop_parity[p] = parity;
      }
      if (n_active == 0) break;
      if (changed) device.SetActiveBlocked(active);
    }
    parity = 1 - parity;
  }
  std::vector<float> final_V, final_u;
  device.ReadBlockedState(stop_parity, &final_V, &final_u);
  Finish(final_V, final_u, device.network(), weights_ms, MillisecondsSince(start), reports);
}

// Row blocks with the whole loop on the device (SolveLoop::kDevice, solve_blocked_resident):
// one launch and one read; the report as SolveBlocked's (the same checks at the same steps).
void SolveBlockedResident(DeviceNetwork& device, const DynamicsOptions& dynamics,
                          std::vector<SolveReport>* reports) {
  Clock::time_point start;
  const double weights_ms = BuildWeightsThenStartSolve(
      device, [&] { device.BuildBlocks(); }, &start);
  const DeviceNetwork::ResidentOutcome outcome = device.SolveResident();
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
  device.StateByNeuron({outcome.stop_parity}, outcome.state, &final_V, &final_u);
  Finish(final_V, final_u, device.network(), weights_ms, MillisecondsSince(start), reports);
}

}  // namespace

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
    const auto network_start = Clock::now();
    DeviceNetwork device(runtime_, problems, energy, dynamics, memory_budget_bytes, options_);
    const double network_ms = MillisecondsSince(network_start);
    const CombinedNetwork& net = device.network();
    for (std::size_t p = 0; p < problems.size(); ++p) {
      reports[p].engine = "opencl";
      reports[p].device = runtime_.description();
      reports[p].n_neurons = net.network_offsets[p + 1] - net.network_offsets[p];
      reports[p].n_connections = net.connections[p];
    }
    if (device.storage() == WeightStorage::kCsr) {
      SolveCsr(device, dynamics, &reports);
    } else if (device.resident()) {
      SolveBlockedResident(device, dynamics, &reports);
    } else {
      SolveBlocked(device, dynamics, &reports);
    }
    device.Finish();
    const std::vector<KernelTime> kernel_times = device.ProfiledTimes();
    for (SolveReport& report : reports) {
      report.kernel_times = kernel_times;  // the batch's, shared
      report.weight_storage = std::string(WeightStorageName(device.storage()));
      if (device.storage() != WeightStorage::kCsr) {
        report.solve_loop = device.resident() ? "device" : "host";
      }
      report.step_bytes = device.StepBytes();
      report.launches = device.launches();
      report.blocking_reads = device.blocking_reads();
      report.network_ms = network_ms;  // the batch's, shared
    }
  } catch (const cl::Error& e) {
    throw ocl::OpenClError(e.what(), e.err());
  }
  return reports;
}

}  // namespace hnnstereo::hnn
