// Undistorted pixels map back to the distorted pixels of the image as given.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "vision/stereo/lens_distortion.h"

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

}  // namespace
}  // namespace hnnstereo::vision
