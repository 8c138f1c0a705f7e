#pragma once
// A second chance for the left features the disparity network leaves unmatched (no winner, or
// dropped by the left-right check: low texture, repetition, occlusion borders): a second, small
// Hopfield network over them whose candidates are the disparities of the matched neighbours
// around each one (a narrow band), with those matched neighbours in the same network as support
// (one neuron each, at its own disparity). Candidates from the disparities of confident
// neighbours are the support points of ELAS (Geiger, Roser & Urtasun, "Efficient Large-Scale
// Stereo Matching", ACCV 2010); the network, not winner-take-all, chooses among them.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "vision/stereo/candidates.h"

namespace hnnstereo::ocl {
class Runtime;
}

namespace hnnstereo::vision {

struct ConfidenceOptions;
struct MatcherOptions;
struct StereoMatch;

struct SecondChanceOptions {
  /// Retry the unmatched left features (rectified pairs, feature-vs-disparity network only).
  bool enabled = false;
  /// Matched neighbours within this distance (px, left image) of an unmatched feature give its
  /// candidate disparities and its support in the second network.
  double support_radius_px = 14.0;
  /// An unmatched feature is retried only when at least this many matched neighbours back it.
  int min_support = 3;
  /// Each neighbour's rounded disparity d makes levels d - band_margin .. d + band_margin
  /// candidates (only those, not the range between two neighbours on either side of an edge).
  int band_margin = 1;
  /// Keep the K most similar of a feature's candidate levels (0 = all).
  int top_k = 3;
  /// A second-chance winner is kept only when the confidence model (ConfidenceOptions, fitted
  /// on first-pass winners) gives it at least this. Chosen on the tuning pairs
  /// (docs/decisions.md): the lowest value of 0, 0.3, 0.4, ... 0.8 at which the matches it adds
  /// are at most half as often wrong (> 1 px) as StereoSGBM at the same pixels and the five
  /// shared pairs' precision within 1 px stays within 0.3 points of the first pass alone.
  double min_model_confidence = 0.5;
  /// A kept second-chance match's confidence is the model's times this, so that it ranks below
  /// first-pass matches of equal evidence: a winner among the levels its neighbours chose has a
  /// margin over fewer rivals than the model was fitted on (tests/vision/second_chance_test.cc).
  double confidence_scale = 0.5;
  /// A second network of fewer neurons than this is solved by the cpu engine whatever
  /// MatcherOptions::engine says: the opencl engine's fixed cost per network outweighs such a
  /// solve (Teddy at 5,000 features, 3,000 neurons: 56-81 ms on PoCL, 16 ms on the cpu engine,
  /// the same winners; 35,000 neurons: 666 against 800 ms). 0: always MatcherOptions::engine.
  int cpu_below_neurons = 10000;
  std::string Check() const;
};

/// What the second chance did (REPORT.json "second_chance").
struct SecondChanceReport {
  bool applied = false;
  int unmatched = 0;  ///< left features with no match after the first network and its check
  int retried = 0;    ///< of them, those with min_support matched neighbours: the network's rows
  int support = 0;    ///< matched features in the second network as support rows
  int neurons = 0;    ///< neurons of the second network
  int matched = 0;    ///< second-chance matches kept (left-right check, min_model_confidence)
  /// The second network did not fit MatcherOptions::memory_budget_bytes: nothing was retried.
  bool over_memory_budget = false;
  std::string engine;  ///< the engine that solved the second network ("" when none ran)
  double ms = 0.0;
};

/// Builds and solves the second network over the features of `left_features` that no match of
/// `matches` sits on (MatchReport::left_features and the refined matches of the same pair) and
/// returns its winners among them in `retried_matches` (left_index: the feature's index in
/// `left_features`; StereoMatch::second_chance set; not yet checked, refined or given a
/// confidence) and, per left feature, the band of levels it searched in `check_bands` (empty
/// bands for the others), for their left-right check. `similarity`: the data term's tables. A
/// second network over the memory budget retries nothing (report->over_memory_budget).
void RetryUnmatchedFeatures(const ZnccMatcher& similarity,
                            const std::vector<Eigen::Vector2f>& left_features,
                            const std::vector<StereoMatch>& matches, const MatcherOptions& matcher,
                            const SecondChanceOptions& options, ocl::Runtime* runtime,
                            std::vector<StereoMatch>* retried_matches,
                            std::vector<DisparityBand>* check_bands, SecondChanceReport* report);

/// Appends those of `retried` that the model `confidence` gives at least
/// options.min_model_confidence to `matches`, each with the model's confidence times
/// options.confidence_scale; the neighbourhood counts (CountAgreeingNeighbours, at `scale`) are
/// taken among all of them. The first-pass matches keep theirs. Returns how many were added.
int AddSecondChanceMatches(std::vector<StereoMatch> retried, const ConfidenceOptions& confidence,
                            const SecondChanceOptions& options, float scale,
                            std::vector<StereoMatch>* matches);

}  // namespace hnnstereo::vision
