#pragma once
// Moravec interest operator (H. P. Moravec, "Towards automatic visual obstacle avoidance",
// IJCAI 1977), thesis 6.2.1 eq. 6.3. Hand-written: OpenCV has no Moravec operator.

#include <opencv2/core.hpp>

namespace hnnstereo::vision {

/// Moravec interest measure on a CV_8UC1 image: V(x, y) = min over the four directions
/// (1,0), (1,1), (0,1), (1,-1) of the sum over the `window` x `window` window centred at (x, y)
/// of the squared difference between each pixel and its neighbour one step along the direction
/// (eq. 6.3). Returns a CV_32F map of the image's size holding V at the local maxima of V
/// (`window` x `window` neighbourhood, equal values to the first in raster order) where
/// V > `threshold`, 0 elsewhere. `window` odd, >= 3. Throws std::invalid_argument otherwise.
cv::Mat MoravecResponse(const cv::Mat& grey, int window, double threshold);

}  // namespace hnnstereo::vision
