#pragma once
// Options of the Hopfield matching energy and of its dynamics. Thesis values are the defaults
// (THESIS.md section 3) unless a comment says why not.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace hnnstereo::hnn {

/// The pairwise compatibility C_ikjl. The text's eq. 6.6-6.8 is the default; the printed code's
/// variants are kept as options.
enum class Objective {
  kThesis,               ///< eq. 6.6-6.8: C = f(X), X = 1 / (W1 g + W2 (M_ik + M_jl))
  kPrinted0,             ///< code objective 0: C = f(0.4 |d_disp| + 0.6 |d_dist|)
  kPrinted1,             ///< code objective 1: C = raw disparity gradient
  kPrinted2,             ///< code objective 2: C = (M_ik + M_jl + 2) / 4
  kGeometrySimilarity,   ///< g (M_ik + 1)(M_jl + 1) / 4 (THESIS.md measured hint)
};

/// The squashing f(X) used by objectives kThesis and kPrinted0.
enum class CompatibilityType {
  kSigmoid,      ///< type 0, eq. 6.6: 2 / (1 + exp(lambda (X - theta))) - 1
  kExponential,  ///< type 1: 2 exp(-X / T) - 1
};

enum class Activation {
  kContinuous,  ///< V = 0.5 (1 + tanh(u / alpha)) (the thesis's choice)
  kDiscrete,    ///< V in {0, 1}, held when the input is exactly zero
};

enum class InitialState {
  kAllOff, kAllOn, kRandomBinary, kRandomContinuous, kConstant, kConstantNoise,
  kCorrelation,  ///< V = (NCC + 1) / 2
};

struct EnergyOptions {
  double A = 2.0;  ///< weight of the compatibility term (eq. 6.5)
  double B = 1.0;  ///< row uniqueness: one match per left feature
  double C = 1.0;  ///< column uniqueness: one match per right feature
  double D = 1.0;  ///< weight of the epipolar distance tau (px) in the bias (eq. 6.12)
  double W1 = 0.3;  ///< eq. 6.7 weight of the disparity-gradient term
  double W2 = 0.7;  ///< eq. 6.7 weight of the correlation term
  double T = 1.5;   ///< eq. 6.8 disparity-gradient scale; also type-1 compatibility scale
  /// eq. 6.6 slope (the code's omega). The thesis printed no value: 5 makes f fall from +0.76 at
  /// a strong match (X = 0.64) to -0.99 at X = 2.
  double lambda = 5.0;
  /// eq. 6.6 centre. No printed value: 1 puts C = 0 where W1 g + W2 (M + M) = 1.
  double theta = 1.0;
  Objective objective = Objective::kThesis;
  CompatibilityType compatibility = CompatibilityType::kSigmoid;
  /// Sparse networks: compatibility only between neurons whose left features lie within this
  /// distance (px). The thesis's distance attenuation, made exact. Ignored by dense networks.
  double support_radius_px = 8.0;
  /// Printed-code attenuation of weights between far-apart left features:
  /// w *= 1 / (1 + exp(slope (d_px - centre))).
  bool distance_attenuation = false;
  double attenuation_centre_px = 40.0;
  double attenuation_slope = 0.2;
  double weight_offset = 0.0;  ///< printed-code constant added to every compatibility weight

  /// Empty when valid, else a readable reason naming the field.
  std::string Check() const;
};

struct DynamicsOptions {
  Activation activation = Activation::kContinuous;
  double alpha = 0.5;  ///< activation gain: V = 0.5 (1 + tanh(u / alpha))
  /// All OFF: the dense (all-pairs) network started from V = (NCC + 1) / 2 is swamped by
  /// inhibition and settles with every neuron off (measured on Teddy 60 x 60); sparse networks
  /// reach the same matches from either start.
  InitialState initial_state = InitialState::kAllOff;
  double initial_value = 0.5;   ///< for kConstant / kConstantNoise
  double initial_noise = 0.05;  ///< Gaussian sigma for kConstantNoise
  std::uint64_t seed = 1;       ///< random initial states and the thesis's random update order

  // Parallel engines (cpu, opencl): explicit Euler steps of du/dt = -u/tau + sum W V + I.
  /// Euler step dt, in units of tau. Measured on Teddy (5000 features) and the dense 60 x 60
  /// network: 0.1 needs 45-65 steps, 0.3 needs 30-35 to the same energy and matches, 1.0
  /// oscillates (the synchronous limit).
  double time_step = 0.3;
  double tau = 1.0;               ///< neuron time constant
  int max_steps = 300;            ///< step limit
  int energy_interval = 5;        ///< compute the energy every this many steps
  double energy_tolerance = 1e-3; ///< |dE| per neuron below which a check counts as stable
  int stable_checks = 3;          ///< consecutive stable checks that end the run
  /// What a check tests. kEnergy: |dE| per neuron below energy_tolerance (the thesis's rule).
  /// kDecisions: the decoded decision of every row (the neuron with the largest u, if its u > 0,
  /// i.e. V > 0.5; else none) changed for at most decision_tolerance of the rows since the last
  /// check - the matches are settled even though V still creeps towards saturation. Measured on
  /// Teddy (all edges): 99.8 % of the matches after 10 steps equal those after 85.
  enum class StopRule { kEnergy, kDecisions };
  StopRule stop_rule = StopRule::kEnergy;
  double decision_tolerance = 1e-3;  ///< share of rows whose decision may still change

  // Thesis engine: serial asynchronous random single-neuron updates.
  int max_updates = 20000;        ///< thesis: 20,000 updates
  int stable_updates = 200;       ///< thesis: 200 consecutive updates with |dE| < tolerance
  double update_tolerance = 1e-3; ///< thesis: 0.001

  std::string Check() const;
};

std::string_view ObjectiveName(Objective objective);
std::optional<Objective> ParseObjective(std::string_view name);
std::string_view InitialStateName(InitialState state);
std::optional<InitialState> ParseInitialState(std::string_view name);
std::string_view ActivationName(Activation activation);  ///< "continuous" or "discrete"
std::optional<Activation> ParseActivation(std::string_view name);
std::string_view StopRuleName(DynamicsOptions::StopRule rule);  ///< "energy" or "decisions"
std::optional<DynamicsOptions::StopRule> ParseStopRule(std::string_view name);

}  // namespace hnnstereo::hnn
