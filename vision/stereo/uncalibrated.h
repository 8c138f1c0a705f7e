#pragma once
// Epipolar geometry of an uncalibrated pair (`match` with neither --calib nor --rectified):
// confident putative matches (ORB descriptors, or ZNCC between corners), then F by normalised 8-point + RANSAC
// (calib/fundamental.h), then the canonical projective cameras of F for gating.

#include <opencv2/core.hpp>
#include <string>

#include "calib/calibration.h"
#include "calib/fundamental.h"

namespace hnnstereo::vision {

/// How putative matches for F are found.
enum class PutativeMatches {
  /// ORB keypoints, Hamming ratio test, mutual best (default: rotation invariant; on the OpenCV
  /// books pair correlation windows gave 41 putative matches of which only 9 fitted one F).
  kOrb,
  kCorrelation,  ///< Shi-Tomasi corners, best ZNCC within a radius, mutual best
};

struct UncalibratedOptions {
  PutativeMatches putative = PutativeMatches::kOrb;
  double orb_ratio = 0.8;          ///< Lowe's ratio test on Hamming distances
  int max_corners = 1500;          ///< corners / ORB keypoints per image
  double corner_quality = 0.005;   ///< relative to the strongest corner
  double corner_min_distance_px = 6.0;
  int zncc_window = 11;            ///< window side for the putative matches (odd, <= 15)
  double max_shift_fraction = 0.3; ///< search radius, as a fraction of the image width
  double min_correlation = 0.8;    ///< a putative match needs at least this ZNCC
  double min_margin = 0.03;        ///< best minus second-best ZNCC (ambiguity test)
  calib::FundamentalRansacOptions ransac;  ///< default 1 px threshold, seeded
  std::string Check() const;
};

struct UncalibratedReport {
  calib::StereoCalibration calibration;  ///< F, and P1 = [I | 0], P2 = [[e2]x F | e2] (projective)
  calib::FundamentalReport fundamental;
  int n_putative = 0;                    ///< mutual-best confident correlation matches
  double time_ms = 0.0;
};

/// Estimates F from the images. Throws std::runtime_error with a one-line reason when too few
/// confident matches exist or RANSAC finds no consistent F.
UncalibratedReport EstimateEpipolarGeometry(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                            const UncalibratedOptions& options = {});

/// The canonical camera pair of F (Hartley & Zisserman, result 9.14): P1 = [I | 0],
/// P2 = [[e2]x F | e2] with F^T e2 = 0.
calib::StereoCalibration CanonicalCamerasFromFundamental(const Eigen::Matrix3d& F);

}  // namespace hnnstereo::vision
