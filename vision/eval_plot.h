#pragma once
// The precision-versus-density plot of `hnnstereo eval` (OpenCV drawing, no plotting library).

#include <opencv2/core.hpp>

#include "vision/evaluation.h"

namespace hnnstereo::vision {

/// One panel per pair: precision within 1 px (y, 0-100 %) against density (x, share of Canny
/// edge pixels with ground truth, 0-100 %), one coloured curve per method (most confident
/// matches first), single-point methods as dots; a legend in the first panel. CV_8UC3.
cv::Mat DrawPrecisionDensityPlot(const EvaluationReport& report);

}  // namespace hnnstereo::vision
