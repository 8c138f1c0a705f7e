#pragma once
// The fundamental matrix from point correspondences: the normalised 8-point algorithm with
// rank-2 enforcement (Hartley 1997, "In defense of the eight-point algorithm"; H&Z algorithm
// 11.1) inside RANSAC (Fischler & Bolles 1981; H&Z algorithm 11.4). The thesis used a plain
// 8-point method on raw pixels without rank-2 enforcement; THESIS.md section 1 keeps F from P1, P2
// (calib/epipolar.h) and adds this for uncalibrated pairs (`match` without --calib/--rectified).
// Convention: x2^T F x1 = 0, image 1 = left. Pure functions: no I/O, no globals.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace hnnstereo::calib {

/// Options of EstimateFundamentalRansac.
struct FundamentalRansacOptions {
  /// A correspondence is an inlier when both one-sided epipolar distances (right point to F x1,
  /// left point to F^T x2) are at most this many pixels.
  double max_epipolar_distance_px = 1.0;
  /// Stop when a sample of 8 inliers has been drawn with this probability (H&Z eq. 4.18).
  double confidence = 0.999;
  /// Upper bound on the RANSAC samples drawn.
  int max_iterations = 5000;
  /// Seed of the sample generator (results are reproducible for a given seed).
  std::uint64_t random_seed = 42;
  /// Re-estimate F from all inliers with the 8-point algorithm (and re-classify) at the end.
  bool refine_on_inliers = true;

  /// Empty when valid, otherwise a readable reason naming the field and its value.
  std::string Check() const;
};

/// What EstimateFundamentalRansac found. `success` is false (and F zero) when no F with at least
/// 8 inliers exists - an expected "no answer", not an error.
struct FundamentalReport {
  bool success = false;
  std::string message;                          ///< one line: what happened
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();  ///< rank 2, unit Frobenius norm, x2^T F x1 = 0
  std::vector<bool> inlier_mask;                ///< one flag per correspondence
  int num_inliers = 0;
  int num_iterations = 0;  ///< RANSAC samples drawn
  /// Mean over inliers of the distance of the right point to the epipolar line F x1 (px), the
  /// tau of thesis eq. 6.14.
  double mean_epipolar_distance_px = 0.0;
  /// Mean over inliers of the symmetric distance (both one-sided distances averaged, px).
  double mean_symmetric_epipolar_distance_px = 0.0;
  /// Mean over all correspondences of the right-point-to-line distance (px).
  double mean_epipolar_distance_all_px = 0.0;
};

/// Normalised 8-point algorithm with rank-2 enforcement on >= 8 correspondences (least squares
/// when more). Returns F with unit Frobenius norm, x2^T F x1 = 0 with x1 = left, x2 = right.
/// @throws std::invalid_argument when the sizes differ, fewer than 8 pairs or non-finite values.
Eigen::Matrix3d EstimateFundamentalEightPoint(const std::vector<Eigen::Vector2d>& left_points,
                                              const std::vector<Eigen::Vector2d>& right_points);

/// Robust F from putative matches left_points[i] <-> right_points[i] (pixels) by RANSAC over
/// minimal 8-point samples, then (optionally) the 8-point algorithm on all inliers.
/// @throws std::invalid_argument when the sizes differ, options are invalid, fewer than 8 pairs
///         are given, or a value is not finite.
FundamentalReport EstimateFundamentalRansac(const std::vector<Eigen::Vector2d>& left_points,
                                            const std::vector<Eigen::Vector2d>& right_points,
                                            const FundamentalRansacOptions& options = {});

/// Mean distance (px) of right points to the epipolar lines F x1 of their left partners.
double MeanEpipolarDistancePx(const Eigen::Matrix3d& F,
                              const std::vector<Eigen::Vector2d>& left_points,
                              const std::vector<Eigen::Vector2d>& right_points);

}  // namespace hnnstereo::calib
