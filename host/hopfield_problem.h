#pragma once
// The matching problem handed to the Hopfield network (thesis 6.2.5): left features, right
// features, and the gated candidate pairs, one neuron each. Built by vision/ (candidate gating),
// solved by host/ engines. Plain data: no OpenCV, no OpenCL.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hnnstereo::hnn {

/// One neuron V_ik: "left feature i matches right feature k" (feature-vs-feature network), or
/// "left feature i has disparity level k" (feature-vs-disparity network, rectified pairs).
struct Candidate {
  int left = 0;                      ///< left feature index i (row of the network)
  int column = 0;                    ///< right feature index k, or disparity level
  Eigen::Vector2f right_point{0, 0}; ///< the right-image point of this match (pixels)
  float epipolar_distance_px = 0;    ///< tau_ik, eq. 6.14 (soft epipolar term)
  float correlation = 0;             ///< M_ik, ZNCC in [-1, 1] (eq. 6.9)
};

enum class NetworkKind {
  kFeatureVsFeature,    ///< rows = left features, columns = right features (thesis default)
  kFeatureVsDisparity,  ///< columns = disparity levels; uniqueness per left feature only
};

/// "feature" or "disparity": the names of `--network`, REPORT.json and EVAL.json.
inline std::string_view NetworkKindName(NetworkKind kind) {
  return kind == NetworkKind::kFeatureVsDisparity ? "disparity" : "feature";
}
inline std::optional<NetworkKind> ParseNetworkKind(std::string_view name) {
  if (name == "feature") return NetworkKind::kFeatureVsFeature;
  if (name == "disparity") return NetworkKind::kFeatureVsDisparity;
  return std::nullopt;
}

struct MatchingProblem {
  std::vector<Eigen::Vector2f> left_points;   ///< left features (pixels)
  int n_columns = 0;                          ///< right features, or disparity levels
  std::vector<Candidate> candidates;          ///< the neurons, sorted by (left, column)
  NetworkKind kind = NetworkKind::kFeatureVsFeature;
  /// true: the thesis's all-pairs network (every neuron connected to every neuron).
  /// false: compatibility only between neurons whose left features lie within the support radius.
  bool dense = false;

  int n_neurons() const { return static_cast<int>(candidates.size()); }
  int n_left() const { return static_cast<int>(left_points.size()); }
  /// Empty when consistent; otherwise a one-line reason (indices out of range, unsorted...).
  std::string Check() const;
};

/// A set of independent problems solved together (many networks per launch).
using ProblemBatch = std::vector<MatchingProblem>;

}  // namespace hnnstereo::hnn
