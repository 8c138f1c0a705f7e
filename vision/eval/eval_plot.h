#pragma once
// The precision-versus-density plot of `hnnstereo eval` (OpenCV drawing, no plotting library).

#include <opencv2/core.hpp>

#include "vision/eval/evaluation.h"

namespace hnnstereo::vision {

/// One panel per pair: precision within 1 px (y, 0-100 %) against density (x, share of Canny
/// edge pixels with ground truth, 0-100 %), one coloured curve per method (most confident
/// matches first), single-point methods as dots; a legend in the first panel. CV_8UC3.
cv::Mat DrawPrecisionDensityPlot(const EvaluationReport& report);

/// One pair's ranked comparison (PairEvaluation::ranked), 1000x680: precision within 1 px (y,
/// range fitted to the data) against density (x, 0-100 % of Canny edge pixels with ground truth);
/// ranked methods as lines (HNN presets thick), swept methods as markers joined in sweep order
/// and labelled with their uniqueness ratio; dashed guides at 25 / 50 / 75 %; a legend.
/// Empty when the pair has no ranked methods. CV_8UC3.
cv::Mat DrawRankedPlot(const PairEvaluation& pair);

/// The first HNN preset's confidence calibration (RankedSummary::calibration), 900x560: error
/// rate (y) in each confidence bin (x, one slot per bin of kConfidenceBinEdges), one thick line
/// per scene type and overall, each pair a thin grey line, and dashed 1 - mean confidence (what a
/// calibrated confidence would give). Empty when no preset was ranked. CV_8UC3.
cv::Mat DrawCalibrationPlot(const EvaluationReport& report);

}  // namespace hnnstereo::vision
