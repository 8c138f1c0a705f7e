#include "calib/fundamental.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>

#include "calib/dlt.h"
#include "calib/epipolar.h"

namespace hnnstereo::calib {
namespace {

void CheckCorrespondences(const std::vector<Eigen::Vector2d>& left,
                          const std::vector<Eigen::Vector2d>& right, const char* what) {
  if (left.size() != right.size()) {
    throw std::invalid_argument(std::string(what) + ": " + std::to_string(left.size()) +
                                " left points but " + std::to_string(right.size()) +
                                " right points");
  }
  if (left.size() < 8) {
    throw std::invalid_argument(std::string(what) + " needs at least 8 correspondences (got " +
                                std::to_string(left.size()) + ")");
  }
  for (size_t i = 0; i < left.size(); ++i) {
    if (!left[i].allFinite() || !right[i].allFinite()) {
      throw std::invalid_argument(std::string(what) + ": correspondence " + std::to_string(i) +
                                  " has a non-finite value");
    }
  }
}

// 8-point on a subset given by indices (no argument checks).
Eigen::Matrix3d EightPoint(const std::vector<Eigen::Vector2d>& left,
                           const std::vector<Eigen::Vector2d>& right,
                           const std::vector<size_t>& indices) {
  std::vector<Eigen::Vector2d> l, r;
  l.reserve(indices.size());
  r.reserve(indices.size());
  for (size_t i : indices) {
    l.push_back(left[i]);
    r.push_back(right[i]);
  }
  const Eigen::Matrix3d T1 = HartleyNormalisation2D(l);
  const Eigen::Matrix3d T2 = HartleyNormalisation2D(r);
  Eigen::MatrixXd A(static_cast<Eigen::Index>(indices.size()), 9);
  for (size_t k = 0; k < indices.size(); ++k) {
    const Eigen::Vector3d x1 = T1 * l[k].homogeneous();
    const Eigen::Vector3d x2 = T2 * r[k].homogeneous();
    // x2^T F x1 = 0 as a row of A for f = F row-major (H&Z eq. 11.3).
    const auto row = static_cast<Eigen::Index>(k);
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) A(row, 3 * a + b) = x2(a) * x1(b);
    }
  }
  Eigen::Matrix<double, 9, 1> f;
  if (A.rows() < 9) {
    // Pad to a square system so the full V is available (8-point minimal case).
    Eigen::MatrixXd padded = Eigen::MatrixXd::Zero(9, 9);
    padded.topRows(A.rows()) = A;
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(padded, Eigen::ComputeFullV);
    f = svd.matrixV().col(8);
  } else {
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
    f = svd.matrixV().col(8);
  }
  Eigen::Matrix3d F_normalised;
  F_normalised << f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7), f(8);
  // Rank 2: zero the smallest singular value (H&Z 11.1.1, Frobenius-closest singular matrix).
  Eigen::JacobiSVD<Eigen::Matrix3d> svd_f(F_normalised, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sigma = svd_f.singularValues();
  sigma(2) = 0.0;
  F_normalised = svd_f.matrixU() * sigma.asDiagonal() * svd_f.matrixV().transpose();
  Eigen::Matrix3d F = T2.transpose() * F_normalised * T1;
  const double norm = F.norm();
  if (norm > 0.0) F /= norm;
  return F;
}

double LeftDistance(const Eigen::Matrix3d& F, const Eigen::Vector2d& left,
                    const Eigen::Vector2d& right) {
  return EpipolarDistancePx(F.transpose(), right, left);
}

int Classify(const Eigen::Matrix3d& F, const std::vector<Eigen::Vector2d>& left,
             const std::vector<Eigen::Vector2d>& right, double threshold, std::vector<bool>* mask) {
  int count = 0;
  mask->assign(left.size(), false);
  for (size_t i = 0; i < left.size(); ++i) {
    const bool inlier = EpipolarDistancePx(F, left[i], right[i]) <= threshold &&
                        LeftDistance(F, left[i], right[i]) <= threshold;
    (*mask)[i] = inlier;
    count += inlier ? 1 : 0;
  }
  return count;
}

}  // namespace

std::string FundamentalRansacOptions::Check() const {
  std::ostringstream out;
  if (!(max_epipolar_distance_px > 0.0) || !std::isfinite(max_epipolar_distance_px)) {
    out << "FundamentalRansacOptions.max_epipolar_distance_px must be > 0 (is "
        << max_epipolar_distance_px << ")";
  } else if (!(confidence > 0.0 && confidence < 1.0)) {
    out << "FundamentalRansacOptions.confidence must be in (0, 1) (is " << confidence << ")";
  } else if (max_iterations < 1) {
    out << "FundamentalRansacOptions.max_iterations must be >= 1 (is " << max_iterations << ")";
  }
  return out.str();
}

double MeanEpipolarDistancePx(const Eigen::Matrix3d& F,
                              const std::vector<Eigen::Vector2d>& left_points,
                              const std::vector<Eigen::Vector2d>& right_points) {
  const size_t n = std::min(left_points.size(), right_points.size());
  if (n == 0) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) sum += EpipolarDistancePx(F, left_points[i], right_points[i]);
  return sum / static_cast<double>(n);
}

Eigen::Matrix3d EstimateFundamentalEightPoint(const std::vector<Eigen::Vector2d>& left_points,
                                              const std::vector<Eigen::Vector2d>& right_points) {
  CheckCorrespondences(left_points, right_points, "8-point F");
  std::vector<size_t> all(left_points.size());
  std::iota(all.begin(), all.end(), size_t{0});
  return EightPoint(left_points, right_points, all);
}

FundamentalReport EstimateFundamentalRansac(const std::vector<Eigen::Vector2d>& left_points,
                                            const std::vector<Eigen::Vector2d>& right_points,
                                            const FundamentalRansacOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  CheckCorrespondences(left_points, right_points, "RANSAC F");
  const size_t n = left_points.size();
  std::mt19937_64 generator(options.random_seed);
  std::vector<size_t> indices(n);
  std::iota(indices.begin(), indices.end(), size_t{0});

  FundamentalReport report;
  std::vector<bool> mask;
  int best_count = 0;
  Eigen::Matrix3d best_F = Eigen::Matrix3d::Zero();
  double needed_iterations = options.max_iterations;
  int iteration = 0;
  for (; iteration < options.max_iterations && iteration < needed_iterations; ++iteration) {
    // Partial Fisher-Yates: the first 8 entries become a uniform sample without repetition.
    for (size_t k = 0; k < 8; ++k) {
      std::uniform_int_distribution<size_t> pick(k, n - 1);
      std::swap(indices[k], indices[pick(generator)]);
    }
    const std::vector<size_t> sample(indices.begin(), indices.begin() + 8);
    const Eigen::Matrix3d F = EightPoint(left_points, right_points, sample);
    if (!F.allFinite()) continue;
    const int count =
        Classify(F, left_points, right_points, options.max_epipolar_distance_px, &mask);
    if (count > best_count) {
      best_count = count;
      best_F = F;
      // Samples needed so that one is all-inlier with the given confidence (H&Z eq. 4.18).
      const double inlier_ratio = static_cast<double>(count) / static_cast<double>(n);
      const double all_inlier = std::pow(inlier_ratio, 8.0);
      needed_iterations =
          all_inlier >= 1.0 ? 0.0 : std::log(1.0 - options.confidence) / std::log(1.0 - all_inlier);
    }
  }
  report.num_iterations = iteration;
  if (best_count < 8) {
    report.message = "no fundamental matrix with at least 8 inliers among " + std::to_string(n) +
                     " correspondences";
    report.inlier_mask.assign(n, false);
    return report;
  }
  Eigen::Matrix3d F = best_F;
  int count = Classify(F, left_points, right_points, options.max_epipolar_distance_px, &mask);
  if (options.refine_on_inliers) {
    // Re-estimate on the inliers and re-classify, while the consensus does not shrink.
    for (int round = 0; round < 3; ++round) {
      std::vector<size_t> inliers;
      for (size_t i = 0; i < n; ++i) {
        if (mask[i]) inliers.push_back(i);
      }
      const Eigen::Matrix3d refined = EightPoint(left_points, right_points, inliers);
      std::vector<bool> refined_mask;
      const int refined_count = Classify(refined, left_points, right_points,
                                         options.max_epipolar_distance_px, &refined_mask);
      if (!refined.allFinite() || refined_count < count) break;
      const bool unchanged = refined_mask == mask;
      F = refined;
      mask = refined_mask;
      count = refined_count;
      if (unchanged) break;
    }
  }
  report.success = true;
  report.F = F;
  report.inlier_mask = mask;
  report.num_inliers = count;
  double sum = 0.0, sum_symmetric = 0.0, sum_all = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double d_right = EpipolarDistancePx(F, left_points[i], right_points[i]);
    sum_all += d_right;
    if (!mask[i]) continue;
    sum += d_right;
    sum_symmetric += 0.5 * (d_right + LeftDistance(F, left_points[i], right_points[i]));
  }
  report.mean_epipolar_distance_px = sum / count;
  report.mean_symmetric_epipolar_distance_px = sum_symmetric / count;
  report.mean_epipolar_distance_all_px = sum_all / static_cast<double>(n);
  std::ostringstream message;
  message << count << " of " << n << " correspondences are inliers after " << iteration
          << " RANSAC samples; mean epipolar distance " << report.mean_epipolar_distance_px
          << " px";
  report.message = message.str();
  return report;
}

}  // namespace hnnstereo::calib
