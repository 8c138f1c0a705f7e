#include "calib/dlt.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "calib/epipolar.h"

namespace hnnstereo::calib {
namespace {

using Vector12d = Eigen::Matrix<double, 12, 1>;

ProjectionMatrix FromRowMajor(const Vector12d& p) {
  ProjectionMatrix P;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) P(r, c) = p(4 * r + c);
  }
  return P;
}

Vector12d ToRowMajor(const ProjectionMatrix& P) {
  Vector12d p;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) p(4 * r + c) = P(r, c);
  }
  return p;
}

// Sum of squared residuals of normalised P on normalised points.
double SquaredError(const ProjectionMatrix& P, const std::vector<Eigen::Vector3d>& world,
                    const std::vector<Eigen::Vector2d>& image) {
  double sum = 0.0;
  for (size_t i = 0; i < world.size(); ++i) {
    const Eigen::Vector3d x = P * world[i].homogeneous();
    sum += (x.hnormalized() - image[i]).squaredNorm();
  }
  return sum;
}

// Levenberg-Marquardt on the 12 entries of a normalised P (H&Z A6.2), the scale gauge held by
// renormalising to unit norm after each step (the damping keeps the normal matrix regular).
int RefineLevenbergMarquardt(const std::vector<Eigen::Vector3d>& world,
                             const std::vector<Eigen::Vector2d>& image, int max_iterations,
                             ProjectionMatrix* P) {
  Vector12d p = ToRowMajor(*P);
  p.normalize();
  double error = SquaredError(FromRowMajor(p), world, image);
  double lambda = 1e-3;
  int iteration = 0;
  for (; iteration < max_iterations; ++iteration) {
    Eigen::Matrix<double, 12, 12> JtJ = Eigen::Matrix<double, 12, 12>::Zero();
    Vector12d Jtr = Vector12d::Zero();
    for (size_t i = 0; i < world.size(); ++i) {
      const Eigen::Vector4d X = world[i].homogeneous();
      const double w = p.segment<4>(8).dot(X);
      const double u = p.segment<4>(0).dot(X) / w;
      const double v = p.segment<4>(4).dot(X) / w;
      Eigen::Matrix<double, 2, 12> J = Eigen::Matrix<double, 2, 12>::Zero();
      J.block<1, 4>(0, 0) = X.transpose() / w;
      J.block<1, 4>(0, 8) = -u * X.transpose() / w;
      J.block<1, 4>(1, 4) = X.transpose() / w;
      J.block<1, 4>(1, 8) = -v * X.transpose() / w;
      const Eigen::Vector2d r(u - image[i].x(), v - image[i].y());
      JtJ.noalias() += J.transpose() * J;
      Jtr.noalias() += J.transpose() * r;
    }
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::Matrix<double, 12, 12> A = JtJ;
      A.diagonal() += lambda * (JtJ.diagonal().array() + 1e-12).matrix();
      const Vector12d step = A.ldlt().solve(-Jtr);
      Vector12d candidate = p + step;
      candidate.normalize();
      const double candidate_error = SquaredError(FromRowMajor(candidate), world, image);
      if (std::isfinite(candidate_error) && candidate_error < error) {
        const double relative_gain = (error - candidate_error) / std::max(error, 1e-300);
        p = candidate;
        error = candidate_error;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        if (relative_gain < 1e-12) iteration = max_iterations;  // converged
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  *P = FromRowMajor(p);
  return std::min(iteration, max_iterations);
}

void ScaleToUnitP23(ProjectionMatrix* P) {
  // The thesis scales so that P[2][3] = 1. When P(2,3) ~ 0 (world origin on the camera's
  // principal plane) that scaling is impossible; fall back to a unit third row direction.
  const double p23 = (*P)(2, 3);
  if (std::abs(p23) > 1e-12 * P->norm()) {
    *P /= p23;
  } else {
    *P /= P->block<1, 3>(2, 0).norm();
  }
}

}  // namespace

std::string DltOptions::Check() const {
  std::ostringstream out;
  if (max_refinement_iterations < 0) {
    out << "DltOptions.max_refinement_iterations must be >= 0 (is " << max_refinement_iterations
        << ")";
  } else if (min_points < 6) {
    out << "DltOptions.min_points must be >= 6 (is " << min_points << ")";
  } else if (!(min_non_planarity >= 0.0 && min_non_planarity < 1.0)) {
    out << "DltOptions.min_non_planarity must be in [0, 1) (is " << min_non_planarity << ")";
  }
  return out.str();
}

Eigen::Vector2d Project(const ProjectionMatrix& P, const Eigen::Vector3d& point3D_in_world) {
  return (P * point3D_in_world.homogeneous()).hnormalized();
}

ReprojectionStatistics SummariseResiduals(std::vector<Eigen::Vector2d> residuals_px) {
  ReprojectionStatistics stats;
  stats.residuals_px = std::move(residuals_px);
  const double n = static_cast<double>(stats.residuals_px.size());
  if (n == 0) return stats;
  double sum_sq = 0.0;
  for (const Eigen::Vector2d& r : stats.residuals_px) {
    stats.mae_x_px += std::abs(r.x());
    stats.mae_y_px += std::abs(r.y());
    stats.rms_x_px += r.x() * r.x();
    stats.rms_y_px += r.y() * r.y();
    stats.mae_px += r.norm();
    sum_sq += r.squaredNorm();
    stats.max_px = std::max(stats.max_px, r.norm());
  }
  stats.mae_x_px /= n;
  stats.mae_y_px /= n;
  stats.rms_x_px = std::sqrt(stats.rms_x_px / n);
  stats.rms_y_px = std::sqrt(stats.rms_y_px / n);
  stats.mae_px /= n;
  stats.rms_px = std::sqrt(sum_sq / n);
  return stats;
}

ReprojectionStatistics ComputeReprojectionStatistics(
    const ProjectionMatrix& P, const std::vector<Eigen::Vector3d>& points3D_in_world,
    const std::vector<Eigen::Vector2d>& image_points) {
  std::vector<Eigen::Vector2d> residuals;
  residuals.reserve(points3D_in_world.size());
  for (size_t i = 0; i < points3D_in_world.size() && i < image_points.size(); ++i) {
    residuals.push_back(Project(P, points3D_in_world[i]) - image_points[i]);
  }
  return SummariseResiduals(std::move(residuals));
}

Eigen::Matrix3d HartleyNormalisation2D(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
  if (points.size() < 2) return T;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  double mean_distance = 0.0;
  for (const auto& p : points) mean_distance += (p - centroid).norm();
  mean_distance /= static_cast<double>(points.size());
  if (!(mean_distance > 0.0)) return T;
  const double scale = std::sqrt(2.0) / mean_distance;
  T(0, 0) = T(1, 1) = scale;
  T.block<2, 1>(0, 2) = -scale * centroid;
  return T;
}

Eigen::Matrix4d HartleyNormalisation3D(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  if (points.size() < 2) return T;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  double mean_distance = 0.0;
  for (const auto& p : points) mean_distance += (p - centroid).norm();
  mean_distance /= static_cast<double>(points.size());
  if (!(mean_distance > 0.0)) return T;
  const double scale = std::sqrt(3.0) / mean_distance;
  T.block<3, 3>(0, 0) *= scale;
  T.block<3, 1>(0, 3) = -scale * centroid;
  return T;
}

Eigen::Matrix<double, 12, 12> DltNormalMatrix(const std::vector<Eigen::Vector3d>& points3D,
                                              const std::vector<Eigen::Vector2d>& image_points) {
  // Thesis eq. 3.9 / H&Z eq. 7.2: for x = (u, v, 1) ~ P X,
  //   [ X^T   0^T  -u X^T ] p = 0
  //   [ 0^T   X^T  -v X^T ]
  Eigen::Matrix<double, 12, 12> AtA = Eigen::Matrix<double, 12, 12>::Zero();
  for (size_t i = 0; i < points3D.size(); ++i) {
    const Eigen::Vector4d X = points3D[i].homogeneous();
    Eigen::Matrix<double, 2, 12> A = Eigen::Matrix<double, 2, 12>::Zero();
    A.block<1, 4>(0, 0) = X.transpose();
    A.block<1, 4>(0, 8) = -image_points[i].x() * X.transpose();
    A.block<1, 4>(1, 4) = X.transpose();
    A.block<1, 4>(1, 8) = -image_points[i].y() * X.transpose();
    AtA.noalias() += A.transpose() * A;
  }
  return AtA;
}

DltReport EstimateProjectionDlt(const std::vector<Eigen::Vector3d>& points3D_in_world,
                                const std::vector<Eigen::Vector2d>& image_points,
                                const DltOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (points3D_in_world.size() != image_points.size()) {
    throw std::invalid_argument("DLT: " + std::to_string(points3D_in_world.size()) +
                                " world points but " + std::to_string(image_points.size()) +
                                " image points");
  }
  const size_t n = points3D_in_world.size();
  if (n < static_cast<size_t>(options.min_points)) {
    throw std::invalid_argument("DLT needs at least " + std::to_string(options.min_points) +
                                " point correspondences (got " + std::to_string(n) + ")");
  }
  for (size_t i = 0; i < n; ++i) {
    if (!points3D_in_world[i].allFinite() || !image_points[i].allFinite()) {
      throw std::invalid_argument("DLT: correspondence " + std::to_string(i) +
                                  " has a non-finite value (NaN or infinity)");
    }
  }
  // Degeneracy: all world points on one plane (H&Z 7.1; the thesis moved its target to
  // several heights for this reason).
  {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& X : points3D_in_world) centroid += X;
    centroid /= static_cast<double>(n);
    Eigen::MatrixXd centred(n, 3);
    for (size_t i = 0; i < n; ++i)
      centred.row(static_cast<Eigen::Index>(i)) = (points3D_in_world[i] - centroid).transpose();
    const Eigen::Vector3d spread = Eigen::JacobiSVD<Eigen::MatrixXd>(centred).singularValues();
    if (!(spread(2) > options.min_non_planarity * spread(0))) {
      std::ostringstream out;
      out << "DLT: the " << n << " world points are coplanar (spread " << spread(2) << " vs "
          << spread(0)
          << "); a projection matrix needs points off one plane, e.g. a target at two or more "
             "heights";
      throw std::invalid_argument(out.str());
    }
  }

  const Eigen::Matrix3d T_image = HartleyNormalisation2D(image_points);
  const Eigen::Matrix4d T_world = HartleyNormalisation3D(points3D_in_world);
  std::vector<Eigen::Vector3d> world_normalised(n);
  std::vector<Eigen::Vector2d> image_normalised(n);
  for (size_t i = 0; i < n; ++i) {
    world_normalised[i] = (T_world * points3D_in_world[i].homogeneous()).hnormalized();
    image_normalised[i] = (T_image * image_points[i].homogeneous()).hnormalized();
  }
  Eigen::MatrixXd A(2 * n, 12);
  A.setZero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::RowVector4d X = world_normalised[i].homogeneous().transpose();
    const auto r = static_cast<Eigen::Index>(2 * i);
    A.block<1, 4>(r, 0) = X;
    A.block<1, 4>(r, 8) = -image_normalised[i].x() * X;
    A.block<1, 4>(r + 1, 4) = X;
    A.block<1, 4>(r + 1, 8) = -image_normalised[i].y() * X;
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Vector12d p = svd.matrixV().col(11);
  ProjectionMatrix P_normalised = FromRowMajor(p);

  auto denormalise = [&](const ProjectionMatrix& Pn) {
    ProjectionMatrix P = T_image.inverse() * Pn * T_world;
    ScaleToUnitP23(&P);
    return P;
  };

  DltReport report;
  report.num_points = static_cast<int>(n);
  report.P = denormalise(P_normalised);
  report.linear = ComputeReprojectionStatistics(report.P, points3D_in_world, image_points);
  report.final = report.linear;
  if (options.refine_nonlinear && options.max_refinement_iterations > 0) {
    ProjectionMatrix P_refined = P_normalised;
    report.refinement_iterations = RefineLevenbergMarquardt(
        world_normalised, image_normalised, options.max_refinement_iterations, &P_refined);
    const ProjectionMatrix P_candidate = denormalise(P_refined);
    const ReprojectionStatistics refined_stats =
        ComputeReprojectionStatistics(P_candidate, points3D_in_world, image_points);
    if (P_candidate.allFinite() && refined_stats.rms_px <= report.linear.rms_px) {
      report.P = P_candidate;
      report.final = refined_stats;
      report.refined = true;
    }
  }
  report.camera_centre = CameraCentre(report.P);
  return report;
}

}  // namespace hnnstereo::calib
