#pragma once
// Reading matches out of the settled network (thesis fig. 6.10).

#include <optional>
#include <string_view>
#include <vector>

#include "host/hopfield_problem.h"

namespace hnnstereo::hnn {

enum class DecodeMethod {
  kThesisPruning,  ///< per row keep the largest activation, then per column, then threshold
  kOneToOne,       ///< greedy: strongest first, each row and column used once, threshold
};

std::string_view DecodeMethodName(DecodeMethod method);
std::optional<DecodeMethod> ParseDecodeMethod(std::string_view name);

struct DecodeOptions {
  DecodeMethod method = DecodeMethod::kThesisPruning;
  double threshold = 0.5;  ///< minimum activation of an accepted match
};

struct DecodedMatch {
  int neuron = 0;
  int left = 0;
  int column = 0;
  double activation = 0.0;  ///< the match's confidence
};

/// Matches sorted by left feature. Column uniqueness is enforced only for
/// feature-vs-feature networks. `potential` (the engines' u, optional) ranks the neurons when
/// given; ties go to the lower neuron index. The threshold applies to the activation.
std::vector<DecodedMatch> Decode(const MatchingProblem& problem,
                                 const std::vector<double>& activation,
                                 const DecodeOptions& options,
                                 const std::vector<double>* potential = nullptr);

}  // namespace hnnstereo::hnn
