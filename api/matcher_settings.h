#pragma once
// Matcher settings from a preset name and overrides named like the CLI's flags: the one place
// where "preset + what the user changed" becomes MatcherOptions and RefinementOptions, for the
// library facade, the Python module and the CLI alike (STYLE.md 14: one source of truth for
// settings; app/cli_support.cc, MatcherFlags::Resolve, hands its flags here). The tests
// api_hnnstereo_facade_test and python_hnnstereo check that the CLI, the facade and Python give
// the same matches.

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::api {

using Overrides = std::map<std::string, std::string>;

struct MatcherSettings {
  std::string preset = "hnn-default";
  vision::MatcherOptions matcher;
  vision::RefinementOptions refinement;
  std::string device;  ///< OpenCL device (index or name substring); empty = environment
  Overrides given;     ///< the overrides as given (names without dashes)
};

/// The names ResolveMatcherSettings accepts (the CLI's matcher flags without the dashes).
std::vector<std::string> OverrideNames();

/// `base` (MatcherOptions{} for `match`; eval: the preset's own), then the preset's
/// compatibility, network, gating, data term, dynamics and refinements unless overridden, then
/// the overrides; a setting neither sets keeps the base's value. Throws std::invalid_argument
/// naming an unknown preset or option, or a bad value.
MatcherSettings ResolveMatcherSettings(const std::string& preset, const Overrides& overrides,
                                       const vision::MatcherOptions& base);

/// The settings of a calibrated pick cell, for `pick`, `serve` and the facade's SensePositions:
/// preset hnn-default over `base` (PickCellMatcherOptions()), its feature-network fallback
/// (the cell is unrectified), then the base's top-K, support radius and dynamics unless given.
MatcherSettings ResolvePickCellSettings(const Overrides& overrides,
                                        const vision::MatcherOptions& base);

/// The feature-vs-disparity network needs rectified rows: on a calibrated, unrectified pair fall
/// back to the feature-vs-feature network of preset hnn-geometry-lr (unless "network" was given).
void UseFeatureNetworkUnlessRectified(bool rectified, MatcherSettings* settings);

/// A field name -> option name table, e.g. {"time_step", "--dt"}.
using OptionNameTable = std::vector<std::pair<std::string, std::string>>;

/// `message` (an options struct's Check()) with every whole-word field name of `table` replaced
/// by the option that sets it, so errors name what the user typed: one way to name options in
/// errors, for the CLI, the facade and Python.
std::string InOptionNames(std::string message, const OptionNameTable& table);

/// The matcher's fields and their `match` options (the names ResolveMatcherSettings accepts).
const OptionNameTable& MatcherOptionNameTable();

}  // namespace hnnstereo::api
