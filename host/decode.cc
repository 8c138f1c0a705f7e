#include "host/decode.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>

namespace hnnstereo::hnn {

std::string_view DecodeMethodName(DecodeMethod method) {
  return method == DecodeMethod::kThesisPruning ? "thesis" : "one-to-one";
}

std::optional<DecodeMethod> ParseDecodeMethod(std::string_view name) {
  if (name == "thesis") return DecodeMethod::kThesisPruning;
  if (name == "one-to-one") return DecodeMethod::kOneToOne;
  return std::nullopt;
}

std::vector<DecodedMatch> Decode(const MatchingProblem& problem,
                                 const std::vector<double>& activation_in,
                                 const DecodeOptions& options,
                                 const std::vector<double>* potential) {
  if (potential && potential->empty()) potential = nullptr;  // engine gave none
  if (activation_in.size() != problem.candidates.size() ||
      (potential && potential->size() != activation_in.size())) {
    throw std::invalid_argument(
        "decode: " + std::to_string(activation_in.size()) + " activations and " +
        std::to_string(potential ? potential->size() : 0) + " potentials for " +
        std::to_string(problem.candidates.size()) + " neurons");
  }
  // Rank by the potential u when given (V = g(u) is monotone, so the order is the same in exact
  // arithmetic, but saturated activations tie in float while u still tells them apart).
  const std::vector<double>& rank = potential ? *potential : activation_in;
  const std::vector<double>& activation = activation_in;
  const bool column_uniqueness = problem.kind == NetworkKind::kFeatureVsFeature;
  const int n = problem.n_neurons();
  std::vector<DecodedMatch> matches;
  if (options.method == DecodeMethod::kThesisPruning) {
    // Row maxima.
    std::vector<int> row_winner(static_cast<std::size_t>(problem.n_left()), -1);
    for (int a = 0; a < n; ++a) {
      const int i = problem.candidates[static_cast<std::size_t>(a)].left;
      int& winner = row_winner[static_cast<std::size_t>(i)];
      if (winner < 0 || rank[static_cast<std::size_t>(a)] > rank[static_cast<std::size_t>(winner)]) {
        winner = a;
      }
    }
    // Column maxima among the row winners.
    std::vector<int> column_winner(static_cast<std::size_t>(problem.n_columns), -1);
    for (int winner : row_winner) {
      if (winner < 0) continue;
      if (!column_uniqueness) continue;
      const int k = problem.candidates[static_cast<std::size_t>(winner)].column;
      int& best = column_winner[static_cast<std::size_t>(k)];
      if (best < 0 || rank[static_cast<std::size_t>(winner)] > rank[static_cast<std::size_t>(best)]) {
        best = winner;
      }
    }
    for (int winner : row_winner) {
      if (winner < 0) continue;
      const Candidate& c = problem.candidates[static_cast<std::size_t>(winner)];
      if (column_uniqueness && column_winner[static_cast<std::size_t>(c.column)] != winner) continue;
      const double v = activation[static_cast<std::size_t>(winner)];
      if (v < options.threshold) continue;
      matches.push_back({winner, c.left, c.column, v});
    }
  } else {
    std::vector<int> order(static_cast<std::size_t>(n));
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return rank[static_cast<std::size_t>(a)] > rank[static_cast<std::size_t>(b)];
    });
    std::vector<char> row_used(static_cast<std::size_t>(problem.n_left()), 0);
    std::vector<char> column_used(static_cast<std::size_t>(problem.n_columns), 0);
    for (int a : order) {
      const double v = activation[static_cast<std::size_t>(a)];
      if (v < options.threshold) continue;
      const Candidate& c = problem.candidates[static_cast<std::size_t>(a)];
      if (row_used[static_cast<std::size_t>(c.left)]) continue;
      if (column_uniqueness && column_used[static_cast<std::size_t>(c.column)]) continue;
      row_used[static_cast<std::size_t>(c.left)] = 1;
      column_used[static_cast<std::size_t>(c.column)] = 1;
      matches.push_back({a, c.left, c.column, v});
    }
    std::sort(matches.begin(), matches.end(),
              [](const DecodedMatch& x, const DecodedMatch& y) { return x.left < y.left; });
  }
  return matches;
}

}  // namespace hnnstereo::hnn
