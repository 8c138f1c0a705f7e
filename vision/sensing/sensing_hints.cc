#include "vision/sensing/sensing_hints.h"

#include <Eigen/LU>
#include <algorithm>
#include <cstdio>

namespace hnnstereo::vision {
namespace {

std::string Format(const char* format, double a, double b = 0.0, double c = 0.0,
                   double d = 0.0) {
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer), format, a, b, c, d);
  return buffer;
}

// The optical axis of P in the world (unit; H&Z 6.2.3: det(M) m3 points forwards).
Eigen::Vector3d OpticalAxis(const calib::ProjectionMatrix& P) {
  const Eigen::Matrix3d M = P.leftCols<3>();
  return (M.determinant() * M.row(2).transpose()).normalized();
}

}  // namespace

std::string TableFrameProblem(const calib::StereoCalibration& calibration) {
  const double axis1 = OpticalAxis(calibration.P1).z(), axis2 = OpticalAxis(calibration.P2).z();
  if (calibration.world_frame == "left camera" ||
      !(calibration.C1.z() > 0.0 && calibration.C2.z() > 0.0 && axis1 < 0.0 && axis2 < 0.0)) {
    return Format("its world frame is not a table under the cameras (camera heights %.0f and "
                  "%.0f mm, optical axes' z %.2f and %.2f; a table frame has both above z = 0 "
                  "looking down): is CAL.yml's world frame the table? `calibrate --dir` with a "
                  "board lying on the table gives one",
                  calibration.C1.z(), calibration.C2.z(), axis1, axis2);
  }
  return {};
}

std::string CalibrationFitProblem(const SwapComparison& probe, double min_median_zncc) {
  if (probe.points < 8 || probe.as_given_zncc >= min_median_zncc) return {};
  return Format("the residuals say this calibration is not for this pair: along the epipolar "
                "lines of CAL.yml the left features' best ZNCC has median %.2f (below %.2f; a "
                "fitting calibration gives 0.95+): calibrate this rig, at this image size",
                probe.as_given_zncc, min_median_zncc);
}

std::vector<std::string> ExplainNoParts(const PositionSensingReport& report,
                                        const PositionSensingOptions& options) {
  if (!report.objects.empty()) return {};
  std::vector<std::string> hints;
  const TriangulationCounts& counts = report.triangulation;
  const int triangulated = counts.accepted + counts.large_residual;
  if (triangulated > 0 && 2 * counts.large_residual > triangulated) {
    hints.push_back(Format("the residuals say this calibration is not for this pair: %.0f of %.0f "
                           "matches reproject more than %.1f px off; calibrate this rig (and "
                           "check --left/--right are its cameras)",
                           counts.large_residual, triangulated,
                           options.max_reprojection_error_px));
  }
  const std::vector<Eigen::Vector3d>& points = report.points_in_world;
  if (!points.empty()) {
    std::vector<double> heights;
    for (const Eigen::Vector3d& point : points) heights.push_back(point.z());
    std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
    const double median = heights[heights.size() / 2];
    const auto below = std::count_if(points.begin(), points.end(), [&](const Eigen::Vector3d& p) {
      return p.z() < -options.grid.min_height_mm;
    });
    const auto above = std::count_if(points.begin(), points.end(), [&](const Eigen::Vector3d& p) {
      return p.z() > options.grid.max_height_mm;
    });
    const double count = static_cast<double>(points.size());
    if (2 * below > static_cast<long>(points.size())) {
      hints.push_back(Format("most points lie below the table plane (%.0f of %.0f, median z = "
                             "%.0f mm): is CAL.yml's world frame the table?",
                             static_cast<double>(below), count, median));
    } else if (2 * above > static_cast<long>(points.size())) {
      hints.push_back(Format("most points lie far above the table (%.0f of %.0f, median z = %.0f "
                             "mm): is CAL.yml's world frame the table?",
                             static_cast<double>(above), count, median));
    }
  }
  if (hints.empty()) {
    hints.push_back(Format("no part: %.0f points, none grouped into a part standing at least "
                           "%.0f mm above the table with %.0f points: is the table empty, and "
                           "are the images the cell's, lit and in focus?",
                           static_cast<double>(points.size()), options.grid.min_height_mm,
                           static_cast<double>(options.grid.min_points)));
  }
  return hints;
}

}  // namespace hnnstereo::vision
