#pragma once
// Sensing a calibrated cell pair, shared by `pick` and `serve`: the pick-cell matcher and the
// position-sensing options as command-line flags, and one call from image files to parts.

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "app/cli_support.h"
#include "calib/calibration.h"
#include "robot/pick_planning.h"
#include "common/image.h"
#include "vision/sensing/position_sensing.h"

namespace hnnstereo::app {

struct CellSensingFlags {
  std::string clustering = "grid";
  std::string yaw = "rectangle";
  std::string lens_route{vision::LensRouteName(vision::PositionSensingOptions().lens_route)};
  vision::PositionSensingOptions sensing;
  MatcherFlags flags;
  CellSensingFlags();  ///< the pick-cell matcher (PickCellMatcherOptions) as the flags' base
  void AddTo(CLI::App* cmd);
  /// Parses the string flags into `sensing`; throws std::invalid_argument with a one-line reason.
  void Resolve();
};

struct SensedPair {
  vision::LoadedImage left, right;
  vision::PositionSensingReport report;
};

/// Loads the pair (same size, the calibration's size) and senses it (through the lens when D is
/// present: PositionSensingOptions::lens_route).
/// Builds and runs the opencl engine's kernels once (OpenClEngine::WarmUp) for the cell's
/// matcher settings, so that the first trigger costs what later ones do; no-op without a
/// runtime or for the other engines. Returns the milliseconds spent.
double WarmUpCellKernels(ocl::Runtime* runtime, const vision::MatcherOptions& matcher);

SensedPair SenseCellPair(const std::string& left_path, const std::string& right_path,
                         const calib::StereoCalibration& calibration,
                         const std::string& calibration_name, const CellSensingFlags& flags,
                         ocl::Runtime* runtime);

/// OBJECTS.json as `pick` writes it: the report's objects and figures, and the input files.
nlohmann::json ObjectsFileJson(const SensedPair& pair, const CellSensingFlags& flags,
                               const std::string& left_path, const std::string& right_path,
                               const std::string& calibration_path);

/// The pair's grey images in the pixels P1, P2 and F refer to: as stored, or undistorted
/// (resampled) when the calibration carries distortion - for the probes along epipolar lines.
std::pair<cv::Mat, cv::Mat> GreyInCalibrationPixels(const SensedPair& pair,
                                                    const calib::StereoCalibration& calibration);

/// The left image for overlays drawn through P1: as stored, or undistorted when the calibration
/// carries distortion (P1 then refers to undistorted pixels).
cv::Mat OverlayImageOf(const SensedPair& pair, const calib::StereoCalibration& calibration);

/// An overlay drawn on OverlayImageOf's image, in the input image's pixels: resampled back
/// through the lens when the calibration carries distortion, else as drawn.
cv::Mat OverlayInInputPixels(const cv::Mat& overlay, const calib::StereoCalibration& calibration);

/// The robot side's view of the parts (ids 1.. in the report's order, tallest first).
std::vector<robot::SensedObject> SensedObjectsOf(const vision::PositionSensingReport& report);

}  // namespace hnnstereo::app
