#include "host/hopfield_options.h"

#include <array>
#include <cmath>
#include <utility>

namespace hnnstereo::hnn {
namespace {

constexpr std::array<std::pair<Objective, std::string_view>, 5> kObjectiveNames{{
    {Objective::kThesis, "thesis"},
    {Objective::kPrinted0, "printed0"},
    {Objective::kPrinted1, "printed1"},
    {Objective::kPrinted2, "printed2"},
    {Objective::kGeometrySimilarity, "geometry-similarity"},
}};

constexpr std::array<std::pair<InitialState, std::string_view>, 7> kInitialStateNames{{
    {InitialState::kAllOff, "off"},
    {InitialState::kAllOn, "on"},
    {InitialState::kRandomBinary, "random-binary"},
    {InitialState::kRandomContinuous, "random"},
    {InitialState::kConstant, "constant"},
    {InitialState::kConstantNoise, "constant-noise"},
    {InitialState::kCorrelation, "correlation"},
}};

constexpr std::array<std::pair<Activation, std::string_view>, 2> kActivationNames{{
    {Activation::kContinuous, "continuous"},
    {Activation::kDiscrete, "discrete"},
}};

constexpr std::array<std::pair<DynamicsOptions::StopRule, std::string_view>, 2> kStopRuleNames{{
    {DynamicsOptions::StopRule::kEnergy, "energy"},
    {DynamicsOptions::StopRule::kDecisions, "decisions"},
}};

// The name of `value` in `table` ("unknown" when absent), and the value named `name`.
template <class Enum, std::size_t N>
std::string_view NameIn(const std::array<std::pair<Enum, std::string_view>, N>& table, Enum value) {
  for (const auto& [entry, name] : table) {
    if (entry == value) return name;
  }
  return "unknown";
}

template <class Enum, std::size_t N>
std::optional<Enum> ValueIn(const std::array<std::pair<Enum, std::string_view>, N>& table,
                            std::string_view name) {
  for (const auto& [entry, text] : table) {
    if (text == name) return entry;
  }
  return std::nullopt;
}

// Largest energy coefficient, gain or time step accepted. The defaults are of order 0.01-10; a
// value of 1e308 (a typo, a hostile --config) passed "finite" and overflowed the energy to
// infinity, so that the report said energy null and no neuron was decided. 1e6 still leaves the
// float sums over ~10^7 connections far from overflow.
constexpr double kMaxCoefficient = 1e6;

std::string Positive(const char* name, double value) {
  if (std::isfinite(value) && value > 0.0 && value <= kMaxCoefficient) return {};
  return std::string(name) + " must be a positive number <= 1e6 (got " + std::to_string(value) +
         ")";
}

std::string NonNegative(const char* name, double value) {
  if (std::isfinite(value) && value >= 0.0 && value <= kMaxCoefficient) return {};
  return std::string(name) + " must be >= 0 and <= 1e6 (got " + std::to_string(value) + ")";
}

}  // namespace

std::string EnergyOptions::Check() const {
  for (const auto& [name, value] : {std::pair{"A", A}, {"B", B}, {"C", C}, {"D", D}, {"W1", W1},
                                    {"W2", W2}}) {
    if (auto error = NonNegative(name, value); !error.empty()) return error;
  }
  if (auto error = Positive("T", T); !error.empty()) return error;
  if (auto error = Positive("lambda", lambda); !error.empty()) return error;
  if (!std::isfinite(theta)) return "theta must be finite";
  if (auto error = Positive("support_radius_px", support_radius_px); !error.empty()) return error;
  if (!std::isfinite(weight_offset)) return "weight_offset must be finite";
  if (!std::isfinite(attenuation_centre_px) || !std::isfinite(attenuation_slope)) {
    return "attenuation parameters must be finite";
  }
  return {};
}

std::string DynamicsOptions::Check() const {
  if (auto error = Positive("alpha", alpha); !error.empty()) return error;
  if (auto error = Positive("time_step", time_step); !error.empty()) return error;
  if (auto error = Positive("tau", tau); !error.empty()) return error;
  if (auto error = NonNegative("energy_tolerance", energy_tolerance); !error.empty()) return error;
  if (auto error = NonNegative("update_tolerance", update_tolerance); !error.empty()) return error;
  if (!(initial_value >= 0.0 && initial_value <= 1.0)) return "initial_value must be in [0, 1]";
  if (auto error = NonNegative("initial_noise", initial_noise); !error.empty()) return error;
  if (max_steps < 0) return "max_steps must be >= 0";
  if (energy_interval < 1) return "energy_interval must be >= 1";
  if (stable_checks < 1) return "stable_checks must be >= 1";
  if (!(decision_tolerance >= 0.0 && decision_tolerance <= 1.0)) {
    return "decision_tolerance must be in [0, 1]";
  }
  if (max_updates < 0) return "max_updates must be >= 0";
  if (stable_updates < 1) return "stable_updates must be >= 1";
  return {};
}

std::string_view ObjectiveName(Objective objective) { return NameIn(kObjectiveNames, objective); }

std::optional<Objective> ParseObjective(std::string_view name) {
  return ValueIn(kObjectiveNames, name);
}

std::string_view InitialStateName(InitialState state) { return NameIn(kInitialStateNames, state); }

std::optional<InitialState> ParseInitialState(std::string_view name) {
  return ValueIn(kInitialStateNames, name);
}

std::string_view ActivationName(Activation activation) {
  return NameIn(kActivationNames, activation);
}

std::optional<Activation> ParseActivation(std::string_view name) {
  return ValueIn(kActivationNames, name);
}

std::string_view StopRuleName(DynamicsOptions::StopRule rule) {
  return NameIn(kStopRuleNames, rule);
}

std::optional<DynamicsOptions::StopRule> ParseStopRule(std::string_view name) {
  return ValueIn(kStopRuleNames, name);
}

}  // namespace hnnstereo::hnn
