#pragma once
// The pictures of a pick (THESIS.md section 4, display): the left image with every feature,
// the matched features, each part's centroid and orientation line projected back with P; the
// depth (height) histogram of the triangulated points; the Hopfield energy trace. Drawn with
// OpenCV; written with WritePngAtomically (vision/overlay.h).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "host/solve_report.h"
#include "vision/sensing/position_sensing.h"

namespace hnnstereo::vision {

/// A distinct BGR colour per cluster label (grey for -1).
cv::Scalar LabelColour(int label);

/// The left image (dimmed): all left features as grey dots, matched features coloured by
/// their part (white when in no part), each part's top-face centroid as a cross with its id,
/// and its orientation line (`line_length_mm` long, along yaw through the centroid, at the top
/// height) projected with P1, so a negative yaw is drawn turning to the image's right of +x
/// the same way the table sees it.
cv::Mat DrawObjectOverlay(const cv::Mat& left_image, const PositionSensingReport& report,
                          const calib::ProjectionMatrix& P1, double line_length_mm = 40.0);

/// A histogram of the heights (z, mm) of the triangulated points, with the detected part
/// heights marked. 640 x 360 px.
cv::Mat PlotHeightHistogram(const PositionSensingReport& report, double bin_mm = 2.0);

/// Energy against iteration of the network's run (solve.energy_trace). 640 x 360 px.
cv::Mat PlotEnergyTrace(const hnn::SolveReport& solve);

}  // namespace hnnstereo::vision
