#pragma once
// The thesis energy in Hopfield form, as pure functions (no I/O, no globals).
//   E = -1/2 sum_ab W_ab V_a V_b - sum_a I_a V_a                         (eq. 6.10)
//   W_ab = 2 (A C_ab - B delta_ij - C delta_kl), (i,k) != (j,l)           (eq. 6.11)
//   I_a  = B + C - D tau_a                                                (eq. 6.12)
// The uniqueness parts of W are never stored: sum_b W_ab V_b is split into the stored
// compatibility part and -2B (row_i - V_a) - 2C (col_k - V_a) from row and column sums.

#include <Eigen/Core>
#include <vector>

#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"

namespace hnnstereo::hnn {

/// What the compatibility needs of one match.
struct MatchGeometry {
  Eigen::Vector2d left;   ///< left image point (px)
  Eigen::Vector2d right;  ///< right image point (px)
  double correlation;     ///< M, ZNCC in [-1, 1]
};

/// Disparity gradient between two matches (ch. 5.3.5): |d_a - d_b| / |c_a - c_b| with the 2D
/// disparity vectors d = right - left and cyclopean points c = (left + right) / 2 (the text's
/// vector form). Coincident cyclopean points: 0 for equal disparities, else kMaxDisparityGradient.
double DisparityGradient(const MatchGeometry& a, const MatchGeometry& b);
inline constexpr double kMaxDisparityGradient = 1e6;

/// f(X) of eq. 6.6 (sigmoid) or of the printed type 1 (exponential).
double CompatibilityFunction(double X, const EnergyOptions& options);

/// C_ab in [-1, 1] (for kPrinted1 the raw disparity gradient), per options.objective.
/// eq. 6.7 divides by s = W1 g + W2 (M_a + M_b), which can be zero or negative: for s below
/// kMinCompatibilityDenominator the pair is treated as maximally incompatible (X = +inf),
/// since a vanishing or negative s means weak geometry and weak similarity.
double Compatibility(const MatchGeometry& a, const MatchGeometry& b, const EnergyOptions& options);
inline constexpr double kMinCompatibilityDenominator = 1e-3;

/// The stored compatibility weight between neurons a and b of different... or the same left
/// feature: 2 A C_ab (+ offset), times the optional distance attenuation (printed code).
double CompatibilityWeight(const MatchGeometry& a, const MatchGeometry& b,
                           double left_distance_px, const EnergyOptions& options);

/// I_a = B + C - D tau_a (eq. 6.12); C drops out when columns carry no uniqueness.
double Bias(double epipolar_distance_px, bool column_uniqueness, const EnergyOptions& options);

/// V = g(u) for the continuous or discrete activation; `previous` is held by the discrete
/// neuron when u == 0.
double Activate(double u, Activation activation, double alpha, double previous);

/// u with g(u) = V for the continuous activation (V clamped into (0, 1)).
double InverseActivation(double V, double alpha);

/// Hopfield's (1984) integral term alpha * sum_a G(V_a), G(V) = int_{1/2}^{V} g^-1(v) dv: added
/// to E it gives the Lyapunov function of the continuous network under asynchronous updates.
double ActivationIntegral(double V, double alpha);

}  // namespace hnnstereo::hnn
