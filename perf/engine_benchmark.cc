// Google Benchmark: the engines and single kernels on seeded synthetic problems.
// Run: build/perf/hnnstereo_engine_benchmark (set POCL_CACHE_DIR; kernels warm up in the first
// iterations, which Google Benchmark's own warm-up absorbs with --benchmark_min_warmup_time).
#include <benchmark/benchmark.h>

#include <memory>

#include "host/cpu_engines.h"
#include "host/opencl_engine.h"
#include "../tests/host/synthetic_problems.h"

namespace {

using namespace hnnstereo;

ocl::Runtime* SharedRuntime() {
  static std::unique_ptr<ocl::Runtime> runtime = [] {
    std::string why_not;
    return ocl::Runtime::Create(ocl::DeviceSelection::FromEnvironment(), &why_not);
  }();
  return runtime.get();
}

hnn::EnergyOptions Energy() {
  hnn::EnergyOptions energy;
  energy.support_radius_px = 12.0;
  return energy;
}

void BM_CpuSolve(benchmark::State& state) {
  const auto problem = hnn::testing::SyntheticProblem(1, static_cast<int>(state.range(0)), 100);
  for (auto _ : state) {
    auto report = hnn::SolveCpu(problem, Energy(), hnn::DynamicsOptions{});
    benchmark::DoNotOptimize(report.energy_final);
    state.counters["neurons"] = report.n_neurons;
    state.counters["connections"] = static_cast<double>(report.n_connections);
  }
}
BENCHMARK(BM_CpuSolve)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond);

void BM_OpenClSolve(benchmark::State& state) {
  if (!SharedRuntime()) {
    state.SkipWithError("no OpenCL device");
    return;
  }
  const auto problem = hnn::testing::SyntheticProblem(1, static_cast<int>(state.range(0)), 100);
  hnn::OpenClEngine engine(*SharedRuntime());
  for (auto _ : state) {
    auto report = engine.Solve(problem, Energy(), hnn::DynamicsOptions{});
    benchmark::DoNotOptimize(report.energy_final);
    state.counters["neurons"] = report.n_neurons;
    state.counters["connections"] = static_cast<double>(report.n_connections);
  }
}
BENCHMARK(BM_OpenClSolve)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond);

void BM_OpenClBuildWeights(benchmark::State& state) {
  if (!SharedRuntime()) {
    state.SkipWithError("no OpenCL device");
    return;
  }
  const auto problem = hnn::testing::SyntheticProblem(2, static_cast<int>(state.range(0)), 100);
  hnn::OpenClEngine engine(*SharedRuntime());
  for (auto _ : state) benchmark::DoNotOptimize(engine.BuildWeights(problem, Energy()).size());
}
BENCHMARK(BM_OpenClBuildWeights)->Arg(2000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
