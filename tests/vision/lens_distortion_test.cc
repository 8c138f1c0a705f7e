// Undistorted pixels map back to the distorted pixels of the image as given.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/sensing/position_sensing.h"
#include "vision/stereo/lens_distortion.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::vision {
namespace {

TEST(DistortPoints, InvertsOpenCvUndistortPoints) {
  Eigen::Matrix3d K;
  K << 530, 0, 320, 0, 530, 240, 0, 0, 1;
  const std::vector<double> D = {-0.28, 0.09, 0.001, -0.0005, 0.0};
  std::vector<cv::Point2f> distorted = {{20, 30}, {320, 240}, {600, 450}, {100, 400}};
  cv::Mat camera;
  cv::eigen2cv(K, camera);
  std::vector<cv::Point2f> undistorted;
  cv::undistortPoints(distorted, undistorted, camera, cv::Mat(D, true), cv::noArray(), camera);
  std::vector<Eigen::Vector2f> points;
  for (const auto& p : undistorted) points.emplace_back(p.x, p.y);
  const auto back = DistortPoints(points, K, D);
  ASSERT_EQ(back.size(), distorted.size());
  for (std::size_t t = 0; t < back.size(); ++t) {
    EXPECT_NEAR(back[t].x(), distorted[t].x, 0.05) << t;
    EXPECT_NEAR(back[t].y(), distorted[t].y, 0.05) << t;
  }
}

TEST(UndistortPoints, InvertsDistortPoints) {
  Eigen::Matrix3d K;
  K << 530, 0, 320, 0, 530, 240, 0, 0, 1;
  const std::vector<double> D = {-0.28, 0.09, 0.001, -0.0005, 0.0};
  const std::vector<Eigen::Vector2f> undistorted = {{20, 30}, {320, 240}, {600, 450}, {100, 400}};
  const auto there = DistortPoints(undistorted, K, D);
  const auto back = UndistortPoints(there, K, D);
  ASSERT_EQ(back.size(), undistorted.size());
  for (std::size_t t = 0; t < back.size(); ++t) {
    EXPECT_NEAR((back[t] - undistorted[t]).norm(), 0.0, 0.05) << t;
  }
  EXPECT_TRUE(UndistortPoints({}, K, D).empty());
}

// An overlay drawn in undistorted pixels lands, resampled, where the input image shows the point.
TEST(RedistortImage, PutsAnUndistortedMarkAtItsInputPixel) {
  Eigen::Matrix3d K;
  K << 1100, 0, 319.5, 0, 1100, 239.5, 0, 0, 1;
  const std::vector<double> D = {-0.25, 0.08, 0.001, -0.001};
  const Eigen::Vector2f input(600.0f, 40.0f);  // near a corner: about 9 px of distortion
  const Eigen::Vector2f ideal = UndistortPoints({input}, K, D)[0];
  ASSERT_GT((ideal - input).norm(), 5.0f);
  cv::Mat overlay(480, 640, CV_8U, cv::Scalar(0));
  cv::circle(overlay, cv::Point(static_cast<int>(std::lround(ideal.x())),
                                static_cast<int>(std::lround(ideal.y()))), 3, cv::Scalar(255), -1);
  const cv::Mat original = RedistortImage(overlay, K, D);
  const cv::Moments moments = cv::moments(original);
  const Eigen::Vector2d centre(moments.m10 / moments.m00, moments.m01 / moments.m00);
  EXPECT_LT((centre - input.cast<double>()).norm(), 1.0);
}

// The library refuses a calibration for another image size, as every command does.
TEST(SensePositions, RefusesACalibrationForAnotherImageSize) {
  SceneRenderOptions options;
  options.seed = 3;
  options.num_objects = 1;
  const RenderedScene scene = RenderScene(options);
  calib::StereoCalibration other = scene.cameras;
  other.image_width = 1280;
  other.image_height = 1024;
  try {
    SensePositions(scene.left, scene.right, other, PositionSensingOptions{}, nullptr);
    FAIL() << "accepted a 1280x1024 calibration for 640x480 images";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("is for 1280x1024 images"), std::string::npos)
        << error.what();
  }
}

}  // namespace
}  // namespace hnnstereo::vision
