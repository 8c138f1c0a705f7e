// host/network_file.h: a captured network reads back as written, and malformed files are
// refused with a reason instead of crashing.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>

#include "host/cpu_engines.h"
#include "host/network_file.h"
#include "synthetic_problems.h"

namespace hnnstereo::hnn {
namespace {

TEST(NetworkFile, RoundTripsTheProblemAndOptionsAndSolvesTheSame) {
  MatchingProblem problem = testing::SyntheticProblem(7, 60, 20);
  problem.kind = NetworkKind::kFeatureVsDisparity;
  EnergyOptions energy;
  energy.objective = Objective::kGeometrySimilarity;
  energy.support_radius_px = 12.0;
  energy.B = 1.25;
  DynamicsOptions dynamics;
  dynamics.stop_rule = DynamicsOptions::StopRule::kDecisions;
  dynamics.energy_interval = 2;
  dynamics.seed = 0x123456789abcdefULL;
  const CapturedNetwork back = ParseNetwork(SerializeNetwork(problem, energy, dynamics));
  ASSERT_EQ(back.problem.candidates.size(), problem.candidates.size());
  EXPECT_EQ(back.problem.left_points, problem.left_points);
  EXPECT_EQ(back.problem.n_columns, problem.n_columns);
  EXPECT_EQ(back.problem.kind, problem.kind);
  for (std::size_t a = 0; a < problem.candidates.size(); ++a) {
    const Candidate &x = problem.candidates[a], &y = back.problem.candidates[a];
    EXPECT_EQ(x.left, y.left);
    EXPECT_EQ(x.column, y.column);
    EXPECT_EQ(x.right_point, y.right_point);
    EXPECT_EQ(x.correlation, y.correlation);
    EXPECT_EQ(x.epipolar_distance_px, y.epipolar_distance_px);
  }
  EXPECT_EQ(back.energy.objective, energy.objective);
  EXPECT_EQ(back.energy.B, energy.B);
  EXPECT_EQ(back.dynamics.stop_rule, dynamics.stop_rule);
  EXPECT_EQ(back.dynamics.seed, dynamics.seed);
  // What matters for a replay: the same network solves to the same state.
  const SolveReport a = SolveCpu(problem, energy, dynamics);
  const SolveReport b = SolveCpu(back.problem, back.energy, back.dynamics);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.energy_final, b.energy_final);
  EXPECT_EQ(a.activation, b.activation);
}

TEST(NetworkFile, MalformedFilesAreRefusedWithAReason) {
  const std::string good =
      SerializeNetwork(testing::SyntheticProblem(3, 20, 5), EnergyOptions{}, DynamicsOptions{});
  EXPECT_THROW(ParseNetwork(""), std::invalid_argument);
  EXPECT_THROW(ParseNetwork("P5\n640 480\n255\n"), std::invalid_argument);
  // Every truncation is refused, none reads past the end.
  for (std::size_t n = 0; n < good.size(); n += 7) {
    EXPECT_THROW(ParseNetwork(good.substr(0, n)), std::invalid_argument) << n << " bytes";
  }
  EXPECT_THROW(ParseNetwork(good + "x"), std::invalid_argument);
  // A candidate count far beyond the file (a forged header) is refused before allocating.
  try {
    std::string huge = good;
    // The candidate count is the int64 right before the candidate records.
    const MatchingProblem p = testing::SyntheticProblem(3, 20, 5);
    const std::size_t at = good.size() - 24 * p.candidates.size() - 8;
    const std::int64_t big = std::int64_t{1} << 60;
    std::memcpy(huge.data() + at, &big, sizeof(big));
    ParseNetwork(huge);
    ADD_FAILURE() << "a forged candidate count was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("beyond the file"), std::string::npos) << e.what();
  }
  // A NaN energy constant is refused.
  std::string nan = good;
  const double bad = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(nan.data() + 8, &bad, sizeof(bad));
  EXPECT_THROW(ParseNetwork(nan), std::invalid_argument);
}

}  // namespace
}  // namespace hnnstereo::hnn
