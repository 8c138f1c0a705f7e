#include "vision/sensing/triangulation.h"

#include <Eigen/SVD>
#include <cmath>

#include "vision/stereo/lens_distortion.h"

namespace hnnstereo::vision {

std::optional<TriangulatedPoint> TriangulateLinear(const Eigen::Matrix<double, 3, 4>& P1,
                                                   const Eigen::Matrix<double, 3, 4>& P2,
                                                   const Eigen::Vector2d& left_point,
                                                   const Eigen::Vector2d& right_point) {
  Eigen::Matrix4d A;
  A.row(0) = left_point.x() * P1.row(2) - P1.row(0);
  A.row(1) = left_point.y() * P1.row(2) - P1.row(1);
  A.row(2) = right_point.x() * P2.row(2) - P2.row(0);
  A.row(3) = right_point.y() * P2.row(2) - P2.row(1);
  Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X(3)) < 1e-12 || !X.allFinite()) return std::nullopt;
  TriangulatedPoint result;
  result.point_in_world = X.hnormalized();
  const Eigen::Vector3d x1 = P1 * X, x2 = P2 * X;
  // Positive depth: the projective depth has the sign of w * det(M) (H&Z 6.2.3).
  const double depth1 = x1.z() * X(3) * P1.leftCols<3>().determinant();
  const double depth2 = x2.z() * X(3) * P2.leftCols<3>().determinant();
  result.in_front = depth1 > 0 && depth2 > 0;
  const double e1 = (x1.hnormalized() - left_point).squaredNorm();
  const double e2 = (x2.hnormalized() - right_point).squaredNorm();
  result.reprojection_error_px = std::sqrt(0.5 * (e1 + e2));
  return result;
}

std::vector<Eigen::Vector3d> MatchesInWorld(const calib::StereoCalibration& calibration,
                                            const std::vector<StereoMatch>& matches,
                                            double max_reprojection_error_px,
                                            std::vector<int>* match_of_point) {
  std::vector<Eigen::Vector2f> lefts, rights;
  lefts.reserve(matches.size());
  rights.reserve(matches.size());
  for (const StereoMatch& match : matches) {
    lefts.push_back(match.left);
    rights.push_back(match.right);
  }
  const calib::Intrinsics* lens = calibration.intrinsics && !calibration.intrinsics->D1.empty()
                                      ? &*calibration.intrinsics
                                      : nullptr;
  if (lens) {
    lefts = UndistortPoints(lefts, lens->K1, lens->D1);
    rights = UndistortPoints(rights, lens->K2, lens->D2);
  }
  std::vector<Eigen::Vector3d> points;
  if (match_of_point) match_of_point->clear();
  for (std::size_t m = 0; m < matches.size(); ++m) {
    const auto point = TriangulateLinear(calibration.P1, calibration.P2, lefts[m].cast<double>(),
                                         rights[m].cast<double>());
    if (!point || !point->in_front || !(point->reprojection_error_px <= max_reprojection_error_px)) {
      continue;
    }
    points.push_back(point->point_in_world);
    if (match_of_point) match_of_point->push_back(static_cast<int>(m));
  }
  return points;
}

}  // namespace hnnstereo::vision
