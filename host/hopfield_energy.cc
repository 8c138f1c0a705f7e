#include "host/hopfield_energy.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hnnstereo::hnn {

double DisparityGradient(const MatchGeometry& a, const MatchGeometry& b) {
  const Eigen::Vector2d disparity_a = a.right - a.left;
  const Eigen::Vector2d disparity_b = b.right - b.left;
  const double disparity_change = (disparity_a - disparity_b).norm();
  const double cyclopean_separation = (0.5 * (a.left + a.right) - 0.5 * (b.left + b.right)).norm();
  if (cyclopean_separation < 1e-9) {
    return disparity_change < 1e-9 ? 0.0 : kMaxDisparityGradient;
  }
  return std::min(disparity_change / cyclopean_separation, kMaxDisparityGradient);
}

double CompatibilityFunction(double X, const EnergyOptions& options) {
  if (std::isinf(X)) return X > 0 ? -1.0 : 1.0;
  if (options.compatibility == CompatibilityType::kExponential) {
    return 2.0 * std::exp(-X / options.T) - 1.0;  // printed type 1
  }
  const double z = options.lambda * (X - options.theta);
  if (z > 700.0) return -1.0;
  return 2.0 / (1.0 + std::exp(z)) - 1.0;  // eq. 6.6
}

double Compatibility(const MatchGeometry& a, const MatchGeometry& b, const EnergyOptions& options) {
  switch (options.objective) {
    case Objective::kThesis: {
      const double dd = DisparityGradient(a, b);
      const double g = 2.0 * std::exp(-dd / options.T) - 1.0;  // eq. 6.8
      const double s = options.W1 * g + options.W2 * (a.correlation + b.correlation);  // eq. 6.7
      const double X = s < kMinCompatibilityDenominator ? std::numeric_limits<double>::infinity()
                                                        : 1.0 / s;
      return CompatibilityFunction(X, options);
    }
    case Objective::kPrinted0: {
      // Differences of disparity magnitudes and of left/right feature separations.
      const double disparity_change =
          std::abs((a.right - a.left).norm() - (b.right - b.left).norm());
      const double separation_change =
          std::abs((a.left - b.left).norm() - (a.right - b.right).norm());
      return CompatibilityFunction(0.4 * disparity_change + 0.6 * separation_change, options);
    }
    case Objective::kPrinted1:
      return DisparityGradient(a, b);
    case Objective::kPrinted2:
      return (a.correlation + b.correlation + 2.0) / 4.0;
    case Objective::kGeometrySimilarity: {
      const double g = 2.0 * std::exp(-DisparityGradient(a, b) / options.T) - 1.0;
      return g * (a.correlation + 1.0) * (b.correlation + 1.0) / 4.0;
    }
  }
  return 0.0;
}

double CompatibilityWeight(const MatchGeometry& a, const MatchGeometry& b,
                           double left_distance_px, const EnergyOptions& options) {
  double weight = 2.0 * options.A * Compatibility(a, b, options) + options.weight_offset;
  if (options.distance_attenuation) {
    weight /= 1.0 + std::exp(options.attenuation_slope *
                             (left_distance_px - options.attenuation_centre_px));
  }
  return weight;
}

double Bias(double epipolar_distance_px, bool column_uniqueness, const EnergyOptions& options) {
  return options.B + (column_uniqueness ? options.C : 0.0) - options.D * epipolar_distance_px;
}

double Activate(double u, Activation activation, double alpha, double previous) {
  if (activation == Activation::kDiscrete) {
    if (u > 0.0) return 1.0;
    if (u < 0.0) return 0.0;
    return previous;
  }
  return 0.5 * (1.0 + std::tanh(u / alpha));
}

double InverseActivation(double V, double alpha) {
  const double v = std::clamp(V, 1e-6, 1.0 - 1e-6);
  return alpha * std::atanh(2.0 * v - 1.0);
}

double ActivationIntegral(double V, double alpha) {
  // int_{1/2}^{V} alpha atanh(2v - 1) dv = alpha/2 [x atanh x + 1/2 ln(1 - x^2)], x = 2V - 1.
  const double x = std::clamp(2.0 * V - 1.0, -1.0, 1.0);
  if (std::abs(x) == 1.0) return 0.5 * alpha * std::log(2.0);
  return 0.5 * alpha * (x * std::atanh(x) + 0.5 * std::log1p(-x * x));
}

}  // namespace hnnstereo::hnn
