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
      {"check-interval",
       [](auto& n, auto& v, auto& o) { o.dynamics.energy_interval = ParseInt(n, v); }},
  };
  return options;
}

// The CLI's string-valued flags with their defaults (parsed after the preset, as Resolve does).
const std::map<std::string, std::string>& StringOptionDefaults() {
  static const std::map<std::string, std::string> defaults = {
      {"features", "canny"},        {"engine", "opencl"}, {"objective", ""},        {"init", "off"},
      {"activation", "continuous"}, {"decode", "thesis"}, {"network", ""},          {"zrange", ""},
      {"memory-budget-mb", "2048"}, {"device", ""},       {"no-lr-check", "false"}, {"stop", ""},
      {"weights", "auto"},          {"data-term", ""},
  };
  return defaults;
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
  for (const auto& [name, value] : StringOptionDefaults()) names.push_back(name);
  return names;
}

// The preset's settings, except those given in `settings.given` (the objective, network,
// top-k, data term, support radius) and its refinements (unless no-lr-check).
void ApplyPreset(const std::string& preset, std::map<std::string, std::string>& strings,
                 MatcherSettings& settings) {
  vision::MatcherOptions& o = settings.matcher;
  const auto given = [&](const char* name) { return settings.given.count(name) > 0; };

  // The preset, unless overridden, then the string-valued settings.
  const std::optional<vision::MatcherPreset> chosen = vision::FindPreset(preset);
  if (!chosen) {
    std::string names;
    for (const vision::MatcherPreset& p : vision::AllPresets()) names += (names.empty() ? "" : ", ") + p.name;
    throw std::invalid_argument("unknown preset '" + preset + "' (" + names + ")");
  }
  if (!given("objective")) strings["objective"] = std::string(hnn::ObjectiveName(chosen->matcher.energy.objective));
  settings.refinement = chosen->refinement;
  if (ParseFlag("no-lr-check", strings["no-lr-check"])) settings.refinement.left_right_check = false;
  const vision::CandidateOptions& preset_candidates = chosen->matcher.candidates;
  if (!given("network")) {
    strings["network"] =
        preset_candidates.kind == hnn::NetworkKind::kFeatureVsDisparity ? "disparity" : "feature";
    o.candidates.zncc_peaks = preset_candidates.zncc_peaks;
    o.candidates.subpixel_peaks = preset_candidates.subpixel_peaks;
  }
  if (!given("top-k")) o.candidates.top_k = preset_candidates.top_k;
  o.data_term = chosen->matcher.data_term;
  o.confidence = chosen->matcher.confidence;
  if (given("data-term")) {
    if (strings["data-term"] == "census") {
      o.data_term.kind = vision::DataTermOptions::Kind::kCensus;
    } else if (strings["data-term"] == "zncc") {
      o.data_term.kind = vision::DataTermOptions::Kind::kZncc;
    } else {
      throw std::invalid_argument("unknown data-term '" + strings["data-term"] +
                                  "' (census or zncc)");
    }
    o.confidence = vision::ConfidenceOptionsFor(o.data_term);  // the model fitted for it
  }
  if (!given("support-radius")) o.energy.support_radius_px = chosen->matcher.energy.support_radius_px;

}

// The string-valued settings (features, engine, objective, init, activation, stop rule, weight
// storage, decoding, network) parsed into `o`; an unknown name is refused naming the choices.
void ParseNamedSettings(std::map<std::string, std::string>& strings, MatcherSettings& settings,
                        const vision::MatcherPreset& chosen) {
  vision::MatcherOptions& o = settings.matcher;
  const auto given = [&](const char* name) { return settings.given.count(name) > 0; };
  if (auto d = vision::ParseFeatureDetector(strings["features"])) {
    o.features.detector = *d;
  } else {
    throw std::invalid_argument("unknown features '" + strings["features"] + "'");
  }
  if (auto e = vision::ParseEngine(strings["engine"])) {
    o.engine = *e;
  } else {
    throw std::invalid_argument("unknown engine '" + strings["engine"] + "' (opencl, cpu or thesis)");
  }
  if (auto obj = hnn::ParseObjective(strings["objective"])) {
    o.energy.objective = *obj;
  } else {
    throw std::invalid_argument("unknown objective '" + strings["objective"] + "'");
  }
  if (auto s = hnn::ParseInitialState(strings["init"])) {
    o.dynamics.initial_state = *s;
  } else {
    throw std::invalid_argument("unknown init '" + strings["init"] + "'");
  }
  if (strings["activation"] == "continuous") {
    o.dynamics.activation = hnn::Activation::kContinuous;
  } else if (strings["activation"] == "discrete") {
    o.dynamics.activation = hnn::Activation::kDiscrete;
  } else {
    throw std::invalid_argument("unknown activation '" + strings["activation"] + "'");
  }
  // The stop rule and the check interval are the preset's unless given (hnn-default: decisions,
  // every 2 steps, twice in a row; docs/engine.md).
  if (!given("stop")) {
    o.dynamics.stop_rule = chosen.matcher.dynamics.stop_rule;
  } else if (strings["stop"] == "energy") {
    o.dynamics.stop_rule = hnn::DynamicsOptions::StopRule::kEnergy;
  } else if (strings["stop"] == "decisions") {
    o.dynamics.stop_rule = hnn::DynamicsOptions::StopRule::kDecisions;
  } else {
    throw std::invalid_argument("unknown stop '" + strings["stop"] + "' (energy or decisions)");
  }
  if (!given("check-interval")) {
    o.dynamics.energy_interval = chosen.matcher.dynamics.energy_interval;
    o.dynamics.stable_checks = chosen.matcher.dynamics.stable_checks;
  }
  if (auto w = hnn::ParseWeightStorage(strings["weights"])) {
    o.opencl.storage = *w;
  } else {
    throw std::invalid_argument("unknown weights '" + strings["weights"] + "' (" +
                                hnn::WeightStorageNames() + ")");
  }
  if (auto m = hnn::ParseDecodeMethod(strings["decode"])) {
    o.decode.method = *m;
  } else {
    throw std::invalid_argument("unknown decode '" + strings["decode"] + "'");
  }
  if (strings["network"] == "feature") {
    o.candidates.kind = hnn::NetworkKind::kFeatureVsFeature;
  } else if (strings["network"] == "disparity") {
    o.candidates.kind = hnn::NetworkKind::kFeatureVsDisparity;
  } else {
    throw std::invalid_argument("unknown network '" + strings["network"] + "' (feature or disparity)");
  }
  if (const std::string& zrange = strings["zrange"]; !zrange.empty()) {
    double zmin = 0, zmax = 0;
    char comma = 0;
    std::istringstream in(zrange);
    if (!(in >> zmin >> comma >> zmax) || comma != ',' || !(zmin < zmax)) {
      throw std::invalid_argument("zrange must be ZMIN,ZMAX with ZMIN < ZMAX (got '" + zrange + "')");
    }
    o.candidates.z_range_mm = std::make_pair(zmin, zmax);
  }
}

MatcherSettings ResolveMatcherSettings(const std::string& preset, const Overrides& overrides,
                                       const vision::MatcherOptions& base) {
  MatcherSettings settings;
  settings.preset = preset;
  settings.matcher = base;
  vision::MatcherOptions& o = settings.matcher;
  std::map<std::string, std::string> strings = StringOptionDefaults();
  for (const auto& [raw_name, value] : overrides) {
    const std::string name = CanonicalName(raw_name);
    settings.given[name] = value;
    if (auto direct = DirectOptions().find(name); direct != DirectOptions().end()) {
      direct->second(name, value, o);
    } else if (strings.count(name) > 0) {
      strings[name] = value;
    } else {
      throw std::invalid_argument("unknown option " + Quoted(raw_name) +
                                  " (the match command's flags without dashes, e.g. max-features)");
    }
  }
  // The library allows 0 steps (sizing a network); from a user it would solve nothing.
  if (settings.given.count("max-steps") > 0 && o.dynamics.max_steps < 1) {
    throw std::invalid_argument("--max-steps must be >= 1 (0 steps leave every neuron where it "
                                "started: no match)");
  }
  ApplyPreset(preset, strings, settings);
  ParseNamedSettings(strings, settings, *vision::FindPreset(preset));
  const double memory_budget_mb = ParseDouble("memory-budget-mb", strings["memory-budget-mb"]);
  // Bounded above so that the conversion to bytes is defined (inf or 1e300 would not fit a
  // size_t: undefined behaviour, seen as a budget of 0 MB). 2^40 MB is beyond any machine.
  if (!(memory_budget_mb > 0) || !(memory_budget_mb <= kMaxMemoryBudgetMb)) {
    throw std::invalid_argument("memory-budget-mb must be a number in (0, 1099511627776] (is " +
                                strings["memory-budget-mb"] + ")");
  }
  o.memory_budget_bytes = static_cast<std::size_t>(memory_budget_mb * 1024.0 * 1024.0);
  settings.device = strings["device"];
  // The geometry (rectified or not) is settled by the call; check the rest now.
  vision::MatcherOptions rest = o;
  rest.candidates.rectified = true;
  if (auto error = rest.Check(); !error.empty()) {
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
  };
  return table;
}

}  // namespace hnnstereo::api
