#pragma once
// Shared pieces of the subcommands: a flat-YAML --config reader for CLI11, matcher options on
// the command line, and the OpenCL runtime with its fallback notice.

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "api/matcher_settings.h"
#include "host/opencl_runtime.h"
#include "vision/matcher_presets.h"
#include "vision/stereo_matcher.h"

namespace hnnstereo::app {

/// Expands `--config FILE.yml` (flat YAML: "long-option-name: value" per line, '#' comments,
/// `true`/`false` for flags, lists as [a, b]) into command-line arguments placed after the
/// subcommand; options given on the command line win. Returns `arguments` unchanged when there is
/// no --config. Throws std::runtime_error on an unreadable or malformed file.
std::vector<std::string> ExpandConfigArguments(const std::vector<std::string>& arguments);

/// Matcher options as command-line flags (features, gating, energy, dynamics, decoding).
struct MatcherFlags {
  vision::MatcherOptions options;
  std::string features = "canny";
  std::string engine = "opencl";
  std::string objective = "geometry-similarity";
  std::string preset = "hnn-default";
  bool no_left_right_check = false;
  vision::RefinementOptions refinement;  ///< from the preset, after Resolve()
  CLI::Option* objective_option = nullptr;
  CLI::Option* network_option = nullptr;
  CLI::Option* top_k_option = nullptr;
  CLI::Option* support_radius_option = nullptr;
  std::string initial_state = "off";
  std::string activation = "continuous";
  std::string decode = "thesis";
  std::string network = "feature";
  std::string zrange;
  double memory_budget_mb = 2048.0;
  std::string device;
  api::MatcherSettings settings;  ///< after Resolve(): the library's resolution of the flags
  /// Adds the flags to `cmd`.
  void AddTo(CLI::App* cmd);
  /// Parses the string-valued flags into `options` and applies the preset (its objective unless
  /// --objective was given, its refinements unless --no-lr-check) through
  /// api::ResolveMatcherSettings, as the library facade does; throws std::invalid_argument.
  void Resolve();
  /// The preset's feature-vs-disparity network needs rectified rows: for a calibrated,
  /// unrectified pair fall back to the feature-vs-feature network of preset hnn-geometry-lr
  /// (unless --network was given). Call after Resolve() once the geometry is known.
  void UseFeatureNetworkUnlessRectified(bool rectified);
};

/// The OpenCL runtime for `engine` == opencl (nullptr otherwise or when none exists, with a
/// notice on stderr).
std::unique_ptr<ocl::Runtime> OpenRuntimeFor(hnn::EngineKind engine, const std::string& device);

}  // namespace hnnstereo::app
