#pragma once
// Overlay images people look at instead of reading numbers.

#include <opencv2/core.hpp>
#include <string>

#include "common/image.h"  // WritePngAtomically
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

/// A BGR 8-bit copy of an image for drawing: 16-bit scaled by its range, grey and BGRA converted.
cv::Mat ToColour8(const cv::Mat& image);

/// Left and right images side by side: every feature as a dim dot, matched features coloured by
/// disparity (blue near zero, red at the largest) and joined by a line for every `line_every`-th
/// match; below them a 56 px legend: the colour bar with its scale in px, the number of matches
/// and features, the engine, the device and the time.
cv::Mat DrawMatchOverlay(const cv::Mat& left, const cv::Mat& right, const MatchReport& report,
                         int line_every = 60);

}  // namespace hnnstereo::vision
