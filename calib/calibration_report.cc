#include "calib/calibration_report.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "common/atomic_file.h"
#include "common/format.h"

namespace hnnstereo::calib {
namespace {

nlohmann::json StatisticsToJson(const ReprojectionStatistics& s) {
  return {{"mae_x_px", s.mae_x_px}, {"mae_y_px", s.mae_y_px},
          {"rms_x_px", s.rms_x_px}, {"rms_y_px", s.rms_y_px},
          {"mae_px", s.mae_px},     {"rms_px", s.rms_px},
          {"max_px", s.max_px},     {"num_points", s.residuals_px.size()}};
}

using common::Fixed;

}  // namespace

nlohmann::json ReportToJson(const CalibrationReport& report) {
  nlohmann::json json;
  json["method"] = report.method;
  json["num_views"] = report.num_views;
  json["elapsed_ms"] = report.elapsed_ms;
  json["mean_epipolar_distance_px"] = report.mean_epipolar_distance_px;
  json["num_epipolar_pairs"] = report.num_epipolar_pairs;
  json["notes"] = report.notes;
  json["error_definitions"] = {
      {"residual", "reprojected - measured, pixels"},
      {"mae", "mean absolute error (per axis: mean |dx|, |dy|; per point: mean Euclidean)"},
      {"rms", "root mean square error"}};
  json["cameras"] = nlohmann::json::array();
  for (const CameraCalibrationReport& camera : report.cameras) {
    nlohmann::json c;
    c["camera"] = camera.camera;
    c["camera_centre_mm"] = {camera.camera_centre.x(), camera.camera_centre.y(),
                             camera.camera_centre.z()};
    c["refined"] = camera.refined;
    c["linear"] = StatisticsToJson(camera.linear);
    c["final"] = StatisticsToJson(camera.final);
    c["points"] = nlohmann::json::array();
    for (const CalibrationObservation& o : camera.observations) {
      const Eigen::Vector2d error = o.reprojected_px - o.measured_px;
      c["points"].push_back(
          {{"view", o.view},
           {"label", o.label},
           {"world_mm", {o.point3D_in_world.x(), o.point3D_in_world.y(), o.point3D_in_world.z()}},
           {"measured_px", {o.measured_px.x(), o.measured_px.y()}},
           {"reprojected_px", {o.reprojected_px.x(), o.reprojected_px.y()}},
           {"error_x_px", error.x()},
           {"error_y_px", error.y()},
           {"error_px", error.norm()}});
    }
    json["cameras"].push_back(c);
  }
  json["extra"] = report.extra;
  return json;
}

std::string FormatReportTable(const CalibrationReport& report, bool per_point) {
  std::ostringstream out;
  out << "calibration (" << report.method << "): " << report.num_views << " view(s), "
      << Fixed(report.elapsed_ms, 0) << " ms\n";
  out << "reprojection error in pixels; MAE = mean absolute error, RMS = root mean square\n";
  out << "camera  points   MAE x   MAE y   RMS x   RMS y  MAE pt  RMS pt     max   "
         "centre (mm)\n";
  for (const CameraCalibrationReport& camera : report.cameras) {
    const ReprojectionStatistics& s = camera.final;
    char line[256];
    std::snprintf(line, sizeof(line),
                  "%-6s %7zu %7.3f %7.3f %7.3f %7.3f %7.3f %7.3f %7.3f   (%.2f, %.2f, %.2f)\n",
                  camera.camera.c_str(), s.residuals_px.size(), s.mae_x_px, s.mae_y_px, s.rms_x_px,
                  s.rms_y_px, s.mae_px, s.rms_px, s.max_px, camera.camera_centre.x(),
                  camera.camera_centre.y(), camera.camera_centre.z());
    out << line;
  }
  if (report.num_epipolar_pairs > 0) {
    out << "mean epipolar distance (right points to F x_left): "
        << Fixed(report.mean_epipolar_distance_px) << " px over " << report.num_epipolar_pairs
        << " pairs\n";
  }
  for (const std::string& note : report.notes) out << "note: " << note << "\n";
  if (per_point) {
    for (const CameraCalibrationReport& camera : report.cameras) {
      out << camera.camera << " camera, per point (view label  u v  error x y  |error|):\n";
      for (const CalibrationObservation& o : camera.observations) {
        const Eigen::Vector2d e = o.reprojected_px - o.measured_px;
        char line[200];
        std::snprintf(line, sizeof(line), "  %3d %-8s %9.3f %9.3f  %7.3f %7.3f  %6.3f\n", o.view,
                      o.label.c_str(), o.measured_px.x(), o.measured_px.y(), e.x(), e.y(),
                      e.norm());
        out << line;
      }
    }
  }
  return out.str();
}

cv::Mat DrawCalibrationOverlay(const cv::Mat& image,
                               const std::vector<CalibrationObservation>& observations) {
  cv::Mat canvas;
  if (image.empty()) {
    double max_x = 64, max_y = 64;
    for (const auto& o : observations) {
      max_x = std::max({max_x, o.measured_px.x(), o.reprojected_px.x()});
      max_y = std::max({max_y, o.measured_px.y(), o.reprojected_px.y()});
    }
    const int width = std::min(8192, static_cast<int>(max_x) + 32);
    const int height = std::min(8192, static_cast<int>(max_y) + 32);
    canvas = cv::Mat(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  } else if (image.channels() == 1) {
    cv::cvtColor(image, canvas, cv::COLOR_GRAY2BGR);
  } else {
    canvas = image.clone();
  }
  constexpr int kShift = 4;
  const auto point = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x() * (1 << kShift))),
                     static_cast<int>(std::lround(p.y() * (1 << kShift))));
  };
  constexpr double kErrorMagnification = 20.0;
  for (const CalibrationObservation& o : observations) {
    if (!o.measured_px.allFinite() || !o.reprojected_px.allFinite()) continue;
    cv::circle(canvas, point(o.measured_px), 5 << kShift, cv::Scalar(0, 200, 0), 1, cv::LINE_AA,
               kShift);
    const Eigen::Vector2d r = o.reprojected_px;
    cv::line(canvas, point(r - Eigen::Vector2d(3, 0)), point(r + Eigen::Vector2d(3, 0)),
             cv::Scalar(0, 0, 255), 1, cv::LINE_AA, kShift);
    cv::line(canvas, point(r - Eigen::Vector2d(0, 3)), point(r + Eigen::Vector2d(0, 3)),
             cv::Scalar(0, 0, 255), 1, cv::LINE_AA, kShift);
    cv::line(canvas, point(o.measured_px),
             point(o.measured_px + kErrorMagnification * (o.reprojected_px - o.measured_px)),
             cv::Scalar(0, 220, 255), 1, cv::LINE_AA, kShift);
  }
  cv::putText(canvas, "green o: measured  red +: reprojected  yellow: error x20",
              cv::Point(8, canvas.rows - 8), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 0, 255),
              1, cv::LINE_AA);
  return canvas;
}

void StoreErrorFigures(CalibrationResult* result) {
  auto& figures = result->calibration.error_figures;
  figures.clear();
  for (const CameraCalibrationReport& camera : result->report.cameras) {
    const ReprojectionStatistics& s = camera.final;
    const std::string prefix = camera.camera + "_";
    figures.emplace_back(prefix + "mae_x_px", s.mae_x_px);
    figures.emplace_back(prefix + "mae_y_px", s.mae_y_px);
    figures.emplace_back(prefix + "rms_x_px", s.rms_x_px);
    figures.emplace_back(prefix + "rms_y_px", s.rms_y_px);
    figures.emplace_back(prefix + "mae_px", s.mae_px);
    figures.emplace_back(prefix + "rms_px", s.rms_px);
    figures.emplace_back(prefix + "max_px", s.max_px);
  }
  if (result->report.num_epipolar_pairs > 0) {
    figures.emplace_back("mean_epipolar_distance_px", result->report.mean_epipolar_distance_px);
  }
}

std::vector<std::string> OverlayPaths(const std::string& calibration_path,
                                      const std::string& report_path) {
  const std::filesystem::path out(calibration_path);
  const std::filesystem::path folder =
      report_path.empty() ? out.parent_path() : std::filesystem::path(report_path).parent_path();
  const std::string stem = out.stem().string();
  return {(folder / (stem + "_left.png")).string(), (folder / (stem + "_right.png")).string()};
}

std::vector<std::string> WriteCalibrationOutputs(const CalibrationResult& result,
                                                 const std::string& calibration_path,
                                                 const std::string& report_path) {
  if (const std::string problem = result.calibration.Check(); !problem.empty()) {
    throw std::runtime_error("refusing to write calibration '" + calibration_path +
                             "': " + problem);
  }
  for (const std::string& path : {calibration_path, report_path}) {
    if (path.empty()) continue;
    const std::filesystem::path folder = std::filesystem::path(path).parent_path();
    if (!folder.empty() && !std::filesystem::is_directory(folder)) {
      throw std::runtime_error("output folder '" + folder.string() + "' does not exist");
    }
  }
  std::vector<std::string> written;
  const std::vector<std::string> overlay_paths = OverlayPaths(calibration_path, report_path);
  for (size_t i = 0; i < result.report.cameras.size() && i < overlay_paths.size(); ++i) {
    const cv::Mat& overlay = result.report.cameras[i].overlay;
    if (overlay.empty()) continue;
    WriteAtomically(overlay_paths[i], [&](const std::string& temporary) {
      if (!cv::imwrite(temporary, overlay)) {
        throw std::runtime_error("could not write '" + overlay_paths[i] + "'");
      }
    });
    written.push_back(overlay_paths[i]);
  }
  if (!report_path.empty()) {
    nlohmann::json json = ReportToJson(result.report);
    json["calibration_file"] = calibration_path;
    WriteFileAtomically(report_path, json.dump(2) + "\n");
    written.push_back(report_path);
  }
  SaveCalibration(result.calibration, calibration_path);
  written.push_back(calibration_path);
  return written;
}

}  // namespace hnnstereo::calib
