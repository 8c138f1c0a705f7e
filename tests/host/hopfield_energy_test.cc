// Weights, biases and compatibility against closed forms computed by hand (eq. 6.6-6.12).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "host/hopfield_energy.h"
#include "host/hopfield_network.h"
#include "synthetic_problems.h"

namespace hnnstereo::hnn {
namespace {

MatchGeometry Match(double xl, double yl, double xr, double yr, double m) {
  return {Eigen::Vector2d(xl, yl), Eigen::Vector2d(xr, yr), m};
}

TEST(DisparityGradient, HandComputedCases) {
  // Equal disparities: zero gradient.
  EXPECT_DOUBLE_EQ(DisparityGradient(Match(0, 0, -2, 0, 0), Match(4, 0, 2, 0, 0)), 0.0);
  // d_a = (-2, 0), d_b = (-4, 0): |dd| = 2; cyclopean points (-1, 0) and (3, 0): 4 apart.
  EXPECT_DOUBLE_EQ(DisparityGradient(Match(0, 0, -2, 0, 0), Match(5, 0, 1, 0, 0)), 0.5);
  // 2D disparities (unrectified): d_a = (1, 1), d_b = (1, -1): |dd| = 2;
  // cyclopean (0.5, 0.5) and (10.5, -0.5): sqrt(100 + 1).
  EXPECT_NEAR(DisparityGradient(Match(0, 0, 1, 1, 0), Match(10, 0, 11, -1, 0)),
              2.0 / std::sqrt(101.0), 1e-12);
  // Same cyclopean point, different disparities: the guard value.
  EXPECT_EQ(DisparityGradient(Match(0, 0, 2, 0, 0), Match(1, 0, 1, 0, 0)), kMaxDisparityGradient);
}

TEST(Compatibility, ThesisEquationHandComputed) {
  EnergyOptions options;  // W1 0.3, W2 0.7, T 1.5, lambda 5, theta 1
  // dd = 0 -> g = 1; s = 0.3 + 0.7 * 1.8 = 1.56; X = 1 / 1.56; C = 2 / (1 + e^{5 (X - 1)}) - 1.
  const double X = 1.0 / 1.56;
  const double expected = 2.0 / (1.0 + std::exp(5.0 * (X - 1.0))) - 1.0;
  EXPECT_NEAR(Compatibility(Match(0, 0, -2, 0, 0.9), Match(4, 0, 2, 0, 0.9), options), expected, 1e-12);
  EXPECT_NEAR(expected, 0.71506, 1e-4);
  // dd = 0.5 -> g = 2 e^{-1/3} - 1; s = 0.3 g + 0.7 (0.5 + 0.7).
  const double g = 2.0 * std::exp(-0.5 / 1.5) - 1.0;
  const double s = 0.3 * g + 0.7 * 1.2;
  EXPECT_NEAR(Compatibility(Match(0, 0, -2, 0, 0.5), Match(5, 0, 1, 0, 0.7), options),
              2.0 / (1.0 + std::exp(5.0 * (1.0 / s - 1.0))) - 1.0, 1e-12);
}

TEST(Compatibility, GuardsTheDivisionOfEquation67) {
  EnergyOptions options;
  // s = 0.3 * 1 + 0.7 * (-1.6) < 0: without the guard X < 0 would make the pair *compatible*.
  EXPECT_DOUBLE_EQ(Compatibility(Match(0, 0, -2, 0, -0.8), Match(4, 0, 2, 0, -0.8), options), -1.0);
  // s exactly zero: 0.3 * 1 + 0.7 * (M_a + M_b) = 0 with M_a + M_b = -3/7.
  EXPECT_DOUBLE_EQ(
      Compatibility(Match(0, 0, -2, 0, -1.5 / 7.0), Match(4, 0, 2, 0, -1.5 / 7.0), options), -1.0);
  EXPECT_TRUE(std::isfinite(Compatibility(Match(0, 0, 2, 0, 0.1), Match(1, 0, 1, 0, 0.1), options)));
}

TEST(Compatibility, PrintedVariantsAndProduct) {
  EnergyOptions options;
  const MatchGeometry a = Match(0, 0, -2, 0, 0.6), b = Match(5, 0, 1, 0, 0.2);
  options.objective = Objective::kPrinted2;
  EXPECT_DOUBLE_EQ(Compatibility(a, b, options), (0.6 + 0.2 + 2.0) / 4.0);
  options.objective = Objective::kPrinted1;
  EXPECT_DOUBLE_EQ(Compatibility(a, b, options), 0.5);
  options.objective = Objective::kGeometrySimilarity;
  EXPECT_NEAR(Compatibility(a, b, options),
              (2.0 * std::exp(-0.5 / 1.5) - 1.0) * 1.6 * 1.2 / 4.0, 1e-12);
  options.objective = Objective::kPrinted0;
  options.compatibility = CompatibilityType::kExponential;
  // |(|d_a| - |d_b|)| = |2 - 4| = 2; |(|l_a - l_b| - |r_a - r_b|)| = |5 - 3| = 2; X = 0.8 + 1.2.
  EXPECT_NEAR(Compatibility(a, b, options), 2.0 * std::exp(-2.0 / 1.5) - 1.0, 1e-12);
}

TEST(Bias, Equation612) {
  EnergyOptions options;
  EXPECT_DOUBLE_EQ(Bias(0.5, true, options), 1.0 + 1.0 - 0.5);
  EXPECT_DOUBLE_EQ(Bias(0.5, false, options), 1.0 - 0.5);
  options.D = 2.0;
  EXPECT_DOUBLE_EQ(Bias(0.25, true, options), 1.5);
}

// A 2 x 2 network: left features at (0,0) and (4,0); right features at (-2,0) and (2,0).
MatchingProblem TwoByTwo() {
  MatchingProblem problem;
  problem.dense = true;
  problem.n_columns = 2;
  problem.left_points = {{0, 0}, {4, 0}};
  problem.candidates = {{0, 0, {-2, 0}, 0.0f, 0.9f}, {0, 1, {2, 0}, 0.5f, 0.1f},
                        {1, 0, {-2, 0}, 0.25f, 0.2f}, {1, 1, {2, 0}, 0.0f, 0.9f}};
  return problem;
}

TEST(HopfieldNetwork, DenseWeightsEqualEquation611) {
  const MatchingProblem problem = TwoByTwo();
  EnergyOptions options;
  const NetworkLayout layout = BuildLayout(problem, options);
  const auto compat = BuildCompatibilityWeights(problem, layout, options);
  const auto W = BuildDenseWeights(problem, layout, compat, options);
  ASSERT_EQ(W.size(), 16u);
  auto w = [&](int a, int b) { return static_cast<double>(W[static_cast<std::size_t>(a * 4 + b)]); };
  auto geometry = [&](int a) {
    const Candidate& c = problem.candidates[static_cast<std::size_t>(a)];
    return MatchGeometry{problem.left_points[static_cast<std::size_t>(c.left)].cast<double>(),
                         c.right_point.cast<double>(), c.correlation};
  };
  for (int a = 0; a < 4; ++a) {
    EXPECT_EQ(w(a, a), 0.0) << "no self-connection";
    for (int b = 0; b < 4; ++b) {
      if (a == b) continue;
      const bool same_row = a / 2 == b / 2, same_column = a % 2 == b % 2;
      const double expected = 2.0 * (2.0 * Compatibility(geometry(a), geometry(b), options) -
                                     (same_row ? 1.0 : 0.0) - (same_column ? 1.0 : 0.0));
      EXPECT_NEAR(w(a, b), expected, 1e-5) << a << "," << b;
      EXPECT_NEAR(w(a, b), w(b, a), 1e-6) << "symmetric";
    }
  }
  // Neurons 0 and 3 have equal disparities (-2, 0) and M = 0.9: the hand value of the test above.
  EXPECT_NEAR(w(0, 3), 4.0 * 0.71506, 1e-3);
  const auto I = BuildBiases(problem, layout, options);
  EXPECT_DOUBLE_EQ(I[1], 1.5);
  EXPECT_DOUBLE_EQ(I[2], 1.75);
}

TEST(HopfieldNetwork, SparseAndDenseEnergiesAgreeWhenTheRadiusCoversAll) {
  MatchingProblem sparse = testing::SyntheticProblem(7, 30, 10);
  MatchingProblem dense = sparse;
  dense.dense = true;
  EnergyOptions options;
  options.support_radius_px = 1000.0;
  const NetworkLayout ls = BuildLayout(sparse, options), ld = BuildLayout(dense, options);
  const auto ws = BuildCompatibilityWeights(sparse, ls, options);
  const auto wd = BuildCompatibilityWeights(dense, ld, options);
  const auto bias = BuildBiases(sparse, ls, options);
  DynamicsOptions dynamics;
  dynamics.initial_state = InitialState::kRandomContinuous;
  const auto V = InitialActivations(sparse, dynamics);
  EXPECT_NEAR(Energy(ls, ws, bias, V, options), Energy(ld, wd, bias, V, options), 1e-9);
  // And the thesis's dense matrix gives the same E = -1/2 V W V - I V.
  const auto W = BuildDenseWeights(dense, ld, wd, options);
  const std::size_t n = V.size();
  double E = 0.0;
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = 0; b < n; ++b) E -= 0.5 * W[a * n + b] * V[a] * V[b];
    E -= bias[a] * V[a];
  }
  EXPECT_NEAR(E, Energy(ld, wd, bias, V, options), 1e-3 * std::max(1.0, std::abs(E)));
}

TEST(HopfieldNetwork, RefusesAProblemOverTheMemoryBudget) {
  MatchingProblem problem = testing::SyntheticProblem(3, 40, 20, /*dense=*/true);
  try {
    BuildLayout(problem, EnergyOptions{}, /*memory_budget_bytes=*/1 << 20);
    FAIL() << "expected a memory-budget error";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("memory budget"), std::string::npos) << message;
    EXPECT_NE(message.find("neurons"), std::string::npos) << message;
    EXPECT_NE(message.find("--max-features"), std::string::npos) << message;
  }
}

// The neighbour lists (left features within the support radius, itself included, sorted) against
// a brute-force search: clustered and spread points, enough features for the threaded search,
// points on cell borders and at exactly the radius, and a huge extent (coarser grid cells).
TEST(HopfieldNetwork, FeatureNeighboursAreThoseOfABruteForceSearch) {
  std::mt19937 rng(7);
  for (const auto& [n, extent] : std::vector<std::pair<int, float>>{
           {1, 10.0f}, {50, 40.0f}, {6000, 450.0f}, {3000, 1e6f}, {5000, 60.0f}}) {
    MatchingProblem problem;
    problem.kind = NetworkKind::kFeatureVsDisparity;
    problem.n_columns = 1;
    std::uniform_real_distribution<float> coordinate(0.0f, extent);
    for (int i = 0; i < n; ++i) {
      // Every fourth point on the integer grid: distances of exactly the radius occur.
      Eigen::Vector2f p(coordinate(rng), coordinate(rng));
      if (i % 4 == 0) p = p.array().round();
      problem.left_points.push_back(p);
      problem.candidates.push_back({i, 0, p, 0.0f, 0.5f});
    }
    EnergyOptions options;
    options.support_radius_px = 12.0;
    const NetworkLayout layout = BuildLayout(problem, options);
    ASSERT_EQ(layout.feature_neighbour_offsets.size(), static_cast<std::size_t>(n) + 1);
    for (int i = 0; i < n; ++i) {
      std::vector<std::int32_t> expected;
      for (int j = 0; j < n; ++j) {
        const auto d = (problem.left_points[static_cast<std::size_t>(j)] -
                        problem.left_points[static_cast<std::size_t>(i)]).cast<double>();
        if (d.squaredNorm() <= 144.0) expected.push_back(j);
      }
      const std::vector<std::int32_t> found(
          layout.feature_neighbours.begin() + layout.feature_neighbour_offsets[static_cast<std::size_t>(i)],
          layout.feature_neighbours.begin() + layout.feature_neighbour_offsets[static_cast<std::size_t>(i) + 1]);
      ASSERT_EQ(found, expected) << "feature " << i << " of " << n << " over " << extent << " px";
    }
  }
}

TEST(HopfieldNetwork, RefusesInconsistentProblems) {
  MatchingProblem problem = TwoByTwo();
  problem.candidates[1].epipolar_distance_px = std::nanf("");
  EXPECT_THROW(BuildLayout(problem, EnergyOptions{}), std::invalid_argument);
  problem = TwoByTwo();
  problem.candidates[2].column = 7;
  EXPECT_THROW(BuildLayout(problem, EnergyOptions{}), std::invalid_argument);
  problem = TwoByTwo();
  std::swap(problem.candidates[0], problem.candidates[1]);
  EXPECT_THROW(BuildLayout(problem, EnergyOptions{}), std::invalid_argument);
  EnergyOptions bad;
  bad.T = 0.0;
  EXPECT_THROW(BuildLayout(TwoByTwo(), bad), std::invalid_argument);
}

TEST(Activation, ContinuousDiscreteAndInverse) {
  EXPECT_DOUBLE_EQ(Activate(0.0, Activation::kContinuous, 0.5, 0.0), 0.5);
  EXPECT_NEAR(Activate(1.0, Activation::kContinuous, 0.5, 0.0), 0.5 * (1.0 + std::tanh(2.0)), 1e-15);
  EXPECT_DOUBLE_EQ(Activate(0.0, Activation::kDiscrete, 0.5, 1.0), 1.0) << "holds on zero input";
  EXPECT_DOUBLE_EQ(Activate(-0.1, Activation::kDiscrete, 0.5, 1.0), 0.0);
  EXPECT_NEAR(Activate(InverseActivation(0.3, 0.7), Activation::kContinuous, 0.7, 0.0), 0.3, 1e-12);
}

}  // namespace
}  // namespace hnnstereo::hnn
