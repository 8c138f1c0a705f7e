#pragma once
// The whole match: features -> candidates -> weights -> dynamics -> decoded matches. One call
// that `match`, `bench` and `eval` share; a drop-in fast matcher for the pick cell.

#include <Eigen/Core>
#include <array>
#include <functional>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "host/decode.h"
#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/opencl_engine.h"
#include "host/opencl_runtime.h"
#include "host/solve_report.h"
#include "vision/stereo/candidates.h"
#include "vision/stereo/coarse_to_fine.h"
#include "vision/stereo/second_chance.h"
#include "vision/features/features.h"

namespace hnnstereo::vision {

std::string_view EngineName(hnn::EngineKind engine);
std::optional<hnn::EngineKind> ParseEngine(std::string_view name);

/// Radii (px, left image) of the neighbourhoods whose matches vote on a match's confidence:
/// 3 and 6 px (the local surface), 12 px (the network's support radius) and 24 px.
inline constexpr std::array<float, 4> kAgreementRadiiPx = {3.0f, 6.0f, 12.0f, 24.0f};
/// A neighbour at distance s px agrees when its displacement is within 1 px + slope * s of the
/// match's: 0 for the three inner radii; 0.1 px per px on the 24 px ring, so that a slanted
/// surface (a disparity gradient up to 0.1) still agrees with itself there.
inline constexpr std::array<float, 4> kAgreementSlope = {0.0f, 0.0f, 0.0f, 0.1f};
/// The local surface: a plane fitted (least squares) to the displacements of the other matches
/// within this radius (px, left image).
inline constexpr float kSurfaceRadiusPx = 12.0f;
/// surface_residual's value (px) when it cannot be fitted (fewer than 4 neighbours), and its cap.
inline constexpr float kSurfaceResidualCapPx = 5.0f;

/// The per-match confidence (docs/accuracy.md, "Confidence"): a logistic model of what the
/// settled network and its neighbouring winners know about each winner,
///   confidence = 1 / (1 + exp(-z)),
///   z = bias + w_potential_margin * min(potential_margin, cap)
///     + w_correlation * correlation + w_correlation_margin * correlation_margin
///     + sum_r ( w_agreement[r] * agreement_r + w_neighbours[r] * neighbours_r )
///     + w_surface_residual * surface_residual,
/// where potential_margin = u(winner) - u(best other neuron of its row) (at equilibrium
/// u = sum_b W_ab V_b + I_a: the winner's lead in support over its runner-up);
/// correlation = the winner's similarity (the data term's: census in hnn-default, ZNCC
/// otherwise), correlation_margin = it minus the best other candidate's of the row; for r in
/// kAgreementRadiiPx, neighbours_r = the other decoded matches whose left point lies within r px,
/// agreement_r = the share of them whose displacement (right - left point) agrees with this match's
/// (kAgreementSlope; 0 with no neighbour); surface_residual = the distance (px) of this match's
/// displacement from the plane fitted to its neighbours' within kSurfaceRadiusPx (capped at
/// kSurfaceResidualCapPx). A wrong winner is one its surface does not back, and dense, agreeing
/// neighbourhoods are textured surfaces the network resolved. Weights fitted by logistic
/// regression (correct = within 1 px of the ground truth) on the five shared Middlebury pairs
/// (scripts/fit_confidence.py; figures in docs/accuracy.md), one model per data term, since the
/// similarity is one of the inputs: these defaults are the ZNCC data term's (the feature
/// network's: `match --calib`, `pick`, `serve`); CensusConfidenceOptions() is hnn-default's.
struct ConfidenceOptions {
  double bias = -7.90734;
  double w_potential_margin = 5.97741e-05;
  double w_correlation = 4.22575;
  double w_correlation_margin = 0.399208;
  std::array<double, 4> w_agreement = {0.191842, 0.748735, 1.78553,
                                       2.14769};  ///< per kAgreementRadiiPx
  std::array<double, 4> w_neighbours = {-0.000448942, 0.0182109, 0.0133881,
                                        0.00269549};  ///< per kAgreementRadiiPx
  double w_surface_residual = -0.058943;              ///< per px
  double potential_margin_cap = 1e4;  ///< clamps absurd margins (none seen above ~1,500)
  std::string Check() const;
};

struct MatcherOptions {
  FeatureOptions features;          ///< same detector on both images
  CandidateOptions candidates;
  int zncc_window = 7;              ///< thesis: 7 (or 5)
  /// The similarity of windows (vision/correlation.h): ZNCC here; census in hnn-default.
  DataTermOptions data_term;
  hnn::EnergyOptions energy;
  hnn::DynamicsOptions dynamics;
  hnn::DecodeOptions decode;
  ConfidenceOptions confidence;
  /// Drop decoded matches whose confidence is below this (0 keeps all): trades density for
  /// precision (docs/accuracy.md, "Ranked by confidence").
  double min_confidence = 0.0;
  hnn::EngineKind engine = hnn::EngineKind::kOpenCL;
  hnn::OpenClEngineOptions opencl;  ///< weight storage and work split of the opencl engine
  std::size_t memory_budget_bytes = hnn::kDefaultMemoryBudgetBytes;
  /// A sparse network over the memory budget matches an evenly spread share of the left
  /// features that fits (MatchReport::memory_fit says how many) instead of refusing the pair.
  bool fit_memory_budget = true;
  /// Camera-sized rectified pairs: a half-size match first, then each feature searches a band
  /// of disparities around it (vision/stereo/coarse_to_fine.h).
  CoarseToFineOptions coarse_to_fine;
  /// Called with the network (problem, energy, dynamics) before it is solved, when set: `match
  /// --save-network` captures it for replays on other devices (host/network_file.h).
  std::function<void(const hnn::MatchingProblem&, const hnn::EnergyOptions&,
                     const hnn::DynamicsOptions&)>
      network_observer;
  std::string Check() const;
};

struct StereoMatch {
  Eigen::Vector2f left;
  Eigen::Vector2f right;
  float activation;  ///< the winner's final V (saturates near 1: not a ranking)
  int left_index;
  int column;
  /// In [0, 1], higher = more likely correct; ranks matches (ConfidenceOptions).
  float confidence = 0.0f;
  float potential_margin = 0.0f;    ///< u(winner) - u(best other neuron of its row)
  float correlation = 0.0f;         ///< the winner's similarity (data term: census or ZNCC)
  float correlation_margin = 0.0f;  ///< it - the best other candidate's of the row
  /// Per kAgreementRadiiPx: other decoded matches within r px (left image), and how many of them
  /// have a displacement that agrees with this one's (kAgreementSlope; ConfidenceOptions).
  std::array<std::int32_t, 4> neighbours = {0, 0, 0, 0};
  std::array<std::int32_t, 4> agreeing = {0, 0, 0, 0};
  /// |displacement - the plane of the neighbours' displacements within kSurfaceRadiusPx| (px).
  float surface_residual = kSurfaceResidualCapPx;
  /// Matched by the second network over the features the first left unmatched
  /// (vision/stereo/second_chance.h); its confidence carries SecondChanceOptions' penalty.
  bool second_chance = false;
};

/// The confidence model fitted for the census data term (hnn-default, DataTermOptions): it weighs
/// the potential margin and the surface residual 0 - fitted with the rest, their weights came
/// out with the sign that would rank a better-supported match lower, for no gain out of sample.
ConfidenceOptions CensusConfidenceOptions();

/// The confidence model fitted for `data_term` (ConfidenceOptions{} for ZNCC).
ConfidenceOptions ConfidenceOptionsFor(const DataTermOptions& data_term);

/// The confidence of `match` from its potential_margin, correlations and neighbourhood counts.
float MatchConfidence(const StereoMatch& match, const ConfidenceOptions& options);

/// Fills `neighbours`, `agreeing` and `surface_residual` of every match (ConfidenceOptions) from
/// the others' left points and displacements: a uniform grid of 24 px cells, so O(n) for evenly
/// spread features. `scale` < 1 counts in an image `scale` times the size (points and
/// displacements scaled; surface_residual is in those pixels).
void CountAgreeingNeighbours(std::vector<StereoMatch>& matches, float scale = 1.0f);

struct TimingMs {
  double features = 0, candidates = 0, network = 0, weights = 0, solve = 0, decode = 0, total = 0;
  double coarse = 0;  ///< the half-size match of a coarse-to-fine pair (part of candidates' time)
  double second_chance = 0;  ///< the second network and its checks (a refinement: in total)
};

struct MatchReport {
  std::vector<StereoMatch> matches;
  std::vector<Eigen::Vector2f> left_features, right_features;
  hnn::SolveReport solve;
  int n_left = 0, n_right = 0, n_neurons = 0;
  std::int64_t n_connections = 0;
  std::string engine_notice;  ///< e.g. why the opencl engine fell back to cpu
  TimingMs timing_ms;
  /// The similarity of windows the candidates were scored with, on the matched pair: the
  /// refinement (RefineMatches) reuses it instead of computing the images' tables again.
  std::shared_ptr<const ZnccMatcher> similarity;
  /// Coarse-to-fine pairs (CoarseBands; one per left feature of the network, empty otherwise):
  /// the disparity levels each left feature searched, and those its left-right check searches.
  std::vector<DisparityBand> disparity_bands, check_bands;
  CoarseToFineReport coarse_to_fine;
  /// What the second chance over the unmatched features did (RefinementOptions::second_chance).
  SecondChanceReport second_chance;
  /// What fit_memory_budget chose, when the network over every left feature did not fit.
  struct MemoryFit {
    bool applied = false;
    std::size_t needed_bytes = 0;    ///< what the network over every left feature needed
    int left_features_matched = 0;   ///< the share of the n_left features the network matched
  } memory_fit;
};

/// Solves `problem` on options.engine with options.energy and options.dynamics; the opencl engine
/// without a runtime falls back to the cpu engine and says so in `engine_notice`.
hnn::SolveReport SolveMatchingNetwork(const hnn::MatchingProblem& problem,
                                      const MatcherOptions& options, ocl::Runtime* runtime,
                                      std::string* engine_notice);

/// The decoded winners as matches, each with its margins over the best other neuron of its row
/// (StereoMatch::potential_margin, correlation_margin; `u`: the settled potentials, B: the row
/// inhibition). The neighbourhood counts and the confidence are left to the caller.
std::vector<StereoMatch> MatchesWithMargins(const hnn::MatchingProblem& problem,
                                            const std::vector<hnn::DecodedMatch>& decoded,
                                            const std::vector<double>& u, double B);

/// Runs the matcher on CV_8U grey images of equal size. `calibration` may be null only for
/// rectified pairs. `runtime` is used by the opencl engine; when it is null that engine falls
/// back to cpu and says so in engine_notice. Throws std::invalid_argument / std::runtime_error
/// with a one-line reason (no features, no candidates, over the memory budget...).
MatchReport MatchStereo(const cv::Mat& left_grey, const cv::Mat& right_grey,
                        const calib::StereoCalibration* calibration, const MatcherOptions& options,
                        ocl::Runtime* runtime);

}  // namespace hnnstereo::vision
