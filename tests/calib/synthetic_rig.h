#pragma once
// Seeded synthetic stereo rig for the calibration tests: the thesis geometry (two cameras about
// 720 mm above the table, about 190 mm apart, not coplanar, looking down at the work area) and
// helpers that render the circle target at random poses.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "calib/circle_calibration.h"
#include "vision/synth/circle_target_render.h"

namespace hnnstereo::calib::testing {

struct StereoRig {
  ProjectionMatrix P1, P2;
  Eigen::Vector3d C1, C2;
  Eigen::Vector3d work_centre{100.0, 385.0, 0.0};
};

// Thesis camera centres (THESIS.md section 1): C1 = (86.4, 479.7, 719.9) mm, C2 = (81.1, 291.5,
// 711.9) mm; world +X appears to the right in both images.
inline StereoRig ThesisRig(double focal_px = 1400.0) {
  StereoRig rig;
  rig.C1 = {86.4, 479.7, 719.9};
  rig.C2 = {81.1, 291.5, 711.9};
  const Eigen::Vector2d principal(319.5, 239.5);
  rig.P1 = LookAtCamera(focal_px, principal, rig.C1, rig.work_centre + Eigen::Vector3d(0, 8, 0),
                        Eigen::Vector3d::UnitY());
  rig.P2 = LookAtCamera(focal_px * 1.01, principal + Eigen::Vector2d(4, -3), rig.C2,
                        rig.work_centre + Eigen::Vector3d(3, -6, 0), Eigen::Vector3d::UnitY());
  return rig;
}

struct SyntheticPlacement {
  Eigen::Matrix4d world_from_target;
  RenderedCircleTarget left, right;
};

// Renders `num_placements` placements of `grid` at random poses: plate centre within
// +-max_offset_mm of the work centre, placement h at height (h % num_levels) * height_step_mm
// (+-5 mm), yaw uniform in [0, 360) when random_yaw; a pose not fully visible in both images is
// drawn again. num_levels = 0 means one level per placement.
inline std::vector<SyntheticPlacement> RenderRandomPlacements(
    const StereoRig& rig, const CircleGridGeometry& grid, int num_placements, std::uint64_t seed,
    CircleTargetRenderOptions render, bool random_yaw = true, double max_offset_mm = 40.0,
    double height_step_mm = 50.0, int num_levels = 0) {
  const int levels = num_levels > 0 ? num_levels : num_placements;
  std::mt19937_64 generator(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::vector<SyntheticPlacement> placements;
  for (int h = 0; h < num_placements; ++h) {
    for (int attempt = 0; attempt < 5000; ++attempt) {
      const double yaw = random_yaw ? 180.0 + 180.0 * uniform(generator) : 0.0;
      // Target centre near the work centre; origin = circle (0, 0).
      const Eigen::Vector3d centre =
          rig.work_centre +
          Eigen::Vector3d(max_offset_mm * uniform(generator), max_offset_mm * uniform(generator),
                          (h % levels) * height_step_mm + 5.0 * uniform(generator));
      const Eigen::Vector3d half_extent(0.5 * (grid.cols - 1) * grid.pitch_mm,
                                        0.5 * (grid.rows - 1) * grid.pitch_mm, 0.0);
      const Eigen::Matrix4d at_centre = WorldFromTargetFlat(centre, yaw);
      const Eigen::Vector3d origin = (at_centre * (-half_extent).homogeneous()).hnormalized();
      SyntheticPlacement placement;
      placement.world_from_target = WorldFromTargetFlat(origin, yaw);
      // Cheap visibility check of the plate corners before rendering.
      bool visible = true;
      for (const ProjectionMatrix* P : {&rig.P1, &rig.P2}) {
        for (int corner = 0; corner < 4; ++corner) {
          const double margin = render.plate_margin_mm + 2.0;
          const Eigen::Vector3d in_target(
              (corner % 2 == 0) ? -margin : (grid.cols - 1) * grid.pitch_mm + margin,
              (corner / 2 == 0) ? -margin : (grid.rows - 1) * grid.pitch_mm + margin, 0.0);
          const Eigen::Vector3d x = *P * (placement.world_from_target * in_target.homogeneous());
          const Eigen::Vector2d pixel = x.hnormalized();
          visible = visible && x.z() > 0 && pixel.x() > 1 && pixel.y() > 1 &&
                    pixel.x() < render.image_width - 2 && pixel.y() < render.image_height - 2;
        }
      }
      if (!visible) continue;
      render.random_seed = seed * 1000 + static_cast<std::uint64_t>(h * 10 + attempt) * 2;
      placement.left = RenderCircleTarget(rig.P1, placement.world_from_target, grid, render);
      render.random_seed += 1;
      placement.right = RenderCircleTarget(rig.P2, placement.world_from_target, grid, render);
      if (placement.left.fully_visible && placement.right.fully_visible) {
        placements.push_back(placement);
        break;
      }
    }
  }
  return placements;
}

// Writes a TARGET_DIR (images + target.yml) for the placements; returns the folder.
inline void WriteTargetDirectory(const std::vector<SyntheticPlacement>& placements,
                                 const CircleGridGeometry& grid, const std::string& dir) {
  std::filesystem::create_directories(dir);
  TargetDescription target;
  target.grid = grid;
  for (size_t h = 0; h < placements.size(); ++h) {
    TargetPlacement placement;
    placement.left_image = "left_" + std::to_string(h) + ".png";
    placement.right_image = "right_" + std::to_string(h) + ".png";
    placement.world_from_target = placements[h].world_from_target;
    cv::imwrite(dir + "/" + placement.left_image, placements[h].left.image);
    cv::imwrite(dir + "/" + placement.right_image, placements[h].right.image);
    target.placements.push_back(placement);
  }
  SaveTargetDescription(target, dir + "/target.yml");
}

inline std::string TemporaryDirectory(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("hnnstereo_calib_test_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

}  // namespace hnnstereo::calib::testing
