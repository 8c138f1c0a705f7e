#pragma once
// Matching through a lens without resampling the images (LensRoute::kPoints): features found on
// the captured images, their points undistorted for the epipolar gate and the network's
// geometry, every window read from the captured images around the captured pixels.

#include <memory>
#include <opencv2/core.hpp>

#include "calib/calibration.h"
#include "vision/stereo/lens_distortion.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

/// Both lenses of a calibration with distortion (D1, D2 present); null without. Throws
/// std::invalid_argument when a model is one CameraLens cannot evaluate.
std::shared_ptr<const StereoLens> LensOf(const calib::StereoCalibration& calibration);

/// `matcher` for MatchStereo on the captured pair `left`, `right` (those very cv::Mat buffers):
/// features undistorted (FeatureOptions::map_points, which tells the two images apart by their
/// pixel buffers) and windows read through the lens (DataTermOptions::lens). The report's
/// points are then undistorted pixels, as P and F want them.
MatcherOptions MatcherThroughLens(MatcherOptions matcher, const cv::Mat& left,
                                  const cv::Mat& right, std::shared_ptr<const StereoLens> lens);

/// RefineMatches for a report of MatcherThroughLens: the epipolar snap in undistorted pixels, and
/// the parabola sub-pixel fit of ZNCC along the epipolar line with each window taken
/// (bilinearly) around its captured pixel. The left-right check and the row fit are for
/// rectified pairs without a lens: refused (std::invalid_argument).
void RefineMatchesThroughLens(const cv::Mat& left, const cv::Mat& right,
                              const calib::StereoCalibration& calibration,
                              const MatcherOptions& matcher, const RefinementOptions& refinement,
                              const StereoLens& lens, MatchReport* report);

/// Moves `match`'s right point (undistorted, on the left point's epipolar line F x_l) along
/// that line to the vertex of the parabola through ZNCC at -1, 0, +1 px (at most 0.5 px), the
/// `window` x `window` windows read from the captured images around each point's captured pixel.
void SubpixelAlongEpipolarLineThroughLens(const cv::Mat& left, const cv::Mat& right,
                                          const Eigen::Matrix3d& F, const StereoLens& lens,
                                          int window, StereoMatch* match);

/// The report's matches and features in the captured images' pixels (CameraLens::Distort), as
/// MATCHES.csv and overlays on the captured images want them.
void MatchesToCapturedPixels(const StereoLens& lens, MatchReport* report);

}  // namespace hnnstereo::vision
