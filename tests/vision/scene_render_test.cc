// The synthetic pick cell: seeded, truth consistent with the pixels, target calibratable.
#include "vision/scene_render.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <unistd.h>

#include "calib/circle_calibration.h"

namespace hnnstereo::vision {
namespace {

namespace fs = std::filesystem;

constexpr std::uint64_t kSeed = 11;

Eigen::Vector2d Project(const calib::ProjectionMatrix& P, const Eigen::Vector3d& X) {
  return (P * X.homogeneous()).hnormalized();
}

double MeanGrey(const cv::Mat& image, const Eigen::Vector2d& at, int radius) {
  const cv::Rect window(static_cast<int>(at.x()) - radius, static_cast<int>(at.y()) - radius,
                        2 * radius + 1, 2 * radius + 1);
  return cv::mean(image(window & cv::Rect(0, 0, image.cols, image.rows)))[0];
}

TEST(SceneRender, SameSeedSamePixelsOtherSeedOtherScene) {
  SceneRenderOptions options;
  options.seed = kSeed;
  options.num_objects = 3;
  const auto start = std::chrono::steady_clock::now();
  const RenderedScene a = RenderScene(options);
  std::cout << "render (3 parts, both images): "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
            << " s\n";
  const RenderedScene b = RenderScene(options);
  EXPECT_EQ(cv::norm(a.left, b.left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.right, b.right, cv::NORM_INF), 0.0);
  options.seed = kSeed + 1;
  const RenderedScene c = RenderScene(options);
  EXPECT_GT(cv::norm(a.left, c.left, cv::NORM_L1), 0.0);
  EXPECT_NE(a.objects[0].centre_mm, c.objects[0].centre_mm);
}

TEST(SceneRender, TruthIsWithinTheDocumentedRangesAndTallestFirst) {
  SceneRenderOptions options;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    options.seed = seed;
    options.num_objects = 0;  // 1-9 from the seed
    const RenderedScene scene = RenderScene(options);
    ASSERT_GE(scene.objects.size(), 1u);
    ASSERT_LE(scene.objects.size(), 9u);
    for (std::size_t i = 0; i < scene.objects.size(); ++i) {
      const SceneObject& object = scene.objects[i];
      EXPECT_GE(object.height_mm(), options.min_height_mm);
      EXPECT_LE(object.height_mm(), options.max_height_mm);
      EXPECT_GT(object.yaw_deg, -90.0);
      EXPECT_LE(object.yaw_deg, 90.0);
      if (object.shape == SceneObject::Shape::kBox) {
        EXPECT_GE(object.size_mm.x(), options.min_aspect * object.size_mm.y() - 1e-9);
      }
      if (i > 0) {
        EXPECT_GE(scene.objects[i - 1].height_mm(), object.height_mm());
      }
    }
  }
}

// The truth agrees with the pixels: each part's top centre is brighter than the dark table
// around the scene, and it appears in both images where the true cameras put it.
TEST(SceneRender, PartsAppearWhereTheTrueCamerasProjectThem) {
  SceneRenderOptions options;
  options.seed = kSeed;
  options.num_objects = 5;
  const RenderedScene scene = RenderScene(options);
  const double table_grey = MeanGrey(scene.left, {20, 20}, 10);
  EXPECT_LT(table_grey, 70.0) << "the table should be dark";
  for (const SceneObject& object : scene.objects) {
    const Eigen::Vector3d top(object.centre_mm.x(), object.centre_mm.y(), object.height_mm());
    EXPECT_GT(MeanGrey(scene.left, Project(scene.cameras.P1, top), 2), table_grey + 30.0);
    EXPECT_GT(MeanGrey(scene.right, Project(scene.cameras.P2, top), 2), table_grey + 30.0);
  }
  // The cameras are the thesis's: about 720 mm up, about 190 mm apart, not coplanar.
  EXPECT_NEAR((scene.cameras.C1 - scene.cameras.C2).norm(), 190.0, 10.0);
  EXPECT_NEAR(scene.cameras.C1.z(), 720.0, 10.0);
  EXPECT_GT(std::abs(scene.cameras.C1.z() - scene.cameras.C2.z()), 1.0);
}

TEST(SceneRender, DirectoryRoundTripsAndTheTargetCalibrates) {
  SceneRenderOptions options;
  options.seed = kSeed;
  options.num_objects = 2;
  const RenderedScene scene = RenderScene(options);
  const RenderedTarget target = RenderTargetPlacements(scene.cameras, options);
  const fs::path dir = fs::temp_directory_path() / ("hnnstereo_scene_" + std::to_string(::getpid()));
  WriteSceneDirectory(scene, target, dir.string());
  for (const char* name : {"left.png", "right.png", "calib.yml", "truth.json", "target/target.yml"}) {
    EXPECT_TRUE(fs::exists(dir / name)) << name;
  }
  const std::vector<SceneObject> truth = LoadTruthObjects((dir / "truth.json").string());
  ASSERT_EQ(truth.size(), scene.objects.size());
  EXPECT_NEAR((truth[0].centre_mm - scene.objects[0].centre_mm).norm(), 0.0, 1e-9);
  EXPECT_EQ(truth[0].shape, scene.objects[0].shape);
  const calib::TargetDescription description = calib::LoadTargetDirectory((dir / "target").string());
  EXPECT_EQ(description.placements.size(), options.target_heights_mm.size());

  // Calibrated from the images, the cameras reproject the truth's top centres within 0.5 px.
  const calib::CalibrationResult calibrated = calib::CalibrateCircleTarget((dir / "target").string());
  for (const SceneObject& object : scene.objects) {
    const Eigen::Vector3d top(object.centre_mm.x(), object.centre_mm.y(), object.height_mm());
    EXPECT_LT((Project(calibrated.calibration.P1, top) - Project(scene.cameras.P1, top)).norm(), 0.5);
    EXPECT_LT((Project(calibrated.calibration.P2, top) - Project(scene.cameras.P2, top)).norm(), 0.5);
  }
  fs::remove_all(dir);
}

TEST(SceneRender, BadOptionsAreRefusedWithTheFieldName) {
  SceneRenderOptions options;
  options.min_height_mm = 0.0;
  EXPECT_NE(options.Check().find("min_height_mm"), std::string::npos);
  EXPECT_THROW(RenderScene(options), std::invalid_argument);
  options = {};
  options.target_heights_mm = {0.0};
  EXPECT_THROW(RenderScene(options), std::invalid_argument);
  options = {};
  options.num_objects = 30;
  options.min_side_mm = options.max_side_mm = 80.0;
  options.min_aspect = 1.0;
  EXPECT_THROW(RenderScene(options), std::invalid_argument);  // cannot place 30 large parts
  EXPECT_THROW(LoadTruthObjects("/nonexistent/truth.json"), std::runtime_error);
}

}  // namespace
}  // namespace hnnstereo::vision
