// `hnnstereo probe`: the thesis's selective point matching - one left point, a correlation
// search along its epipolar line, its 3D position and the match statistics.
#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "app/cli_support.h"
#include "app/commands.h"
#include "calib/calibration.h"
#include "common/image.h"
#include "vision/sensing/position_sensing.h"
#include "vision/stereo/setup_checks.h"

namespace hnnstereo::app {
namespace {

struct ProbeArgs {
  std::string left, right, calib, point;
  std::string zrange = "-5,200";
  vision::ProbeOptions options;
};

void RunProbe(ProbeArgs& args) {
  Eigen::Vector2d left_point;
  {
    std::istringstream in(args.point);
    char comma = 0;
    double x = 0, y = 0;
    if (!(in >> x >> comma >> y) || comma != ',' || !in.eof()) {
      throw std::invalid_argument("--point must be X,Y in left-image pixels (got '" + args.point + "')");
    }
    left_point = {x, y};
  }
  {
    std::istringstream in(args.zrange);
    char comma = 0;
    if (!(in >> args.options.z_range_mm.first >> comma >> args.options.z_range_mm.second) ||
        comma != ',') {
      throw std::invalid_argument("--zrange must be ZMIN,ZMAX (got '" + args.zrange + "')");
    }
  }
  // Inputs that cannot be used are a refused setup (exit 2), found before any matching.
  const vision::LoadedImage left = AsSetupError("--left", [&] { return vision::LoadImage(args.left); });
  const vision::LoadedImage right =
      AsSetupError("--right", [&] { return vision::LoadImage(args.right); });
  const calib::StereoCalibration calibration =
      AsSetupError("--calib", [&] { return calib::LoadCalibration(args.calib); });
  AsSetupError([&] {
    vision::CheckSameSize(left, right);
    vision::CheckDistinctViews(left.grey, right.grey, "--left and --right");
  });
  if (auto problem = calibration.ImageSizeProblem(left.grey.cols, left.grey.rows); !problem.empty()) {
    throw std::invalid_argument("--calib '" + args.calib + "' " + problem);
  }
  if (calibration.rectified) {
    throw std::invalid_argument("probe needs the cell's CAL.yml (world frame), not a rectified calib.txt");
  }
  const vision::ProbeReport report =
      vision::ProbePoint(left.grey, right.grey, calibration, left_point, args.options);
  std::printf("left point      (%.2f, %.2f) px\n", left_point.x(), left_point.y());
  std::printf("epipolar search (%.1f, %.1f) -> (%.1f, %.1f) px for z %.0f..%.0f mm, %d positions\n",
              report.search_start.x(), report.search_start.y(), report.search_end.x(),
              report.search_end.y(), args.options.z_range_mm.first,
              args.options.z_range_mm.second, report.positions_tested);
  if (!report.found) {
    throw std::runtime_error("no positive correlation along the epipolar line (best ZNCC " +
                             std::to_string(report.zncc) + ")");
  }
  std::printf("right point     (%.2f, %.2f) px, %.3f px from the epipolar line\n",
              report.right_point.x(), report.right_point.y(), report.epipolar_distance_px);
  std::printf("ZNCC            %.3f (window %d), next best on the line %.3f, ratio %.2f\n",
              report.zncc, args.options.zncc_window, report.second_zncc,
              report.second_zncc > 0 ? report.zncc / report.second_zncc : 0.0);
  if (!report.point_in_world) throw std::runtime_error("the rays are parallel; no 3D point");
  const Eigen::Vector3d& X = *report.point_in_world;
  std::printf("3D point        (%.2f, %.2f, %.2f) mm, reprojection residual %.3f px\n", X.x(),
              X.y(), X.z(), report.reprojection_error_px);
  std::printf("height          %.2f mm above the table\n", X.z());
}

}  // namespace

void AddProbeCommand(CLI::App& app) {
  auto args = std::make_shared<ProbeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "probe",
      "Selective point matching (thesis debug tool): match one left-image point by ZNCC along "
      "its epipolar line in the right image and print its 3D position, its height and the match "
      "statistics.\n"
      "Example:\n"
      "  hnnstereo probe --left s3/left.png --right s3/right.png --calib s3/calib.yml "
      "--point 320,240");
  cmd->add_option("--left", args->left, "Left image")->required();
  cmd->add_option("--right", args->right, "Right image, same size")->required();
  cmd->add_option("--calib", args->calib, "CAL.yml of the cell (P1, P2, F)")->required();
  cmd->add_option("--point", args->point, "X,Y: the left-image pixel to match")->required();
  cmd->add_option("--zrange", args->zrange, "ZMIN,ZMAX: heights searched along the line (mm)")
      ->capture_default_str();
  cmd->add_option("--zncc-window", args->options.zncc_window, "ZNCC window side (odd)")
      ->capture_default_str();
  cmd->callback([args] { RunProbe(*args); });
}

}  // namespace hnnstereo::app
