#pragma once
// What a calibration did and how well: per camera the observations (world point, measured and
// reprojected pixel), MAE and RMS per axis and per point, the camera centre; the epipolar
// consistency of the pair. Written as JSON (--report), printed as a table, and drawn as one
// overlay image per camera. Outputs are written atomically (calib/atomic_file.h).

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "calib/dlt.h"

namespace hnnstereo::calib {

/// One 3D-2D correspondence used by the calibration, with its reprojection.
struct CalibrationObservation {
  Eigen::Vector3d point3D_in_world = Eigen::Vector3d::Zero();  ///< mm
  Eigen::Vector2d measured_px = Eigen::Vector2d::Zero();       ///< detected / given
  Eigen::Vector2d reprojected_px = Eigen::Vector2d::Zero();    ///< through the final model
  int view = 0;       ///< height (circles), image pair (chessboard), 0 (known points)
  std::string label;  ///< e.g. "r0c2"
};

/// The report of one camera.
struct CameraCalibrationReport {
  std::string camera;  ///< "left" or "right"
  std::vector<CalibrationObservation> observations;
  ReprojectionStatistics linear;                            ///< linear DLT (circles, known points)
  ReprojectionStatistics final;                             ///< the model written to CAL.yml
  Eigen::Vector3d camera_centre = Eigen::Vector3d::Zero();  ///< world (mm)
  bool refined = false;                                     ///< nonlinear refinement kept
  cv::Mat overlay;  ///< detected and reprojected points drawn (BGR)
};

/// The report of a stereo calibration.
struct CalibrationReport {
  std::string method;                            ///< "circles", "chessboard" or "points"
  std::vector<CameraCalibrationReport> cameras;  ///< left, right
  /// Mean distance (px) of the right measured points to the epipolar lines F x1 of their left
  /// partners (points seen by both cameras).
  double mean_epipolar_distance_px = 0.0;
  int num_epipolar_pairs = 0;
  int num_views = 0;
  double elapsed_ms = 0.0;
  std::vector<std::string> notes;                   ///< e.g. how the circle ordering was decided
  nlohmann::json extra = nlohmann::json::object();  ///< method-specific figures
};

/// A calibration and its report, ready to be written.
struct CalibrationResult {
  StereoCalibration calibration;
  CalibrationReport report;
};

/// The report as JSON (units in the key names: _px, _mm).
nlohmann::json ReportToJson(const CalibrationReport& report);

/// A readable table for stdout: per camera MAE / RMS per axis and per point, max, centre; and
/// the per-point list when `per_point` is true.
std::string FormatReportTable(const CalibrationReport& report, bool per_point = false);

/// Draws measured points (green rings), reprojected points (red crosses) and the error vectors
/// magnified 20x (yellow) on a copy of `image` (grey or BGR); an empty image gives a white
/// canvas large enough for the points.
cv::Mat DrawCalibrationOverlay(const cv::Mat& image,
                               const std::vector<CalibrationObservation>& observations);

/// Fills the error figures of result->calibration from the report (left_mae_px, ...).
void StoreErrorFigures(CalibrationResult* result);

/// Where the overlays go: beside --report when given, else beside --out:
/// "<out stem>_left.png" and "<out stem>_right.png".
std::vector<std::string> OverlayPaths(const std::string& calibration_path,
                                      const std::string& report_path);

/// Writes the overlays, then the JSON report (when `report_path` is not empty), then CAL.yml,
/// each atomically. Returns the paths written. Nothing is written when the calibration fails its
/// Check(). @throws std::runtime_error with a one-line reason.
std::vector<std::string> WriteCalibrationOutputs(const CalibrationResult& result,
                                                 const std::string& calibration_path,
                                                 const std::string& report_path);

}  // namespace hnnstereo::calib
