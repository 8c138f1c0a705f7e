#pragma once
// SUSAN edges and corners (Smith & Brady, "SUSAN - A New Approach to Low Level Image
// Processing", IJCV 23(1), 1997), thesis 6.2.2-6.2.3. Hand-written: OpenCV has no SUSAN.

#include <opencv2/core.hpp>

namespace hnnstereo::vision {

/// Pixels of the 37-pixel circular SUSAN mask (radius about 3.4 pixels, nucleus included).
inline constexpr int kSusanMaskPixels = 37;
/// Radius of the mask's bounding box: responses are computed at least this far from the border.
inline constexpr int kSusanMaskRadius = 3;

/// SUSAN edge detector on a CV_8UC1 image with brightness threshold `brightness_threshold` (t).
/// Returns a CV_32F map of the image's size: the edge response R = g - n (paper eq. 3, geometric
/// threshold g = 3/4 n_max) at pixels that survive non-maximum suppression across the edge, 0
/// elsewhere.
cv::Mat SusanEdgeResponse(const cv::Mat& grey, int brightness_threshold);

/// SUSAN corner detector: as SusanEdgeResponse with g = 1/2 n_max, the paper's false-positive
/// tests (USAN centre of gravity far from the nucleus, USAN contiguous towards it) and 7x7
/// non-maximum suppression. Returns a CV_32F map: R at corners, 0 elsewhere.
cv::Mat SusanCornerResponse(const cv::Mat& grey, int brightness_threshold);

}  // namespace hnnstereo::vision
