#pragma once
// Seeded synthetic matching problems for the engine tests (COLMAP habit: synthetic data from a
// seeded generator). A slanted plane seen by a rectified pair: left features at random, their
// true right partners shifted by a smooth disparity, plus distractor right features; candidates
// on the same row within a disparity range; the true partner correlates strongly.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "host/hopfield_problem.h"

namespace hnnstereo::hnn::testing {

inline MatchingProblem SyntheticProblem(std::uint64_t seed, int n_left, int n_distractors,
                                        bool dense = false, int max_per_row = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> x_dist(20.0f, 180.0f), y_dist(0.0f, 40.0f);
  std::uniform_real_distribution<float> weak(-0.3f, 0.6f), strong(0.8f, 0.98f);
  MatchingProblem problem;
  problem.dense = dense;
  std::vector<Eigen::Vector2f> right;
  for (int i = 0; i < n_left; ++i) {
    const Eigen::Vector2f l(x_dist(rng), std::round(y_dist(rng)));
    problem.left_points.push_back(l);
    const float disparity = 8.0f + 0.05f * l.x() + 0.1f * l.y();  // a slanted plane
    right.emplace_back(l.x() - disparity, l.y());
  }
  for (int k = 0; k < n_distractors; ++k) right.emplace_back(x_dist(rng) - 10.0f, std::round(y_dist(rng)));
  // Shuffle right features so that the true partner's index says nothing.
  std::vector<int> order(right.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<int> true_column(static_cast<std::size_t>(n_left));
  std::vector<Eigen::Vector2f> shuffled(right.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    shuffled[k] = right[static_cast<std::size_t>(order[k])];
    if (order[k] < n_left) true_column[static_cast<std::size_t>(order[k])] = static_cast<int>(k);
  }
  problem.n_columns = static_cast<int>(shuffled.size());
  for (int i = 0; i < n_left; ++i) {
    const Eigen::Vector2f& l = problem.left_points[static_cast<std::size_t>(i)];
    int kept = 0;
    for (int k = 0; k < problem.n_columns; ++k) {
      const Eigen::Vector2f& r = shuffled[static_cast<std::size_t>(k)];
      const float tau = std::abs(l.y() - r.y());
      const float d = l.x() - r.x();
      if (!dense && (tau > 1.0f || d < 0.0f || d > 40.0f)) continue;
      if (!dense && max_per_row > 0 && kept >= max_per_row && k != true_column[static_cast<std::size_t>(i)]) continue;
      const bool is_true = k == true_column[static_cast<std::size_t>(i)];
      problem.candidates.push_back({i, k, r, tau, is_true ? strong(rng) : weak(rng)});
      ++kept;
    }
  }
  return problem;
}

/// The same scene as a feature-vs-disparity network (hnn-default's kind: columns are integer
/// disparity levels 0..40, uniqueness per left feature only): each candidate takes the level of
/// its disparity; of two candidates of a row on one level the better correlated stays.
inline MatchingProblem SyntheticDisparityProblem(std::uint64_t seed, int n_left, int n_distractors,
                                                 int max_per_row = 0) {
  const MatchingProblem features =
      SyntheticProblem(seed, n_left, n_distractors, false, max_per_row);
  MatchingProblem problem;
  problem.kind = NetworkKind::kFeatureVsDisparity;
  problem.left_points = features.left_points;
  problem.n_columns = 41;
  std::vector<Candidate> row;
  auto flush = [&] {
    std::sort(row.begin(), row.end(),
              [](const Candidate& a, const Candidate& b) { return a.column < b.column; });
    for (const Candidate& c : row) problem.candidates.push_back(c);
    row.clear();
  };
  for (Candidate c : features.candidates) {
    if (!row.empty() && row.front().left != c.left) flush();
    const Eigen::Vector2f& l = problem.left_points[static_cast<std::size_t>(c.left)];
    c.column = std::clamp(static_cast<int>(std::lround(l.x() - c.right_point.x())), 0, 40);
    c.right_point = Eigen::Vector2f(l.x() - static_cast<float>(c.column), l.y());
    auto same = std::find_if(row.begin(), row.end(),
                             [&](const Candidate& o) { return o.column == c.column; });
    if (same == row.end()) {
      row.push_back(c);
    } else if (c.correlation > same->correlation) {
      *same = c;
    }
  }
  flush();
  return problem;
}

/// The thesis's Fig. 6.1: three left pixels A, B, C and four right pixels A'..D' on one scan
/// line, grey levels chosen so that the text's costs hold: |A-A'| = 2, |B-B'| = 1, |C-C'| = 0,
/// |A-B'| = 1, |B-C'| = 2, |C-A'| = 6. Greedy local search pairs A-B', B-C', C-A' (cost 9); the
/// global optimum is A-A', B-B', C-C' (cost 3). The cost enters as the bias term (D tau).
inline constexpr float kToyLeftGrey[3] = {10.0f, 8.0f, 6.0f};
inline constexpr float kToyRightGrey[4] = {12.0f, 9.0f, 6.0f, 20.0f};

inline MatchingProblem Figure61Problem() {
  MatchingProblem problem;
  problem.dense = true;
  problem.n_columns = 4;
  for (int i = 0; i < 3; ++i) problem.left_points.emplace_back(static_cast<float>(10 * i), 0.0f);
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 4; ++k) {
      const float cost = std::abs(kToyLeftGrey[i] - kToyRightGrey[k]);
      problem.candidates.push_back(
          {i, k, Eigen::Vector2f(static_cast<float>(10 * k), 0.0f), cost, 0.0f});
    }
  }
  return problem;
}

}  // namespace hnnstereo::hnn::testing
