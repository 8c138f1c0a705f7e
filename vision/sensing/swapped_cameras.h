#pragma once
// A calibrated pair given the wrong way round: the check that needs ProbePoint (position_sensing),
// so it sits in sensing, above the rectified-pair checks of vision/stereo/setup_checks.h.

#include <opencv2/core.hpp>
#include <utility>

#include "calib/calibration.h"

namespace hnnstereo::vision {

/// A calibrated, unrectified pair matched both ways round (see CompareWithSwappedCameras).
struct SwapComparison {
  int points = 0;                 ///< textured left points probed
  double as_given_zncc = 0.0;     ///< median best ZNCC along the epipolar segments, as given
  double swapped_zncc = 0.0;      ///< the same with the two images exchanged
  bool looks_swapped = false;     ///< swapped_zncc clearly above as_given_zncc
};

/// Probes up to 24 textured points (the strongest gradient of each 40 px cell) by ZNCC along
/// their epipolar segments over the heights `z_range_mm` (ProbePoint), once as given and once
/// with the two images exchanged (the same calibration). The images of a swapped pair correlate far
/// better the other way round. looks_swapped: swapped_zncc >= 0.7 and >= as_given_zncc + 0.15.
/// Callers run it only when something looks wrong (no parts found); covered by the
/// SwappedCellPairCorrelatesTheOtherWayRound (tests/vision/setup_checks_test.cc).
SwapComparison CompareWithSwappedCameras(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                         const calib::StereoCalibration& calibration,
                                         std::pair<double, double> z_range_mm);

}  // namespace hnnstereo::vision
