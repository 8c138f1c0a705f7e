#pragma once
// Why a pick cell's run found nothing, said in the user's words: a calibration whose world frame
// is not the table, a calibration for another rig, points below the table. `pick` and `serve`
// print these (stderr) and write them into OBJECTS.json ("warnings"); never "0 parts" silently.

#include <string>
#include <vector>

#include "calib/calibration.h"
#include "vision/sensing/position_sensing.h"
#include "vision/sensing/swapped_cameras.h"

namespace hnnstereo::vision {

/// Empty when the world frame of `calibration` can be a pick cell's table (z = 0 on the table,
/// z up): both camera centres above z = 0 and both optical axes pointing down (-z; the axis is
/// det(M) m3, H&Z 6.2.3). Otherwise a one-line reason with the hint, e.g. for CAL.yml from
/// `calibrate --target chessboard`, whose world frame is the left camera.
std::string TableFrameProblem(const calib::StereoCalibration& calibration);

/// Empty when the pair fits its calibration; otherwise "the residuals say this calibration is not
/// for this pair ..." with the figure. The probe's median best ZNCC along the epipolar segments
/// (CompareWithSwappedCameras, at least 8 points) is 0.99 on the synthetic cell with its own
/// calibration, 0.84 with its right camera turned 8 deg about the vertical, 0.79 moved 10 mm, 0.69
/// moved 40 mm; below 0.9 the epipolar lines miss the features (tests/app/lens_calibration_cli_test.cc).
std::string CalibrationFitProblem(const SwapComparison& probe, double min_median_zncc = 0.9);

/// When `report` has no part: the likeliest reasons, most telling first, each one line ending in
/// what to check. Thresholds: more than half the triangulated matches rejected for their
/// residual means the calibration does not fit the pair; more than half the accepted points
/// below -options.grid.min_height_mm (or above grid.max_height_mm) means the world frame is not
/// the table. Empty when parts were found.
std::vector<std::string> ExplainNoParts(const PositionSensingReport& report,
                                        const PositionSensingOptions& options);

}  // namespace hnnstereo::vision
