#include "calib/epipolar.h"

#include <Eigen/SVD>
#include <cmath>
#include <limits>

namespace hnnstereo::calib {

Eigen::Vector3d EpipolarLineInRight(const Eigen::Matrix3d& F, const Eigen::Vector2d& left_point) {
  const Eigen::Vector3d line = F * left_point.homogeneous();
  const double norm = std::hypot(line.x(), line.y());
  if (!(norm > 0.0) || !std::isfinite(norm)) return Eigen::Vector3d::Zero();
  return line / norm;
}

double EpipolarDistancePx(const Eigen::Matrix3d& F, const Eigen::Vector2d& left_point,
                          const Eigen::Vector2d& right_point) {
  const Eigen::Vector3d line = EpipolarLineInRight(F, left_point);
  if (line.isZero()) return std::numeric_limits<double>::infinity();
  return std::abs(line.dot(right_point.homogeneous()));
}

Eigen::Vector3d CameraCentre(const Eigen::Matrix<double, 3, 4>& P) {
  Eigen::JacobiSVD<Eigen::Matrix<double, 3, 4>> svd(P, Eigen::ComputeFullV);
  const Eigen::Vector4d null_vector = svd.matrixV().col(3);
  return null_vector.hnormalized();
}

Eigen::Matrix3d CrossProductMatrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Matrix3d FundamentalFromProjections(const Eigen::Matrix<double, 3, 4>& P1,
                                           const Eigen::Matrix<double, 3, 4>& P2) {
  Eigen::JacobiSVD<Eigen::Matrix<double, 3, 4>> svd(P1, Eigen::ComputeFullV);
  const Eigen::Vector4d centre1 = svd.matrixV().col(3);
  const Eigen::Vector3d epipole2 = P2 * centre1;
  // Pseudo-inverse of a full-rank 3x4 matrix from its SVD (V S^-1 U^T). The closed form
  // P^T (P P^T)^-1 squares the condition number: with pixel/mm entries (1e3 vs 1e6) it lost
  // about 1e-4 px of epipolar accuracy.
  Eigen::JacobiSVD<Eigen::Matrix<double, 3, 4>> thin(P1, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix<double, 4, 3> P1_pinv = thin.matrixV().leftCols<3>() *
                                              thin.singularValues().cwiseInverse().asDiagonal() *
                                              thin.matrixU().transpose();
  Eigen::Matrix3d F = CrossProductMatrix(epipole2) * P2 * P1_pinv;
  const double norm = F.norm();
  if (norm > 0.0) F /= norm;
  return F;
}

}  // namespace hnnstereo::calib
