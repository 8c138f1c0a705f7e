// The point route through a lens (vision/stereo/lens_matching.h): the lens model against
// OpenCV's, windows read through it, features undistorted as points against features found on
// the undistorted images, and a distorted cell sensed by both routes.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "vision/eval/truth_comparison.h"
#include "vision/sensing/position_sensing.h"
#include "vision/stereo/correlation.h"
#include "vision/stereo/lens_distortion.h"
#include "vision/stereo/lens_matching.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::vision {
namespace {

const std::vector<double> kDistortion = {-0.25, 0.08, 0.001, -0.001};

Eigen::Matrix3d RenderK() {
  Eigen::Matrix3d K;
  K << 1100, 0, 319.5, 0, 1100, 239.5, 0, 0, 1;
  return K;
}

TEST(CameraLens, DistortIsOpenCvsProjectPoints) {
  const std::vector<Eigen::Vector2f> undistorted = {{-20, 30}, {319.5, 239.5}, {660, 500}, {100, 400}};
  for (const std::vector<double>& D :
       {kDistortion, std::vector<double>{-0.28, 0.09, 0.001, -0.0005, 0.02},
        std::vector<double>{-0.2, 0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.003}}) {
    const CameraLens lens{RenderK(), D};
    ASSERT_EQ(lens.Check(), "");
    const std::vector<Eigen::Vector2f> opencv = DistortPoints(undistorted, lens.K, D);
    for (std::size_t i = 0; i < undistorted.size(); ++i) {
      const Eigen::Vector2d ours = lens.Distort(undistorted[i].cast<double>());
      EXPECT_LT((ours - opencv[i].cast<double>()).norm(), 1e-3) << "D size " << D.size() << ", " << i;
    }
  }
}

TEST(CameraLens, CheckRefusesModelsItCannotEvaluate) {
  EXPECT_NE(CameraLens{RenderK(), {-0.2, 0.1, 0.0}}.Check(), "");
  EXPECT_NE(CameraLens{RenderK(), std::vector<double>(14, 0.0)}.Check(), "");
}

// The gradient per undistorted pixel is the chain rule: a captured ramp I = a . x_captured seen
// at an undistorted pixel has gradient J^T a.
TEST(CameraLens, GradientAtIsPerUndistortedPixel) {
  const CameraLens lens{RenderK(), kDistortion};
  cv::Mat gx(480, 640, CV_32F, cv::Scalar(3.0f)), gy(480, 640, CV_32F, cv::Scalar(-2.0f));
  const Eigen::Vector2d at(600.0, 60.0);
  const Eigen::Vector2d expected = lens.Jacobian(at).transpose() * Eigen::Vector2d(3.0, -2.0);
  EXPECT_LT((lens.GradientAt(gx, gy, at) - expected).norm(), 1e-6);
  EXPECT_GT((expected - Eigen::Vector2d(3.0, -2.0)).norm(), 0.05);  // the lens matters there
  EXPECT_EQ(lens.GradientAt(gx, gy, Eigen::Vector2d(-400.0, 60.0)), Eigen::Vector2d::Zero());
}

// Windows through the lens are the captured image's windows at the captured pixels.
TEST(ZnccMatcher, ThroughALensReadsTheCapturedPixels) {
  SceneRenderOptions options;
  options.seed = 5;
  options.cameras.distortion = kDistortion;
  const RenderedScene scene = RenderScene(options);
  const auto lens = LensOf(scene.cameras);
  ASSERT_TRUE(lens);
  DataTermOptions through;
  through.lens = lens;
  const ZnccMatcher plain(scene.left, scene.right, 7), lensed(scene.left, scene.right, 7, through);
  for (const Eigen::Vector2f& l : {Eigen::Vector2f(100, 80), Eigen::Vector2f(500, 400)}) {
    const Eigen::Vector2f r = l + Eigen::Vector2f(-30, 2);
    const Eigen::Vector2f l_captured = lens->left.Distort(l.cast<double>()).cast<float>();
    const Eigen::Vector2f r_captured = lens->right.Distort(r.cast<double>()).cast<float>();
    EXPECT_EQ(lensed(l, r), plain(l_captured, r_captured));
    EXPECT_EQ(lensed.ReverseSimilarity(l, r), plain.ReverseSimilarity(l_captured, r_captured));
  }
  float profile[3];
  EXPECT_THROW(lensed.RowProfile(Eigen::Vector2f(100, 80), 0, 2, profile), std::logic_error);
}

// The features the point route matches (found on the captured images, undistorted as points)
// lie where the image route finds them on the undistorted images.
TEST(MatcherThroughLens, UndistortedFeaturesAgreeWithTheImageRoutes) {
  SceneRenderOptions options;
  options.seed = 7;
  options.cameras.distortion = kDistortion;
  const RenderedScene scene = RenderScene(options);
  const auto lens = LensOf(scene.cameras);
  ASSERT_TRUE(lens);
  MatcherOptions matcher = PickCellMatcherOptions();
  matcher.features.max_features = 0;  // every edge pixel: the cap picks different ones
  const MatcherOptions through = MatcherThroughLens(matcher, scene.left, scene.right, lens);
  std::vector<Eigen::Vector2f> points = DetectFeatures(scene.left, matcher.features).points;
  through.features.map_points(scene.left, &points);
  const cv::Mat undistorted = UndistortImage(scene.left, lens->left.K, lens->left.D);
  const std::vector<Eigen::Vector2f> image_route = DetectFeatures(undistorted, matcher.features).points;
  ASSERT_GT(points.size(), 1000u);
  ASSERT_GT(image_route.size(), 1000u);
  cv::Mat found(undistorted.size(), CV_8U, cv::Scalar(0));
  for (const Eigen::Vector2f& p : image_route) {
    found.at<uchar>(static_cast<int>(p.y()), static_cast<int>(p.x())) = 255;
  }
  cv::dilate(found, found, cv::Mat::ones(3, 3, CV_8U));  // within 1 px (8-neighbourhood)
  std::size_t near = 0, inside = 0;
  for (const Eigen::Vector2f& p : points) {
    const int u = static_cast<int>(std::lround(p.x())), v = static_cast<int>(std::lround(p.y()));
    if (u < 0 || v < 0 || u >= found.cols || v >= found.rows) continue;
    ++inside;
    near += found.at<uchar>(v, u) ? 1 : 0;
  }
  EXPECT_GT(static_cast<double>(near), 0.9 * static_cast<double>(inside));
  // The other image of the pair is told apart; an image of neither is refused.
  std::vector<Eigen::Vector2f> right_points = {{600.0f, 40.0f}};
  through.features.map_points(scene.right, &right_points);
  EXPECT_LT((right_points[0] - UndistortPoints({{600.0f, 40.0f}}, lens->right.K, lens->right.D)[0])
                .norm(),
            1e-3f);
  const cv::Mat other = scene.left.clone();
  EXPECT_THROW(through.features.map_points(other, &right_points), std::logic_error);
}

// A distorted cell with its true K D R T: the point route finds every part, no false one, and
// its centroids are as close to the truth as the image route's.
TEST(PositionSensing, PointRouteSensesADistortedCellAsTheImageRouteDoes) {
  SceneRenderOptions options;
  options.seed = 7;
  options.cameras.distortion = kDistortion;
  const RenderedScene scene = RenderScene(options);
  double worst_mm[2] = {0.0, 0.0};
  for (LensRoute route : {LensRoute::kPoints, LensRoute::kImages}) {
    PositionSensingOptions sensing;
    sensing.matcher.engine = hnn::EngineKind::kCpu;
    sensing.lens_route = route;
    const PositionSensingReport report =
        SensePositions(scene.left, scene.right, scene.cameras, sensing, nullptr);
    const TruthComparison comparison = CompareWithTruth(report.objects, scene.objects);
    EXPECT_EQ(comparison.detected, static_cast<int>(scene.objects.size())) << LensRouteName(route);
    EXPECT_EQ(comparison.false_objects, 0) << LensRouteName(route);
    for (const TruthPairing& pair : comparison.pairs) {
      if (pair.detected_index >= 0) {
        worst_mm[static_cast<int>(route)] =
            std::max(worst_mm[static_cast<int>(route)], pair.centroid_error_mm);
      }
    }
  }
  EXPECT_LE(worst_mm[0], 0.5);
  EXPECT_LE(worst_mm[0], worst_mm[1] + 0.2);
}

}  // namespace
}  // namespace hnnstereo::vision
