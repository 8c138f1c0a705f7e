// The point route through a lens (vision/stereo/lens_matching.h): the lens model against
// OpenCV's, windows read through it, features undistorted as points against features found on
// the undistorted images, and a distorted cell sensed by both routes.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
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

// Scene `seed` of the cell through kDistortion (both cameras; scene.cameras carries K D R T).
RenderedScene RenderDistorted(std::uint64_t seed) {
  SceneRenderOptions options;
  options.seed = seed;
  options.cameras.distortion = kDistortion;
  return RenderScene(options);
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
  const CameraLens three{RenderK(), {-0.2, 0.1, 0.0}};
  const CameraLens fourteen{RenderK(), std::vector<double>(14, 0.0)};
  EXPECT_NE(three.Check(), "");
  EXPECT_NE(fourteen.Check(), "");
}

// The gradient per undistorted pixel is the chain rule: a captured ramp I = a . x_captured seen
// from an undistorted pixel has gradient J^T a, J = d Distort / d undistorted.
TEST(GradientsPerUndistortedPixel, IsTheChainRule) {
  const CameraLens lens{RenderK(), kDistortion};
  const cv::Mat gx(480, 640, CV_32F, cv::Scalar(3.0f)), gy(480, 640, CV_32F, cv::Scalar(-2.0f));
  cv::Mat ux, uy;
  GradientsPerUndistortedPixel(gx, gy, lens, &ux, &uy);
  for (const Eigen::Vector2d& at : {Eigen::Vector2d(600, 60), Eigen::Vector2d(320, 240),
                                    Eigen::Vector2d(20, 460)}) {
    Eigen::Matrix2d J;
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::Vector2d step = Eigen::Vector2d::Unit(axis);
      J.col(axis) = 0.5 * (lens.Distort(at + step) - lens.Distort(at - step));
    }
    const Eigen::Vector2d expected = J.transpose() * Eigen::Vector2d(3.0, -2.0);
    const int u = static_cast<int>(at.x()), v = static_cast<int>(at.y());
    EXPECT_NEAR(ux.at<float>(v, u), expected.x(), 1e-3) << at.transpose();
    EXPECT_NEAR(uy.at<float>(v, u), expected.y(), 1e-3) << at.transpose();
  }
  // The lens matters at the corner: a tenth of the gradient or more.
  EXPECT_GT(std::abs(ux.at<float>(60, 600) - 3.0f), 0.05f);
}

// In place (outputs = inputs, as sensing calls it): each pixel looks up the captured gradient,
// not one already overwritten. A ramp gx = u, gy = v under a near-identity lens stays the ramp.
TEST(GradientsPerUndistortedPixel, InPlaceReadsTheCapturedGradient) {
  const CameraLens lens{RenderK(), {-0.004, 0.012, 0.0006, -0.0002, 0.0}};
  cv::Mat gx(480, 640, CV_32F), gy(480, 640, CV_32F);
  for (int v = 0; v < gx.rows; ++v) {
    for (int u = 0; u < gx.cols; ++u) {
      gx.at<float>(v, u) = static_cast<float>(u);
      gy.at<float>(v, u) = static_cast<float>(v);
    }
  }
  GradientsPerUndistortedPixel(gx, gy, lens, &gx, &gy);
  for (const cv::Point& at : {cv::Point(10, 10), cv::Point(320, 240), cv::Point(600, 400)}) {
    EXPECT_NEAR(gx.at<float>(at), static_cast<float>(at.x), 1.5f) << at;
    EXPECT_NEAR(gy.at<float>(at), static_cast<float>(at.y), 1.5f) << at;
  }
}

// Windows through the lens are the captured image's windows at the captured pixels.
TEST(ZnccMatcher, ThroughALensReadsTheCapturedPixels) {
  const RenderedScene scene = RenderDistorted(5);
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
  const RenderedScene scene = RenderDistorted(7);
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

// MATCHES.csv's pixels: the point route's matches, mapped back, lie on the captured left image's
// edges (where its features were found) and undistort to the matched points again.
TEST(MatchesToCapturedPixels, PutsTheMatchesOnTheCapturedImagesFeatures) {
  const RenderedScene scene = RenderDistorted(7);
  const auto lens = LensOf(scene.cameras);
  ASSERT_TRUE(lens);
  MatcherOptions matcher = PickCellMatcherOptions();
  matcher.engine = hnn::EngineKind::kCpu;
  MatchReport report = MatchStereo(scene.left, scene.right, &scene.cameras,
                                   MatcherThroughLens(matcher, scene.left, scene.right, lens),
                                   nullptr);
  ASSERT_GT(report.matches.size(), 500u);
  const std::vector<StereoMatch> undistorted = report.matches;
  MatchesToCapturedPixels(*lens, &report);
  cv::Mat edges;
  cv::Canny(scene.left, edges, matcher.features.canny_low, matcher.features.canny_high);
  std::size_t on_edge = 0;
  for (std::size_t m = 0; m < report.matches.size(); ++m) {
    const Eigen::Vector2f& left = report.matches[m].left;
    const int u = static_cast<int>(std::lround(left.x())), v = static_cast<int>(std::lround(left.y()));
    ASSERT_TRUE(u >= 0 && v >= 0 && u < edges.cols && v < edges.rows) << left.transpose();
    on_edge += edges.at<uchar>(v, u) ? 1 : 0;
    const Eigen::Vector2f back = UndistortPoints({left}, lens->left.K, lens->left.D)[0];
    EXPECT_LT((back - undistorted[m].left).norm(), 0.05f) << m;
  }
  EXPECT_GT(static_cast<double>(on_edge), 0.95 * static_cast<double>(report.matches.size()));
}

// A distorted cell with its true K D R T: each route finds every part, no false one, every
// centroid within 0.5 mm of the truth (the bound LensDistortionPick holds the board route to).
TEST(PositionSensing, PointRouteSensesADistortedCellAsTheImageRouteDoes) {
  const RenderedScene scene = RenderDistorted(7);
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
        EXPECT_LE(pair.centroid_error_mm, 0.5) << LensRouteName(route) << " part " << pair.truth_index;
      }
    }
  }
}

}  // namespace
}  // namespace hnnstereo::vision
