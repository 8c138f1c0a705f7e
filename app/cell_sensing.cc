#include "app/cell_sensing.h"

#include "app/cli_support.h"

#include <stdexcept>

#include "vision/stereo/lens_distortion.h"
#include "vision/stereo/setup_checks.h"

namespace hnnstereo::app {

CellSensingFlags::CellSensingFlags() { flags.options = vision::PickCellMatcherOptions(); }

void CellSensingFlags::AddTo(CLI::App* cmd) {
  cmd->add_option("--clustering", clustering,
                  "grid (default: 3D density clustering, separates parts of equal height) or "
                  "thesis (leader clustering on height, thresholds of the thesis code)")
      ->capture_default_str();
  cmd->add_option("--yaw", yaw,
                  "rectangle (long side of the top face's minimum-area rectangle) or moments "
                  "(thesis: 0.5 atan2(2 mu11, mu20 - mu02))")
      ->capture_default_str();
  cmd->add_option("--lens-route", lens_route,
                  "With lens distortion in --calib: points (features undistorted as points, the "
                  "captured images read as they are) or images (both images undistorted first)")
      ->capture_default_str();
  cmd->add_option("--max-residual", sensing.max_reprojection_error_px,
                  "Reject points whose reprojection residual exceeds this (px)")
      ->capture_default_str();
  cmd->add_option("--min-edge-angle", sensing.min_edge_epipolar_angle_deg,
                  "Reject matches on edges within this angle of their epipolar line (deg)")
      ->capture_default_str();
  cmd->add_option("--cell", sensing.grid.cell_mm, "Grid clustering cell edge (mm)")
      ->capture_default_str();
  cmd->add_option("--min-points", sensing.grid.min_points,
                  "Grid clustering: smallest part, in points")
      ->capture_default_str();
  cmd->add_option("--min-height", sensing.grid.min_height_mm,
                  "Grid clustering: points below this height are the table (mm)")
      ->capture_default_str();
  cmd->add_option("--min-top-width", sensing.min_top_width_mm,
                  "Drop parts whose top face is narrower than this (mm): a line of points on a "
                  "tall part's side is not a part (0 keeps all)")
      ->capture_default_str();
  cmd->add_option("--min-whole-top-width", sensing.min_whole_top_width_mm,
                  "Flag parts (\"merged\": true, refused by the safety gate) whose top face is "
                  "narrower than this (mm): a sliver of a face, not a face. Set it below your "
                  "narrowest part (0 flags none)")
      ->capture_default_str();
  cmd->add_option("--max-whole-top-length", sensing.max_whole_top_length_mm,
                  "Flag parts whose top face is longer than this (mm): parts the clustering "
                  "joined. Set it above your longest part (0 flags none)")
      ->capture_default_str();
  cmd->add_option("--min-touching-fill", sensing.min_touching_top_fill,
                  "Flag a part beside another (or in a taller one's shadow) unless its top is "
                  "round or fills this fraction of its minimum-area rectangle (0 flags none)")
      ->capture_default_str();
  cmd->add_option("--min-taller-touching", sensing.min_taller_touching_points,
                  "Flag a part (not round) with this many points of taller parts beside it: "
                  "their walls may hide a strip of its top. Pick tallest first and it is seen "
                  "whole later (0 flags none)")
      ->capture_default_str();
  cmd->add_option("--shadow-strip-reach", sensing.shadow_strip_reach_mm,
                  "Flag a box whose top has an empty strip, no point at any height, between a "
                  "side and a taller part up to this far (mm): the taller part's shadow may hide "
                  "the rest of its top (\"shadow_strip_mm\" says how wide; 0 flags none)")
      ->capture_default_str();
  cmd->add_option("--image-border", sensing.image_border_px,
                  "Flag parts whose top face reaches within this many pixels of either image's "
                  "border: part of it may be out of view (\"at_image_border\": true; 0 flags none)")
      ->capture_default_str();
  AddSwitch(cmd, "image-edges", &sensing.extend_tops_to_image_edges,
            "Fit box tops to the left image's edges: a side of a top the matches left short, or "
            "stretched past the face, moves to the face's edge seen in the image "
            "(\"image_edge_moved_mm\" in the output says how far)");
  AddSwitch(cmd, "flag-unplaced", &sensing.flag_unplaced_sides,
            "Flag a box whose top keeps a side with no edge under it in the left image that the "
            "image-edge fit could not place (\"unplaced_sides\" in the output)");
  AddSwitch(cmd, "subpixel", &sensing.refinement.epipolar_subpixel,
            "Before triangulating, move each match's right point along its epipolar line to the "
            "sub-pixel peak of ZNCC (it is snapped onto the line either way; heights about 2.5x "
            "tighter)");
  cmd->add_option("--leader-threshold", sensing.leader.threshold_mm,
                  "Thesis clustering: join/merge distance of heights (mm)")
      ->capture_default_str();
  flags.unrectified_cell = true;
  flags.AddTo(cmd);
}

void CellSensingFlags::Resolve() {
  // The library's pick-cell resolution, as the facade's SensePositions does.
  flags.settings =
      api::ResolvePickCellSettings(flags.GivenOverrides(), vision::PickCellMatcherOptions());
  flags.options = flags.settings.matcher;
  flags.refinement = flags.settings.refinement;
  flags.device = flags.settings.device;
  sensing.matcher = flags.options;
  if (auto method = vision::ParseClusteringMethod(clustering)) {
    sensing.clustering = *method;
  } else {
    throw std::invalid_argument("unknown --clustering '" + clustering + "' (grid or thesis)");
  }
  if (auto route = vision::ParseLensRoute(lens_route)) {
    sensing.lens_route = *route;
  } else {
    throw std::invalid_argument("unknown --lens-route '" + lens_route + "' (points or images)");
  }
  if (auto method = vision::ParseYawMethod(yaw)) {
    sensing.pose.yaw_method = *method;
  } else {
    throw std::invalid_argument("unknown --yaw '" + yaw + "' (rectangle or moments)");
  }
  if (const std::string problem = sensing.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
}

double WarmUpCellKernels(ocl::Runtime* runtime, const vision::MatcherOptions& matcher) {
  if (runtime == nullptr || matcher.engine != hnn::EngineKind::kOpenCL) return 0.0;
  hnn::OpenClEngine engine(*runtime, matcher.opencl);
  return engine.WarmUp(matcher.energy, matcher.dynamics, matcher.candidates.kind);
}

SensedPair SenseCellPair(const std::string& left_path, const std::string& right_path,
                         const calib::StereoCalibration& calibration,
                         const std::string& calibration_name, const CellSensingFlags& flags,
                         ocl::Runtime* runtime) {
  SensedPair pair;
  // An image that cannot be read is a refused setup (exit 2 from pick; serve's loop publishes
  // it as that cycle's sensing error).
  AsSetupError([&] {
    pair.left = vision::LoadImage(left_path);
    pair.right = vision::LoadImage(right_path);
    vision::CheckSameSize(pair.left, pair.right);
  });
  if (auto problem = calibration.ImageSizeProblem(pair.left.grey.cols, pair.left.grey.rows);
      !problem.empty()) {
    throw std::invalid_argument("--calib '" + calibration_name + "' " + problem);
  }
  // Named after the options here; SensePositions checks again for library callers.
  vision::CheckDistinctViews(pair.left.grey, pair.right.grey, "--left and --right");
  // A board calibration refers P to undistorted pixels (docs/calibration.md): SensePositions
  // senses through the lens (OBJECTS.json is in world mm).
  pair.report =
      vision::SensePositions(pair.left.grey, pair.right.grey, calibration, flags.sensing, runtime);
  return pair;
}

std::pair<cv::Mat, cv::Mat> GreyInCalibrationPixels(const SensedPair& pair,
                                                    const calib::StereoCalibration& calibration) {
  if (!calibration.intrinsics || calibration.intrinsics->D1.empty()) {
    return {pair.left.grey, pair.right.grey};
  }
  const calib::Intrinsics& lens = *calibration.intrinsics;
  return {vision::UndistortImage(pair.left.grey, lens.K1, lens.D1),
          vision::UndistortImage(pair.right.grey, lens.K2, lens.D2)};
}

nlohmann::json ObjectsFileJson(const SensedPair& pair, const CellSensingFlags& flags,
                               const std::string& left_path, const std::string& right_path,
                               const std::string& calibration_path) {
  nlohmann::json json = vision::ObjectsJson(pair.report, flags.sensing);
  json["left"] = left_path;
  json["right"] = right_path;
  json["calib"] = calibration_path;
  return json;
}

cv::Mat OverlayImageOf(const SensedPair& pair, const calib::StereoCalibration& calibration) {
  if (!calibration.intrinsics || calibration.intrinsics->D1.empty()) return pair.left.original;
  return vision::UndistortImage(pair.left.grey, calibration.intrinsics->K1,
                                calibration.intrinsics->D1);
}

cv::Mat OverlayInInputPixels(const cv::Mat& overlay, const calib::StereoCalibration& calibration) {
  if (!calibration.intrinsics || calibration.intrinsics->D1.empty()) return overlay;
  return vision::RedistortImage(overlay, calibration.intrinsics->K1, calibration.intrinsics->D1);
}

std::vector<robot::SensedObject> SensedObjectsOf(const vision::PositionSensingReport& report) {
  std::vector<robot::SensedObject> objects;
  int id = 1;
  for (const vision::ObjectPose& pose : report.objects) {
    // A round part has no orientation: yaw 0 is sent (no needless wrist turn).
    objects.push_back(
        {id++, pose.centroid, pose.height_mm, pose.round ? 0.0 : pose.yaw_deg, pose.merged});
  }
  return objects;
}

}  // namespace hnnstereo::app
