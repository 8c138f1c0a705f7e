// Every kernel against its CPU reference, and the opencl engine against the cpu engine.
// Run under POCL_WORK_GROUP_METHOD=loopvec and =cbs (tests/host/CMakeLists.txt).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <set>

#include "host/cpu_engines.h"
#include "host/decode.h"
#include "host/hopfield_energy.h"
#include "host/opencl_engine.h"
#include "synthetic_problems.h"

namespace hnnstereo::hnn {
namespace {

class OpenClEngineTest : public ::testing::Test {
 protected:
  // One runtime for the whole binary (both suites): its programs, built once per set of build
  // options, serve every test; it lives until the process exits.
  static void SetUpTestSuite() {
    if (runtime_ || !why_not_.empty()) return;
    std::string why_not;
    runtime_ = ocl::Runtime::Create(ocl::DeviceSelection::FromEnvironment(), &why_not).release();
    if (!runtime_) why_not_ = why_not.empty() ? "no device" : why_not;
    const char* method = std::getenv("POCL_WORK_GROUP_METHOD");
    std::printf("OpenCL device: %s; POCL_WORK_GROUP_METHOD=%s\n",
                runtime_ ? runtime_->description().c_str() : why_not.c_str(), method ? method : "(default)");
  }
  void SetUp() override {
    if (!runtime_) GTEST_SKIP() << "no OpenCL device: " << why_not_;
  }
  static ocl::Runtime* runtime_;
  static std::string why_not_;
};
ocl::Runtime* OpenClEngineTest::runtime_ = nullptr;
std::string OpenClEngineTest::why_not_;

// Relative comparisons use the larger of the initial and final energies as the scale, so that a
// network settling near E = 0 is still compared meaningfully.
double EnergyScale(const SolveReport& report) {
  return std::max(std::abs(report.energy_final), std::abs(report.energy_initial));
}

std::vector<int> MatchedNeurons(const MatchingProblem& problem, const SolveReport& report) {
  std::vector<int> neurons;
  for (const DecodedMatch& m : Decode(problem, report.activation, DecodeOptions{}, &report.potential)) {
    neurons.push_back(m.neuron);
  }
  return neurons;
}

TEST_F(OpenClEngineTest, BuildWeightsKernelMatchesTheCpuReference) {
  for (Objective objective : {Objective::kThesis, Objective::kPrinted0, Objective::kPrinted2,
                              Objective::kGeometrySimilarity}) {
    for (bool dense : {false, true}) {
      const MatchingProblem problem = testing::SyntheticProblem(31, 60, 20, dense);
      EnergyOptions energy;
      energy.objective = objective;
      energy.support_radius_px = 15.0;
      energy.distance_attenuation = dense;
      const NetworkLayout layout = BuildLayout(problem, energy);
      const std::vector<double> expected = BuildCompatibilityWeights(problem, layout, energy);
      OpenClEngine engine(*runtime_);
      const std::vector<float> actual = engine.BuildWeights(problem, energy);
      ASSERT_EQ(actual.size(), expected.size());
      double worst = 0.0;
      for (std::size_t t = 0; t < expected.size(); ++t) {
        worst = std::max(worst, std::abs(actual[t] - expected[t]));
      }
      EXPECT_LT(worst, 2e-4) << ObjectiveName(objective) << (dense ? " dense" : " sparse");
    }
  }
}

TEST_F(OpenClEngineTest, FieldAndEnergyKernelsMatchTheCpuReference) {
  const MatchingProblem problem = testing::SyntheticProblem(41, 300, 80);
  EnergyOptions energy;
  energy.support_radius_px = 12.0;
  DynamicsOptions dynamics;
  dynamics.initial_state = InitialState::kRandomContinuous;
  const std::vector<double> V = InitialActivations(problem, dynamics);
  const NetworkLayout layout = BuildLayout(problem, energy);
  const auto weights = BuildCompatibilityWeights(problem, layout, energy);
  const auto biases = BuildBiases(problem, layout, energy);
  const auto input = SynapticInput(layout, weights, V, energy);
  const double expected_energy = Energy(layout, weights, biases, V, energy);
  OpenClEngine engine(*runtime_);
  double actual_energy = 0.0;
  const std::vector<float> field = engine.Field(problem, energy, V, &actual_energy);
  ASSERT_EQ(field.size(), input.size());
  for (std::size_t a = 0; a < field.size(); ++a) {
    ASSERT_NEAR(field[a], input[a] + biases[a], 1e-4 * (1.0 + std::abs(input[a]))) << "neuron " << a;
  }
  EXPECT_NEAR(actual_energy, expected_energy, 1e-5 * std::abs(expected_energy));
}

TEST_F(OpenClEngineTest, SolveAgreesWithTheCpuEngineOnSeededProblems) {
  for (std::uint64_t seed : {101u, 102u, 103u, 104u}) {
    for (Activation activation : {Activation::kContinuous, Activation::kDiscrete}) {
      const MatchingProblem problem = testing::SyntheticProblem(seed, 150, 50);
      EnergyOptions energy;
      energy.support_radius_px = 15.0;
      DynamicsOptions dynamics;
      dynamics.activation = activation;
      dynamics.seed = seed;
      const SolveReport cpu = SolveCpu(problem, energy, dynamics);
      OpenClEngine engine(*runtime_);
      const SolveReport opencl = engine.Solve(problem, energy, dynamics);
      const char* kind = activation == Activation::kContinuous ? "continuous" : "discrete";
      EXPECT_EQ(MatchedNeurons(problem, opencl), MatchedNeurons(problem, cpu))
          << "seed " << seed << " " << kind;
      EXPECT_NEAR(opencl.energy_final, cpu.energy_final, 1e-4 * EnergyScale(cpu))
          << "seed " << seed << " " << kind;
      EXPECT_NEAR(opencl.energy_initial, cpu.energy_initial, 1e-4 * std::abs(cpu.energy_initial));
      EXPECT_EQ(opencl.converged, cpu.converged);
    }
  }
}

TEST_F(OpenClEngineTest, DenseThesisNetworkAgreesWithTheCpuEngine) {
  const MatchingProblem problem = testing::SyntheticProblem(55, 30, 10, /*dense=*/true);
  EnergyOptions energy;
  const SolveReport cpu = SolveCpu(problem, energy, DynamicsOptions{});
  OpenClEngine engine(*runtime_);
  const SolveReport opencl = engine.Solve(problem, energy, DynamicsOptions{});
  EXPECT_EQ(MatchedNeurons(problem, opencl), MatchedNeurons(problem, cpu));
  EXPECT_NEAR(opencl.energy_final, cpu.energy_final, 1e-4 * EnergyScale(cpu));
}

TEST_F(OpenClEngineTest, BatchEqualsIndependentSolves) {
  ProblemBatch batch;
  for (std::uint64_t seed : {201u, 202u, 203u}) batch.push_back(testing::SyntheticProblem(seed, 80 + 20 * static_cast<int>(seed % 3), 30));
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  OpenClEngine engine(*runtime_);
  const std::vector<SolveReport> together = engine.SolveBatch(batch, energy, DynamicsOptions{});
  ASSERT_EQ(together.size(), batch.size());
  for (std::size_t p = 0; p < batch.size(); ++p) {
    const SolveReport alone = engine.Solve(batch[p], energy, DynamicsOptions{});
    EXPECT_EQ(together[p].iterations, alone.iterations) << "network " << p;
    EXPECT_NEAR(together[p].energy_final, alone.energy_final, 1e-4 * std::abs(alone.energy_final));
    EXPECT_EQ(MatchedNeurons(batch[p], together[p]),
              MatchedNeurons(batch[p], alone));
  }
}

TEST_F(OpenClEngineTest, Figure61ToyReachesTheGlobalAssignment) {
  const MatchingProblem problem = testing::Figure61Problem();
  EnergyOptions energy;
  energy.A = 0.0;
  energy.D = 0.25;
  DynamicsOptions dynamics;
  dynamics.initial_state = InitialState::kConstant;
  OpenClEngine engine(*runtime_);
  const SolveReport report = engine.Solve(problem, energy, dynamics);
  const auto matches = Decode(problem, report.activation, DecodeOptions{});
  ASSERT_EQ(matches.size(), 3u);
  for (const DecodedMatch& m : matches) EXPECT_EQ(m.left, m.column);
}

// Every weight storage of the opencl engine (row blocks in float and half, on the fly, CSR)
// solves the same network as the cpu reference: same matches, same energies (half-precision
// blocks within their rounding).
class OpenClStorageTest : public OpenClEngineTest,
                          public ::testing::WithParamInterface<WeightStorage> {};

TEST_P(OpenClStorageTest, SolveAgreesWithTheCpuEngine) {
  const WeightStorage storage = GetParam();
  const double tolerance = storage == WeightStorage::kBlockedHalf ? 2e-3 : 1e-4;
  for (std::uint64_t seed : {301u, 302u, 303u}) {
    for (Activation activation : {Activation::kContinuous, Activation::kDiscrete}) {
      for (int max_per_row : {0, 2, 4, 8}) {
        const MatchingProblem problem = testing::SyntheticProblem(seed, 150, 50, false, max_per_row);
        EnergyOptions energy;
        energy.support_radius_px = 15.0;
        energy.objective = seed == 302u ? Objective::kThesis : Objective::kGeometrySimilarity;
        DynamicsOptions dynamics;
        dynamics.activation = activation;
        const SolveReport cpu = SolveCpu(problem, energy, dynamics);
        OpenClEngine engine(*runtime_, {storage, 0});
        const SolveReport opencl = engine.Solve(problem, energy, dynamics);
        const std::string what = std::string(WeightStorageName(storage)) + " seed " +
                                 std::to_string(seed) + " per-row " + std::to_string(max_per_row) +
                                 (activation == Activation::kContinuous ? " continuous" : " discrete");
        EXPECT_EQ(opencl.weight_storage, WeightStorageName(storage)) << what;
        EXPECT_EQ(MatchedNeurons(problem, opencl), MatchedNeurons(problem, cpu)) << what;
        EXPECT_NEAR(opencl.energy_initial, cpu.energy_initial,
                    tolerance * std::abs(cpu.energy_initial)) << what;
        EXPECT_NEAR(opencl.energy_final, cpu.energy_final, tolerance * EnergyScale(cpu)) << what;
        EXPECT_EQ(opencl.converged, cpu.converged) << what;
      }
    }
  }
}

// The kDecisions stop rule (hnn-default's), whose check the row blocks' step makes itself
// (decide_row, at the steps before a check) and CSR in a kernel of its own: every storage and
// both step kinds stop at the cpu reference's step, with its checks and matches; 4-slot rows
// (four finished at once), 3-slot and wider ones, and a network still changing at the limit.
TEST_P(OpenClStorageTest, DecisionsRuleStopsWhereTheCpuEngineStops) {
  const WeightStorage storage = GetParam();
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  for (const int max_per_row : {4, 3, 2, 0}) {
    for (const int max_steps : {DynamicsOptions{}.max_steps, 5}) {
      const MatchingProblem problem = testing::SyntheticDisparityProblem(351, 150, 50, max_per_row);
      DynamicsOptions dynamics;
      dynamics.stop_rule = DynamicsOptions::StopRule::kDecisions;
      dynamics.energy_interval = 2;
      dynamics.stable_checks = 2;
      dynamics.max_steps = max_steps;
      const SolveReport cpu = SolveCpu(problem, energy, dynamics);
      for (const auto step : {OpenClEngineOptions::BlockStep::kRowPerItem,
                              OpenClEngineOptions::BlockStep::kRowPerGroup}) {
        for (const auto loop :
             {OpenClEngineOptions::SolveLoop::kHost, OpenClEngineOptions::SolveLoop::kDevice}) {
          if (storage == WeightStorage::kCsr &&
              (step != OpenClEngineOptions::BlockStep::kRowPerItem ||
               loop != OpenClEngineOptions::SolveLoop::kHost)) {
            continue;  // CSR has one step and one loop
          }
          OpenClEngineOptions options{storage, 0};
          options.block_step = step;
          options.solve_loop = loop;
          const SolveReport opencl =
              OpenClEngine(*runtime_, options).Solve(problem, energy, dynamics);
          const std::string what =
              std::string(WeightStorageName(storage)) + " per-row " + std::to_string(max_per_row) +
              " max_steps " + std::to_string(max_steps) +
              (step == OpenClEngineOptions::BlockStep::kRowPerGroup ? " group" : " item") +
              (opencl.solve_loop == "device" ? " device loop" : " host loop");
          EXPECT_EQ(opencl.iterations, cpu.iterations) << what;
          EXPECT_EQ(opencl.converged, cpu.converged) << what;
          EXPECT_EQ(opencl.energy_trace_iterations, cpu.energy_trace_iterations) << what;
          EXPECT_EQ(MatchedNeurons(problem, opencl), MatchedNeurons(problem, cpu)) << what;
        }
      }
      // The reference settles at step 10; the limit stops it while rows still change.
      EXPECT_EQ(cpu.converged, max_steps != 5) << "per-row " << max_per_row;
    }
  }
}

// Profiling (bench --profile) times every command on the device without changing the solve:
// the same state and steps as without it, one "solve" entry per kernel the solve launched, whose
// counts add up to the engine's own launch count, and device times that fit in the wall time.
TEST_P(OpenClStorageTest, ProfilingTimesEveryLaunchAndChangesNothing) {
  const WeightStorage storage = GetParam();
  const MatchingProblem problem = testing::SyntheticProblem(321, 150, 50, false, 4);
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  DynamicsOptions dynamics;
  dynamics.stop_rule = DynamicsOptions::StopRule::kDecisions;
  OpenClEngineOptions plain{storage, 0}, profiled{storage, 0};
  profiled.profile = true;
  const SolveReport a = OpenClEngine(*runtime_, plain).Solve(problem, energy, dynamics);
  const SolveReport b = OpenClEngine(*runtime_, profiled).Solve(problem, energy, dynamics);
  EXPECT_TRUE(a.kernel_times.empty());
  ASSERT_FALSE(b.kernel_times.empty());
  EXPECT_EQ(a.activation, b.activation);
  EXPECT_EQ(a.iterations, b.iterations);
  int kernel_launches = 0;
  double solve_device_ms = 0.0;
  for (const KernelTime& t : b.kernel_times) {
    EXPECT_GT(t.count, 0) << t.command;
    EXPECT_GE(t.device_ms, 0.0) << t.command;
    EXPECT_TRUE(t.phase == "build" || t.phase == "solve") << t.phase;
    if (t.command.rfind("read ", 0) != 0) kernel_launches += t.count;
    if (t.phase == "solve") solve_device_ms += t.device_ms;
  }
  if (storage != WeightStorage::kCsr) {
    EXPECT_EQ(kernel_launches, b.launches);  // the blocked solve counts its launches
  }
  EXPECT_GT(solve_device_ms, 0.0);
  EXPECT_LE(solve_device_ms, b.solve_ms * 1.05 + 0.1);
}

// The GPU's block build (one work-item per weight), forced on the CPU device: the same solve as
// the per-row build, for both objectives and for 4-slot (16-wide vector) and wider rows.
TEST_P(OpenClStorageTest, PerWeightBlockBuildAgreesWithThePerRowBuild) {
  const WeightStorage storage = GetParam();
  if (storage != WeightStorage::kBlockedFloat && storage != WeightStorage::kBlockedHalf) {
    GTEST_SKIP() << "row blocks only";
  }
  for (const Objective objective : {Objective::kGeometrySimilarity, Objective::kThesis}) {
    for (int max_per_row : {0, 2, 4, 8}) {
      const MatchingProblem problem = testing::SyntheticProblem(311, 150, 50, false, max_per_row);
      EnergyOptions energy;
      energy.support_radius_px = 15.0;
      energy.objective = objective;
      OpenClEngineOptions per_row{storage, 0}, per_weight{storage, 0};
      per_row.block_build = OpenClEngineOptions::BlockBuild::kPerRow;
      per_weight.block_build = OpenClEngineOptions::BlockBuild::kPerWeight;
      const SolveReport a = OpenClEngine(*runtime_, per_row).Solve(problem, energy, DynamicsOptions{});
      const SolveReport b = OpenClEngine(*runtime_, per_weight).Solve(problem, energy, DynamicsOptions{});
      const std::string what = "objective " + std::to_string(static_cast<int>(objective)) +
                               " per-row " + std::to_string(max_per_row);
      EXPECT_EQ(MatchedNeurons(problem, a), MatchedNeurons(problem, b)) << what;
      EXPECT_EQ(a.iterations, b.iterations) << what;
      EXPECT_NEAR(a.energy_final, b.energy_final, 1e-4 * EnergyScale(a)) << what;
    }
  }
}

// The GPU's blocked step (one work-group of kStepGroup lanes per row, partial inputs summed in
// local memory), forced on the CPU device: the same solve as the per-item step, for 4- and
// 8-slot rows (16-wide vectors), wider rows, the dense network, on the fly, and a batch whose
// networks freeze at different steps.
TEST_P(OpenClStorageTest, RowPerGroupStepAgreesWithTheRowPerItemStep) {
  const WeightStorage storage = GetParam();
  if (storage == WeightStorage::kCsr) GTEST_SKIP() << "row blocks and on the fly only";
  OpenClEngineOptions per_item{storage, 0}, per_group{storage, 0};
  per_item.block_step = OpenClEngineOptions::BlockStep::kRowPerItem;
  per_group.block_step = OpenClEngineOptions::BlockStep::kRowPerGroup;
  auto compare = [&](const MatchingProblem& problem, const EnergyOptions& energy,
                     const std::string& what) {
    const SolveReport a = OpenClEngine(*runtime_, per_item).Solve(problem, energy, DynamicsOptions{});
    const SolveReport b = OpenClEngine(*runtime_, per_group).Solve(problem, energy, DynamicsOptions{});
    EXPECT_EQ(MatchedNeurons(problem, a), MatchedNeurons(problem, b)) << what;
    // The lanes sum in another order: the same steps, up to one energy check either way.
    EXPECT_NEAR(a.iterations, b.iterations, DynamicsOptions{}.energy_interval) << what;
    EXPECT_NEAR(a.energy_final, b.energy_final, 1e-4 * EnergyScale(a)) << what;
  };
  for (const Objective objective : {Objective::kGeometrySimilarity, Objective::kThesis}) {
    for (int max_per_row : {0, 2, 4, 8}) {
      EnergyOptions energy;
      energy.support_radius_px = 15.0;
      energy.objective = objective;
      compare(testing::SyntheticProblem(313, 150, 50, false, max_per_row), energy,
              "objective " + std::to_string(static_cast<int>(objective)) + " per-row " +
                  std::to_string(max_per_row));
    }
  }
  compare(testing::SyntheticProblem(57, 25, 8, /*dense=*/true), EnergyOptions{}, "dense");
  ProblemBatch batch;
  for (std::uint64_t seed : {221u, 222u, 223u}) {
    batch.push_back(testing::SyntheticProblem(seed, 50 + 20 * static_cast<int>(seed % 3), 20, false, 4));
  }
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  const auto a = OpenClEngine(*runtime_, per_item).SolveBatch(batch, energy, DynamicsOptions{});
  const auto b = OpenClEngine(*runtime_, per_group).SolveBatch(batch, energy, DynamicsOptions{});
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t n = 0; n < a.size(); ++n) {
    EXPECT_EQ(MatchedNeurons(batch[n], a[n]), MatchedNeurons(batch[n], b[n])) << "batch " << n;
    EXPECT_NEAR(a[n].energy_final, b[n].energy_final, 1e-4 * EnergyScale(a[n])) << "batch " << n;
  }
}

// The kernels' activation (exp_lanes in kernels/hopfield.cl: the logistic 1 / (1 + e^(-2u/alpha))
// written out in fma and integer operations) against the thesis's V = (1 + tanh(u / alpha)) / 2 in
// double, on the state a solve stopped on (V and u of the same step), for every storage (csr:
// the scalar Euler kernel), 4-slot, 3-slot and wider rows (float16, float4 and float8
// finishes) and two gains: within 2.5e-7 of V plus 3e-8,
// and exactly 0 where the reference is below 2^-26 (as (1 + tanh) / 2 rounds in float).
TEST_P(OpenClStorageTest, ActivationIsTheThesisTanh) {
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  int checked = 0, zeros = 0;
  for (const double alpha : {0.5, 0.13}) {
    for (int max_per_row : {4, 2, 8}) {
      DynamicsOptions dynamics;
      dynamics.alpha = alpha;
      dynamics.max_steps = 9;  // a state in motion, not only the saturated end
      const MatchingProblem problem = testing::SyntheticProblem(41, 150, 50, false, max_per_row);
      const SolveReport r =
          OpenClEngine(*runtime_, {GetParam(), 0}).Solve(problem, energy, dynamics);
      ASSERT_EQ(r.activation.size(), r.potential.size());
      for (std::size_t a = 0; a < r.activation.size(); ++a) {
        const double reference = 0.5 * (1.0 + std::tanh(r.potential[a] / alpha));
        const std::string what = "alpha " + std::to_string(alpha) + " per-row " +
                                 std::to_string(max_per_row) + " neuron " + std::to_string(a);
        if (reference < std::ldexp(1.0, -26)) {
          EXPECT_EQ(r.activation[a], 0.0) << what;
          ++zeros;
        } else {
          EXPECT_NEAR(r.activation[a], reference, 2.5e-7 * reference + 3e-8) << what;
        }
        ++checked;
      }
    }
  }
  EXPECT_GT(zeros, 0);
  EXPECT_GT(checked - zeros, 500);  // compared with the reference, not only 0
}

TEST_P(OpenClStorageTest, DenseNetworkAgreesWithTheCpuEngine) {
  const MatchingProblem problem = testing::SyntheticProblem(56, 30, 10, /*dense=*/true);
  EnergyOptions energy;
  energy.distance_attenuation = true;
  const SolveReport cpu = SolveCpu(problem, energy, DynamicsOptions{});
  OpenClEngine engine(*runtime_, {GetParam(), 0});
  const SolveReport opencl = engine.Solve(problem, energy, DynamicsOptions{});
  EXPECT_EQ(MatchedNeurons(problem, opencl), MatchedNeurons(problem, cpu));
  const double tolerance = GetParam() == WeightStorage::kBlockedHalf ? 2e-3 : 1e-4;
  EXPECT_NEAR(opencl.energy_final, cpu.energy_final, tolerance * EnergyScale(cpu));
}

// A network solved in a batch is the network solved alone: bit for bit where its widest row gives
// the batch's block layout (ChooseStorage in host/device_network_blocks.cc: a row pad of the
// widest row rounded up to four slots, 3 x 4 blocks up to three), else to float rounding - the batch lays a narrower network out
// in its wider blocks, whose step adds the block columns in another order. Seeds 513 and 213
// (4-slot rows in batches of 8-slot ones) differed from their solves alone in the last bits of V.
TEST_P(OpenClStorageTest, BatchEqualsIndependentSolves) {
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  OpenClEngine engine(*runtime_, {GetParam(), 0});
  const auto layout = [](const MatchingProblem& problem) {
    std::map<int, int> row_size;
    int most = 0;
    for (const Candidate& c : problem.candidates) most = std::max(most, ++row_size[c.left]);
    return most <= 3 ? 3 : (most + 3) / 4 * 4;
  };
  int same_layout = 0, other_layout = 0;
  for (const std::uint64_t first_seed : {211u, 511u}) {
    ProblemBatch batch;
    int batch_layout = 0;
    for (std::uint64_t seed = first_seed; seed < first_seed + 3; ++seed) {
      batch.push_back(
          testing::SyntheticProblem(seed, 60 + 30 * static_cast<int>(seed % 3), 30, false, 4));
      batch_layout = std::max(batch_layout, layout(batch.back()));
    }
    const std::vector<SolveReport> together = engine.SolveBatch(batch, energy, DynamicsOptions{});
    ASSERT_EQ(together.size(), batch.size());
    for (std::size_t p = 0; p < batch.size(); ++p) {
      const std::string what = "seed " + std::to_string(first_seed + p);
      const SolveReport alone = engine.Solve(batch[p], energy, DynamicsOptions{});
      EXPECT_EQ(together[p].iterations, alone.iterations) << what;
      EXPECT_NEAR(together[p].energy_final, alone.energy_final, 1e-4 * std::abs(alone.energy_final))
          << what;
      EXPECT_EQ(MatchedNeurons(batch[p], together[p]), MatchedNeurons(batch[p], alone)) << what;
      if (layout(batch[p]) == batch_layout) {
        EXPECT_EQ(together[p].activation, alone.activation) << what;
        ++same_layout;
        continue;
      }
      ASSERT_EQ(together[p].activation.size(), alone.activation.size()) << what;
      for (std::size_t a = 0; a < alone.activation.size(); ++a) {
        EXPECT_NEAR(together[p].activation[a], alone.activation[a], 1e-5)
            << what << " neuron " << a;
      }
      ++other_layout;
    }
  }
  EXPECT_EQ(same_layout, 4);
  EXPECT_EQ(other_layout, 2);
}

// The solve loop on the device (one launch of solve_blocked_resident, SolveLoop::kDevice)
// against the host loop (a launch per step, a round trip per check) on feature-vs-disparity
// networks and feature networks (column sums every step): the same steps, checks, state and
// matches for both stop rules and both activations; 4-slot rows (finished four rows at a time),
// 3-slot and wider rows; row counts that are no multiple of four; and runs cut by the step
// limit (7 steps, and none).
TEST_P(OpenClStorageTest, DeviceLoopAgreesWithTheHostLoop) {
  const WeightStorage storage = GetParam();
  if (storage == WeightStorage::kCsr) GTEST_SKIP() << "row blocks and on the fly only";
  OpenClEngineOptions host{storage, 0}, device{storage, 0};
  host.solve_loop = OpenClEngineOptions::SolveLoop::kHost;
  device.solve_loop = OpenClEngineOptions::SolveLoop::kDevice;
  // The device loop runs the per-item step, a CPU device's own; on a GPU (whose automatic step
  // is a work-group per row, which the loop cannot run) both take it, so that the loop, with
  // several work-groups too, is tested there.
  host.block_step = device.block_step = OpenClEngineOptions::BlockStep::kRowPerItem;
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  int cases = 0;
  const int units = static_cast<int>(runtime_->device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
  for (std::uint64_t seed : {331u, 332u}) {
    // Up to max_per_row + 1 neurons a row: 2 gives the 3 x 4 blocks of hnn-default's K = 3
    // (the disparity network only: seed 332's then converges within 7 steps).
    for (int max_per_row : {4, 3, 2, 0}) {
      if (seed == 332u && max_per_row == 2) continue;
      // Seed 332: a feature-vs-feature network (column uniqueness: column sums every step).
      const MatchingProblem problem =
          seed == 331u ? testing::SyntheticDisparityProblem(seed, 149, 50, max_per_row)
                       : testing::SyntheticProblem(seed, 150, 50, false, max_per_row);
      for (const auto rule :
           {DynamicsOptions::StopRule::kEnergy, DynamicsOptions::StopRule::kDecisions}) {
        for (const Activation activation : {Activation::kContinuous, Activation::kDiscrete}) {
          for (const int max_steps : {DynamicsOptions{}.max_steps, 7, 0}) {
            DynamicsOptions dynamics;
            dynamics.stop_rule = rule;
            dynamics.activation = activation;
            dynamics.max_steps = max_steps;
            if (rule == DynamicsOptions::StopRule::kDecisions) dynamics.energy_interval = 2;
            const SolveReport a = OpenClEngine(*runtime_, host).Solve(problem, energy, dynamics);
            const SolveReport b = OpenClEngine(*runtime_, device).Solve(problem, energy, dynamics);
            const std::string what =
                "seed " + std::to_string(seed) + " per-row " + std::to_string(max_per_row) +
                (rule == DynamicsOptions::StopRule::kEnergy ? " energy" : " decisions") +
                (activation == Activation::kContinuous ? " continuous" : " discrete") +
                " max_steps " + std::to_string(max_steps);
            EXPECT_EQ(a.solve_loop, "host") << what;
            EXPECT_EQ(b.solve_loop, "device") << what;
            EXPECT_EQ(a.iterations, b.iterations) << what;
            EXPECT_EQ(a.converged, b.converged) << what;
            EXPECT_EQ(a.energy_trace_iterations, b.energy_trace_iterations) << what;
            ASSERT_EQ(a.energy_trace.size(), b.energy_trace.size()) << what;
            for (std::size_t c = 0; c < a.energy_trace.size(); ++c) {
              // The device adds the row energies in row order, segment_sum as a tree.
              EXPECT_NEAR(a.energy_trace[c], b.energy_trace[c], 1e-5 * EnergyScale(a)) << what;
            }
            EXPECT_EQ(a.activation, b.activation) << what;  // the same step code, bit for bit
            // Several work-groups taking the ranges of rows of each step: bit for bit one
            // group's run, also with more groups than the device has threads (they never
            // all run at once). A GPU runs one group whatever is asked (stale reads across
            // groups there, host/device_network_blocks.cc).
            for (const int groups : {2, 3, units + 1}) {
              OpenClEngineOptions spread = device;
              spread.resident_groups = groups;
              const SolveReport c =
                  OpenClEngine(*runtime_, spread).Solve(problem, energy, dynamics);
              const std::string in = what + " groups " + std::to_string(groups);
              EXPECT_EQ(c.solve_loop, "device") << in;
              EXPECT_EQ(c.solve_groups, runtime_->is_gpu() ? 1 : groups) << in;
              EXPECT_EQ(b.iterations, c.iterations) << in;
              EXPECT_EQ(b.converged, c.converged) << in;
              EXPECT_EQ(b.energy_trace, c.energy_trace) << in;
              EXPECT_EQ(b.activation, c.activation) << in;
            }
            EXPECT_EQ(a.potential, b.potential) << what;
            EXPECT_EQ(MatchedNeurons(problem, a), MatchedNeurons(problem, b)) << what;
            // One launch for the loop (and one for the block build), one blocking read for its
            // outcome, then the state.
            EXPECT_LE(b.launches, 2) << what;
            EXPECT_LT(b.launches, a.launches) << what;
            EXPECT_LE(b.blocking_reads, 5) << what;
            if (max_steps < 10) EXPECT_FALSE(b.converged) << what;
            if (max_steps < 10) EXPECT_EQ(b.iterations, max_steps) << what;
            ++cases;
          }
        }
      }
    }
  }
  EXPECT_EQ(cases, 84);
}

// Networks solved together in one host loop, where a frozen network's rows share groups of four
// with a live one (the finish of four rows falls back to one row at a time), against each
// solved alone (one network: the loop on the device).
TEST_P(OpenClStorageTest, DisparityBatchEqualsIndependentDeviceLoops) {
  const WeightStorage storage = GetParam();
  if (storage == WeightStorage::kCsr) GTEST_SKIP() << "row blocks and on the fly only";
  ProblemBatch batch;
  batch.push_back(testing::SyntheticDisparityProblem(341, 13, 0, 4));
  batch.push_back(testing::SyntheticDisparityProblem(342, 61, 30, 4));
  batch.push_back(testing::SyntheticDisparityProblem(343, 149, 120, 4));
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  OpenClEngineOptions options{storage, 0};
  options.solve_loop = OpenClEngineOptions::SolveLoop::kDevice;  // a batch still loops on the host
  options.block_step =
      OpenClEngineOptions::BlockStep::kRowPerItem;  // the loop's step, on a GPU too
  OpenClEngine engine(*runtime_, options);
  DynamicsOptions dynamics;  // the energy rule
  const std::vector<SolveReport> together = engine.SolveBatch(batch, energy, dynamics);
  ASSERT_EQ(together.size(), batch.size());
  std::set<int> steps;
  for (std::size_t p = 0; p < batch.size(); ++p) {
    const SolveReport alone = engine.Solve(batch[p], energy, dynamics);
    EXPECT_EQ(together[p].solve_loop, "host");
    EXPECT_EQ(alone.solve_loop, "device");
    EXPECT_EQ(together[p].iterations, alone.iterations) << "network " << p;
    EXPECT_EQ(MatchedNeurons(batch[p], together[p]), MatchedNeurons(batch[p], alone));
    // A row finished alone (float4) or in a group of four (float16) may round differently.
    ASSERT_EQ(together[p].activation.size(), alone.activation.size());
    for (std::size_t a = 0; a < alone.activation.size(); ++a) {
      EXPECT_NEAR(together[p].activation[a], alone.activation[a], 1e-5) << "network " << p;
    }
    steps.insert(alone.iterations);
  }
  EXPECT_GT(steps.size(), 1u) << "the networks should freeze at different steps";
}

INSTANTIATE_TEST_SUITE_P(Storages, OpenClStorageTest,
                         ::testing::Values(WeightStorage::kCsr, WeightStorage::kBlockedFloat,
                                           WeightStorage::kBlockedHalf, WeightStorage::kOnTheFly),
                         [](const ::testing::TestParamInfo<WeightStorage>& info) {
                           std::string name(WeightStorageName(info.param));
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// SolveLoop::kAuto: the loop goes to a CPU device for one small network of stored blocks (also a
// feature-vs-feature network, its column sums inside the loop); batches, kHost and, with one
// group a network, on the fly keep it on the host; larger networks take a group per core.
// Rows of at most three neurons (hnn-default's K = 3) stream 3 x 4 weight blocks, rows of four
// 4 x 4: read off the step-bytes model (docs/benchmark.md) of the float, half and on-the-fly
// layouts of one network - float - half = 8 B x blocks x block columns, and on the fly reads no
// blocks - with the same matches from both block layouts (the solve tests above compare values;
// SyntheticDisparityProblem keeps the true disparity beside max_per_row others).
TEST_F(OpenClEngineTest, ThreeNeuronRowsStreamThreeColumnBlocks) {
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  for (const int max_per_row : {2, 3}) {
    const MatchingProblem problem = testing::SyntheticDisparityProblem(361, 150, 50, max_per_row);
    std::map<WeightStorage, SolveReport> reports;
    for (const WeightStorage storage :
         {WeightStorage::kBlockedFloat, WeightStorage::kBlockedHalf, WeightStorage::kOnTheFly}) {
      reports[storage] =
          OpenClEngine(*runtime_, {storage, 0}).Solve(problem, energy, DynamicsOptions{});
    }
    const double as_float = reports[WeightStorage::kBlockedFloat].step_bytes;
    const double as_half = reports[WeightStorage::kBlockedHalf].step_bytes;
    const double on_the_fly = reports[WeightStorage::kOnTheFly].step_bytes;
    // 4-slot rows: float 4 B x blocks x 4 x columns + 4 B a block + 92 B a row (20 B a slot +
    // 12); half 2 B a slot pair; on the fly 4 B a block + 140 B a row (32 B a slot + 12).
    const double rows = ((as_float - as_half) - (as_half - on_the_fly)) / 48.0;
    const double blocks = (on_the_fly - 140.0 * rows) / 4.0;
    ASSERT_GT(blocks, 0.0) << as_float << " " << as_half << " " << on_the_fly;
    EXPECT_DOUBLE_EQ((as_float - as_half) / (8.0 * blocks), max_per_row == 2 ? 3.0 : 4.0)
        << "max_per_row " << max_per_row;
    EXPECT_EQ(MatchedNeurons(problem, reports[WeightStorage::kBlockedHalf]),
              MatchedNeurons(problem, reports[WeightStorage::kBlockedFloat]));
  }
}

TEST_F(OpenClEngineTest, AutoSolveLoopRunsSmallSingleNetworksOnTheDevice) {
  if (runtime_->is_gpu()) GTEST_SKIP() << "a CPU device's rule";
  EnergyOptions energy;
  energy.support_radius_px = 15.0;
  const MatchingProblem small = testing::SyntheticDisparityProblem(351, 150, 50, 4);
  OpenClEngine automatic(*runtime_, {WeightStorage::kBlockedHalf, 0});
  const SolveReport alone = automatic.Solve(small, energy, DynamicsOptions{});
  EXPECT_EQ(alone.solve_loop, "device");
  EXPECT_LE(alone.step_bytes,
            ResidentMaxStepBytes(runtime_->device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>()));
  // A feature network: its column sums run inside the device loop too.
  EXPECT_EQ(
      automatic.Solve(testing::SyntheticProblem(351, 150, 50, false, 4), energy, DynamicsOptions{})
          .solve_loop,
      "device");
  for (const SolveReport& r : automatic.SolveBatch({small, small}, energy, DynamicsOptions{})) {
    EXPECT_EQ(r.solve_loop, "host");
  }
  // On the fly computes every weight each step: its loop stays on the host (all cores).
  EXPECT_EQ(OpenClEngine(*runtime_, {WeightStorage::kOnTheFly, 0})
                .Solve(small, energy, DynamicsOptions{})
                .solve_loop,
            "host");
  OpenClEngineOptions host{WeightStorage::kBlockedHalf, 0};
  host.solve_loop = OpenClEngineOptions::SolveLoop::kHost;
  EXPECT_EQ(OpenClEngine(*runtime_, host).Solve(small, energy, DynamicsOptions{}).solve_loop,
            "host");
  // A network whose step reads more than the limit (dense rows of many slots): on one core it
  // stays on the host; with more, the device loop runs it with a work-group per core, on the
  // fly too.
  EnergyOptions wide = energy;
  wide.support_radius_px = 60.0;
  const MatchingProblem large = testing::SyntheticDisparityProblem(352, 3000, 0, 4);
  const SolveReport big = automatic.Solve(large, wide, DynamicsOptions{});
  ASSERT_GT(big.step_bytes, 2.0 * kResidentMaxStepBytes);
  const int units = static_cast<int>(runtime_->device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
  if (units == 1) {
    EXPECT_EQ(big.solve_loop, "host");
  } else {
    EXPECT_EQ(big.solve_loop, "device");
    EXPECT_GE(big.solve_groups, 1);
    EXPECT_LE(big.solve_groups, units);
    const MatchingProblem medium = testing::SyntheticDisparityProblem(353, 400, 0, 4);
    OpenClEngineOptions fly{WeightStorage::kOnTheFly, 0};
    EXPECT_EQ(OpenClEngine(*runtime_, fly).Solve(medium, energy, DynamicsOptions{}).solve_loop,
              "device");
  }
}

// The device loop's ranges of rows: cuts at multiples of four rows, about equal work.
TEST(ResidentRanges, CutsAtQuadsWithEqualWork) {
  // 1,000 rows; the first 500 have 30 neighbour blocks each, the rest 10.
  std::vector<int> offsets{0};
  for (int i = 0; i < 1000; ++i) offsets.push_back(offsets.back() + (i < 500 ? 30 : 10));
  for (const int ranges : {1, 2, 3, 7, 16}) {
    const std::vector<int> cuts = ResidentRanges(offsets, 1000, ranges);
    ASSERT_EQ(cuts.size(), static_cast<std::size_t>(ranges) + 1);
    EXPECT_EQ(cuts.front(), 0);
    EXPECT_EQ(cuts.back(), 1000);
    const double total = offsets.back() + 8.0 * 1000;
    for (int r = 0; r < ranges; ++r) {
      EXPECT_EQ(cuts[r] % 4, 0);
      EXPECT_LT(cuts[r], cuts[r + 1]);
      const double work = offsets[cuts[r + 1]] - offsets[cuts[r]] + 8.0 * (cuts[r + 1] - cuts[r]);
      EXPECT_NEAR(work, total / ranges, 4 * 38.0) << ranges << " ranges, range " << r;
    }
  }
  EXPECT_EQ(ResidentRanges(offsets, 1000, 2)[1], 372);  // 38 x 372 = 14,136 of 28,000
  // More ranges than quads of rows: one per quad; no rows, one empty range.
  EXPECT_EQ(ResidentRanges({0, 1, 2, 3, 4, 5, 6}, 6, 4), (std::vector<int>{0, 4, 6}));
  EXPECT_EQ(ResidentRanges({0}, 0, 2), (std::vector<int>{0, 0}));
}

TEST(ResidentLoopLimit, ShrinksWithTheCores) {
  EXPECT_TRUE(std::isinf(ResidentMaxStepBytes(1)));
  EXPECT_DOUBLE_EQ(ResidentMaxStepBytes(2), kResidentMaxStepBytes);
  EXPECT_LT(ResidentMaxStepBytes(16), ResidentMaxStepBytes(4));
  EXPECT_GT(ResidentMaxStepBytes(16), 0.5 * kResidentMaxStepBytes);
}

TEST(SolveLoopNames, Parse) {
  EXPECT_EQ(ParseSolveLoop("auto"), OpenClEngineOptions::SolveLoop::kAuto);
  EXPECT_EQ(ParseSolveLoop("host"), OpenClEngineOptions::SolveLoop::kHost);
  EXPECT_EQ(ParseSolveLoop("device"), OpenClEngineOptions::SolveLoop::kDevice);
  EXPECT_FALSE(ParseSolveLoop("gpu").has_value());
}

TEST(WeightStorageNames, RoundTrip) {
  for (WeightStorage s : {WeightStorage::kAuto, WeightStorage::kCsr, WeightStorage::kBlockedFloat,
                          WeightStorage::kBlockedHalf, WeightStorage::kOnTheFly}) {
    EXPECT_EQ(ParseWeightStorage(WeightStorageName(s)), s);
  }
  EXPECT_FALSE(ParseWeightStorage("fast").has_value());
}

}  // namespace
}  // namespace hnnstereo::hnn
