#include "api/matcher_settings.h"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "vision/features/features.h"

namespace hnnstereo::api {
namespace {

std::string Quoted(const std::string& name) { return "'" + name + "'"; }

double ParseDouble(const std::string& name, const std::string& value) {
  std::size_t used = 0;
  double number = 0.0;
  try {
    number = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size()) {
    throw std::invalid_argument("option " + Quoted(name) + " needs a number (got '" + value + "')");
  }
  // std::stod reads "nan" and "inf"; no option means either, and a NaN passes every "x < limit"
  // check downstream unnoticed.
  if (!std::isfinite(number)) {
    throw std::invalid_argument("option " + Quoted(name) + " needs a finite number (got '" +
                                value + "')");
  }
  return number;
}

// Largest --memory-budget-mb, 2^40 MB: beyond any machine, and its bytes still fit a size_t.
constexpr double kMaxMemoryBudgetMb = 1099511627776.0;

long long ParseInteger(const std::string& name, const std::string& value) {
  std::size_t used = 0;
  long long number = 0;
  try {
    number = std::stoll(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size()) {
    throw std::invalid_argument("option " + Quoted(name) + " needs an integer (got '" + value + "')");
  }
  return number;
}

int ParseInt(const std::string& name, const std::string& value) {
  const long long number = ParseInteger(name, value);
  if (number < INT32_MIN || number > INT32_MAX) {
    throw std::invalid_argument("option " + Quoted(name) + " is out of range (got '" + value + "')");
  }
  return static_cast<int>(number);
}

bool ParseFlag(const std::string& name, const std::string& value) {
  if (value.empty() || value == "true" || value == "1" || value == "on" || value == "yes") return true;
  if (value == "false" || value == "0" || value == "off" || value == "no") return false;
  throw std::invalid_argument("option " + Quoted(name) + " is a flag: true or false (got '" + value + "')");
}

using Setter = std::function<void(const std::string& name, const std::string& value,
                                  vision::MatcherOptions& o)>;

// The CLI's numeric flags and switches, bound straight to the options (app/cli_support.cc).
const std::map<std::string, Setter>& DirectOptions() {
  static const std::map<std::string, Setter> options = {
      {"max-features", [](auto& n, auto& v, auto& o) { o.features.max_features = ParseInt(n, v); }},
      {"canny-low", [](auto& n, auto& v, auto& o) { o.features.canny_low = ParseDouble(n, v); }},
      {"canny-high", [](auto& n, auto& v, auto& o) { o.features.canny_high = ParseDouble(n, v); }},
      {"min-disparity", [](auto& n, auto& v, auto& o) { o.candidates.min_disparity = ParseDouble(n, v); }},
      {"max-disparity", [](auto& n, auto& v, auto& o) { o.candidates.max_disparity = ParseDouble(n, v); }},
      {"max-epipolar",
       [](auto& n, auto& v, auto& o) { o.candidates.max_epipolar_distance_px = ParseDouble(n, v); }},
      {"top-k", [](auto& n, auto& v, auto& o) { o.candidates.top_k = ParseInt(n, v); }},
      {"dense", [](auto& n, auto& v, auto& o) { o.candidates.dense = ParseFlag(n, v); }},
      {"zncc-window", [](auto& n, auto& v, auto& o) { o.zncc_window = ParseInt(n, v); }},
      {"support-radius",
       [](auto& n, auto& v, auto& o) { o.energy.support_radius_px = ParseDouble(n, v); }},
      {"A", [](auto& n, auto& v, auto& o) { o.energy.A = ParseDouble(n, v); }},
      {"B", [](auto& n, auto& v, auto& o) { o.energy.B = ParseDouble(n, v); }},
      {"C", [](auto& n, auto& v, auto& o) { o.energy.C = ParseDouble(n, v); }},
      {"D", [](auto& n, auto& v, auto& o) { o.energy.D = ParseDouble(n, v); }},
      {"lambda", [](auto& n, auto& v, auto& o) { o.energy.lambda = ParseDouble(n, v); }},
      {"theta", [](auto& n, auto& v, auto& o) { o.energy.theta = ParseDouble(n, v); }},
      {"distance-attenuation",
       [](auto& n, auto& v, auto& o) { o.energy.distance_attenuation = ParseFlag(n, v); }},
      {"T", [](auto& n, auto& v, auto& o) { o.energy.T = ParseDouble(n, v); }},
      {"min-correlation",
       [](auto& n, auto& v, auto& o) { o.candidates.min_correlation = ParseDouble(n, v); }},
      {"alpha", [](auto& n, auto& v, auto& o) { o.dynamics.alpha = ParseDouble(n, v); }},
      {"seed",
       [](auto& n, auto& v, auto& o) {
         const long long seed = ParseInteger(n, v);
         if (seed < 0) throw std::invalid_argument("option 'seed' must be >= 0 (got '" + v + "')");
         o.dynamics.seed = static_cast<std::uint64_t>(seed);
       }},
      {"dt", [](auto& n, auto& v, auto& o) { o.dynamics.time_step = ParseDouble(n, v); }},
      {"max-steps", [](auto& n, auto& v, auto& o) { o.dynamics.max_steps = ParseInt(n, v); }},
      {"max-updates", [](auto& n, auto& v, auto& o) { o.dynamics.max_updates = ParseInt(n, v); }},
      {"threshold", [](auto& n, auto& v, auto& o) { o.decode.threshold = ParseDouble(n, v); }},
      {"min-confidence", [](auto& n, auto& v, auto& o) { o.min_confidence = ParseDouble(n, v); }},
      {"fit-memory-budget",
       [](auto& n, auto& v, auto& o) { o.fit_memory_budget = ParseFlag(n, v); }},
      {"coarse-to-fine-mp",
       [](auto& n, auto& v, auto& o) { o.coarse_to_fine.min_megapixels = ParseDouble(n, v); }},
      {"check-interval",
       [](auto& n, auto& v, auto& o) { o.dynamics.energy_interval = ParseInt(n, v); }},
  };
  return options;
}

// An enum's value by its library name (Parse*), or std::invalid_argument naming the option, the
// value and the choices.
template <class Enum>
Enum Named(const std::string& option, const std::string& value, std::optional<Enum> parsed,
           const std::string& choices) {
  if (!parsed) {
    throw std::invalid_argument("unknown " + option + " '" + value + "'" +
                                (choices.empty() ? "" : " (" + choices + ")"));
  }
  return *parsed;
}

// --zrange ZMIN,ZMAX (mm).
std::pair<double, double> ParseZRange(const std::string& zrange) {
  double zmin = 0, zmax = 0;
  char comma = 0;
  std::istringstream in(zrange);
  if (!(in >> zmin >> comma >> zmax) || comma != ',' || !(zmin < zmax)) {
    throw std::invalid_argument("zrange must be ZMIN,ZMAX with ZMIN < ZMAX (got '" + zrange + "')");
  }
  return {zmin, zmax};
}

// MB as the user gives it -> bytes. Bounded above so that the conversion is defined (inf or
// 1e300 would not fit a size_t: undefined behaviour, seen as a budget of 0 MB).
std::size_t ParseMemoryBudget(const std::string& name, const std::string& value) {
  const double megabytes = ParseDouble(name, value);
  if (!(megabytes > 0) || !(megabytes <= kMaxMemoryBudgetMb)) {
    throw std::invalid_argument("memory-budget-mb must be a number in (0, 1099511627776] (is " +
                                value + ")");
  }
  return static_cast<std::size_t>(megabytes * static_cast<double>(hnn::kBytesPerMegabyte));
}

using NamedSetter =
    std::function<void(const std::string& name, const std::string& value, MatcherSettings& s)>;

// The settings applied after the preset, over it: names of enums (the library's Parse*
// functions), the preset's refinements and data-term details, and the run's resources. A name
// not given keeps the base's value (or the preset's, ApplyPreset).
const std::map<std::string, NamedSetter>& NamedOptions() {
  static const std::map<std::string, NamedSetter> options = {
      {"features",
       [](auto& n, auto& v, auto& s) {
         s.matcher.features.detector = Named(n, v, vision::ParseFeatureDetector(v), "");
       }},
      {"engine",
       [](auto& n, auto& v, auto& s) {
         s.matcher.engine = Named(n, v, vision::ParseEngine(v), "opencl, cpu or thesis");
       }},
      {"objective",
       [](auto& n, auto& v, auto& s) {
         s.matcher.energy.objective = Named(n, v, hnn::ParseObjective(v), "");
       }},
      {"init",
       [](auto& n, auto& v, auto& s) {
         s.matcher.dynamics.initial_state = Named(n, v, hnn::ParseInitialState(v), "");
       }},
      {"activation",
       [](auto& n, auto& v, auto& s) {
         s.matcher.dynamics.activation = Named(n, v, hnn::ParseActivation(v), "");
       }},
      {"stop",
       [](auto& n, auto& v, auto& s) {
         s.matcher.dynamics.stop_rule = Named(n, v, hnn::ParseStopRule(v), "energy or decisions");
       }},
      {"weights",
       [](auto& n, auto& v, auto& s) {
         s.matcher.opencl.storage =
             Named(n, v, hnn::ParseWeightStorage(v), hnn::WeightStorageNames());
       }},
      {"decode",
       [](auto& n, auto& v, auto& s) {
         s.matcher.decode.method = Named(n, v, hnn::ParseDecodeMethod(v), "");
       }},
      {"network",
       [](auto& n, auto& v, auto& s) {
         s.matcher.candidates.kind = Named(n, v, hnn::ParseNetworkKind(v), "feature or disparity");
       }},
      {"data-term",
       [](auto& n, auto& v, auto& s) {
         s.matcher.data_term.kind = Named(n, v, vision::ParseDataTermKind(v), "census or zncc");
         s.matcher.confidence = vision::ConfidenceOptionsFor(s.matcher.data_term);  // fitted for it
       }},
      {"census-window",
       [](auto& n, auto& v, auto& s) { s.matcher.data_term.census_window = ParseInt(n, v); }},
      {"aggregation-window",
       [](auto& n, auto& v, auto& s) { s.matcher.data_term.aggregation_window = ParseInt(n, v); }},
      {"support-gamma",
       [](auto& n, auto& v, auto& s) { s.matcher.data_term.support_gamma = ParseDouble(n, v); }},
      {"zncc-peaks",
       [](auto& n, auto& v, auto& s) { s.matcher.candidates.zncc_peaks = ParseFlag(n, v); }},
      {"subpixel-peaks",
       [](auto& n, auto& v, auto& s) { s.matcher.candidates.subpixel_peaks = ParseFlag(n, v); }},
      {"zrange", [](auto&, auto& v, auto& s) { s.matcher.candidates.z_range_mm = ParseZRange(v); }},
      {"memory-budget-mb",
       [](auto& n, auto& v, auto& s) { s.matcher.memory_budget_bytes = ParseMemoryBudget(n, v); }},
      {"device", [](auto&, auto& v, auto& s) { s.device = v; }},
      {"lr-check",
       [](auto& n, auto& v, auto& s) { s.refinement.left_right_check = ParseFlag(n, v); }},
      {"no-lr-check",
       [](auto& n, auto& v, auto& s) {
         if (ParseFlag(n, v)) s.refinement.left_right_check = false;
       }},
      {"lr-tolerance",
       [](auto& n, auto& v, auto& s) { s.refinement.left_right_tolerance_px = ParseDouble(n, v); }},
      {"subpixel", [](auto& n, auto& v, auto& s) { s.refinement.subpixel = ParseFlag(n, v); }},
      {"subpixel-min-offset",
       [](auto& n, auto& v, auto& s) { s.refinement.subpixel_min_offset_px = ParseDouble(n, v); }},
      {"epipolar-snap",
       [](auto& n, auto& v, auto& s) { s.refinement.epipolar_snap = ParseFlag(n, v); }},
      {"epipolar-subpixel",
       [](auto& n, auto& v, auto& s) { s.refinement.epipolar_subpixel = ParseFlag(n, v); }},
      {"second-chance",
       [](auto& n, auto& v, auto& s) { s.refinement.second_chance.enabled = ParseFlag(n, v); }},
  };
  return options;
}

// "max_features" (Python keyword) and "--max-features" (command line) mean "max-features".
std::string CanonicalName(std::string name) {
  while (!name.empty() && name.front() == '-') name.erase(0, 1);
  for (char& c : name) {
    if (c == '_') c = '-';
  }
  return name;
}

}  // namespace

std::vector<std::string> OverrideNames() {
  std::vector<std::string> names;
  for (const auto& [name, setter] : DirectOptions()) names.push_back(name);
  for (const auto& [name, setter] : NamedOptions()) names.push_back(name);
  return names;
}

namespace {

// The preset's compatibility, network, gating, data term, dynamics and refinements over the base,
// except what `settings.given` names (the overrides, applied after).
void ApplyPreset(const vision::MatcherPreset& chosen, MatcherSettings& settings) {
  vision::MatcherOptions& o = settings.matcher;
  const auto given = [&](const char* name) { return settings.given.count(name) > 0; };
  settings.refinement = chosen.refinement;
  o.energy.objective = chosen.matcher.energy.objective;
  const vision::CandidateOptions& preset_candidates = chosen.matcher.candidates;
  if (!given("network")) {
    o.candidates.kind = preset_candidates.kind;
    o.candidates.zncc_peaks = preset_candidates.zncc_peaks;
    o.candidates.subpixel_peaks = preset_candidates.subpixel_peaks;
  }
  if (!given("top-k")) o.candidates.top_k = preset_candidates.top_k;
  o.data_term = chosen.matcher.data_term;
  o.confidence = chosen.matcher.confidence;
  if (!given("support-radius")) {
    o.energy.support_radius_px = chosen.matcher.energy.support_radius_px;
  }
  // The stop rule and the check interval (hnn-default: decisions, every 2 steps, twice in a
  // row; docs/engine.md).
  o.dynamics.stop_rule = chosen.matcher.dynamics.stop_rule;
  if (!given("check-interval")) {
    o.dynamics.energy_interval = chosen.matcher.dynamics.energy_interval;
    o.dynamics.stable_checks = chosen.matcher.dynamics.stable_checks;
  }
}

vision::MatcherPreset PresetNamed(const std::string& preset) {
  const std::optional<vision::MatcherPreset> chosen = vision::FindPreset(preset);
  if (!chosen) {
    std::string names;
    for (const vision::MatcherPreset& p : vision::AllPresets()) {
      names += (names.empty() ? "" : ", ") + p.name;
    }
    throw std::invalid_argument("unknown preset '" + preset + "' (" + names + ")");
  }
  return *chosen;
}

}  // namespace

MatcherSettings ResolveMatcherSettings(const std::string& preset, const Overrides& overrides,
                                       const vision::MatcherOptions& base) {
  MatcherSettings settings;
  settings.preset = preset;
  settings.matcher = base;
  vision::MatcherOptions& o = settings.matcher;
  for (const auto& [raw_name, value] : overrides) {
    const std::string name = CanonicalName(raw_name);
    settings.given[name] = value;
    if (auto direct = DirectOptions().find(name); direct != DirectOptions().end()) {
      direct->second(name, value, o);
    } else if (NamedOptions().count(name) == 0) {
      throw std::invalid_argument("unknown option " + Quoted(raw_name) +
                                  " (the match command's flags without dashes, e.g. max-features)");
    }
  }
  // The library allows 0 steps (sizing a network); from a user it would solve nothing.
  if (settings.given.count("max-steps") > 0 && o.dynamics.max_steps < 1) {
    throw std::invalid_argument("--max-steps must be >= 1 (0 steps leave every neuron where it "
                                "started: no match)");
  }
  ApplyPreset(PresetNamed(preset), settings);
  for (const auto& [name, value] : settings.given) {
    if (auto named = NamedOptions().find(name); named != NamedOptions().end()) {
      named->second(name, value, settings);
    }
  }
  // The geometry (rectified or not) is settled by the call; check the rest now.
  vision::MatcherOptions rest = o;
  rest.candidates.rectified = true;
  if (auto error = rest.Check(); !error.empty()) {
    throw std::invalid_argument(InOptionNames(error, MatcherOptionNameTable()));
  }
  if (auto error = settings.refinement.Check(); !error.empty()) {
    throw std::invalid_argument(InOptionNames(error, MatcherOptionNameTable()));
  }
  return settings;
}

void UseFeatureNetworkUnlessRectified(bool rectified, MatcherSettings* settings) {
  vision::MatcherOptions& o = settings->matcher;
  if (rectified || o.candidates.kind != hnn::NetworkKind::kFeatureVsDisparity) return;
  if (settings->given.count("network") > 0) return;  // the user asked; Check() says no
  const std::optional<vision::MatcherPreset> fallback = vision::FindPreset("hnn-geometry-lr");
  o.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
  o.candidates.zncc_peaks = false;
  o.candidates.subpixel_peaks = false;
  // The feature network's data term is ZNCC (hnn-geometry-lr), unless the user asked.
  if (settings->given.count("data-term") == 0) {
    o.data_term = vision::DataTermOptions{};
    o.confidence = vision::ConfidenceOptionsFor(o.data_term);
  }
  if (fallback) {
    if (settings->given.count("top-k") == 0) o.candidates.top_k = fallback->matcher.candidates.top_k;
    if (settings->given.count("support-radius") == 0) {
      o.energy.support_radius_px = fallback->matcher.energy.support_radius_px;
    }
  }
}

MatcherSettings ResolvePickCellSettings(const Overrides& overrides,
                                        const vision::MatcherOptions& base) {
  MatcherSettings settings = ResolveMatcherSettings("hnn-default", overrides, base);
  UseFeatureNetworkUnlessRectified(false, &settings);
  // What the preset set and the user did not give is the pick cell's own
  // (tests/app/pick_library_defaults_test.cc).
  const auto given = [&](const char* name) { return settings.given.count(name) > 0; };
  vision::MatcherOptions& o = settings.matcher;
  if (!given("stop")) o.dynamics.stop_rule = base.dynamics.stop_rule;
  if (!given("check-interval")) {
    o.dynamics.energy_interval = base.dynamics.energy_interval;
    o.dynamics.stable_checks = base.dynamics.stable_checks;
  }
  if (!given("top-k")) o.candidates.top_k = base.candidates.top_k;
  if (!given("support-radius")) o.energy.support_radius_px = base.energy.support_radius_px;
  return settings;
}

std::string InOptionNames(std::string message, const OptionNameTable& table) {
  auto is_word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
  for (const auto& [field, option] : table) {
    for (std::size_t at = message.find(field); at != std::string::npos;
         at = message.find(field, at + 1)) {
      const std::size_t end = at + field.size();
      if ((at > 0 && (is_word(message[at - 1]) || message[at - 1] == '-')) ||
          (end < message.size() && is_word(message[end]))) {
        continue;
      }
      message.replace(at, field.size(), option);
      at += option.size() - 1;
    }
  }
  return message;
}

const OptionNameTable& MatcherOptionNameTable() {
  static const OptionNameTable table = {
      {"time_step", "--dt"},
      {"max_steps", "--max-steps"},
      {"max_updates", "--max-updates"},
      {"alpha", "--alpha"},
      {"theta", "--theta"},
      {"lambda", "--lambda"},
      {"support_radius_px", "--support-radius"},
      {"top_k", "--top-k"},
      {"min_disparity", "--min-disparity"},
      {"max_disparity", "--max-disparity"},
      {"max_epipolar_distance_px", "--max-epipolar"},
      {"zncc_window", "--zncc-window"},
      {"min_confidence", "--min-confidence"},
      {"max_features", "--max-features"},
      {"left_right_tolerance_px", "--lr-tolerance"},
      {"subpixel_min_offset_px", "--subpixel-min-offset"},
      {"data_term.census_window", "--census-window"},
      {"data_term.aggregation_window", "--aggregation-window"},
      {"data_term.support_gamma", "--support-gamma"},
      {"min_correlation", "--min-correlation"},
  };
  return table;
}

}  // namespace hnnstereo::api
