// F of an uncalibrated pair from correlation matches, and its canonical cameras.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/epipolar.h"
#include "vision/stereo/uncalibrated.h"

namespace hnnstereo::vision {
namespace {

TEST(CanonicalCameras, ReproduceTheFundamentalMatrix) {
  Eigen::Matrix3d F;
  F << 0, -0.001, 0.2, 0.0012, 0.0001, -0.4, -0.25, 0.38, 0.01;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s = svd.singularValues();
  s(2) = 0;  // rank 2
  F = svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
  const calib::StereoCalibration cameras = CanonicalCamerasFromFundamental(F);
  const Eigen::Matrix3d F_back = calib::FundamentalFromProjections(cameras.P1, cameras.P2);
  const double sign = F_back.cwiseProduct(F).sum() < 0 ? -1.0 : 1.0;
  EXPECT_LT((sign * F_back - F / F.norm()).norm(), 1e-9);
  EXPECT_EQ(cameras.Check(), "");
}

TEST(EstimateEpipolarGeometry, SyntheticTranslationGivesHorizontalEpipolarLines) {
  cv::Mat left(240, 320, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(left, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(left, left, cv::Size(0, 0), 1.5);
  // A bumpy surface seen by a camera translated along x: horizontal disparities that vary
  // non-linearly (a constant or planar shift would be a homography, degenerate for F).
  cv::Mat map_x(left.size(), CV_32FC1), map_y(left.size(), CV_32FC1);
  for (int y = 0; y < left.rows; ++y) {
    for (int x = 0; x < left.cols; ++x) {
      const double disparity = 12.0 + 6.0 * std::sin(x / 23.0) * std::cos(y / 17.0);
      map_x.at<float>(y, x) = static_cast<float>(x + disparity);
      map_y.at<float>(y, x) = static_cast<float>(y);
    }
  }
  cv::Mat right;
  cv::remap(left, right, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const UncalibratedReport report = EstimateEpipolarGeometry(left, right);
  EXPECT_GE(report.fundamental.num_inliers, 50);
  EXPECT_LT(report.fundamental.mean_epipolar_distance_px, 0.5);
  // A pure horizontal shift: the epipolar line of any left point is its own row.
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(50, 60), Eigen::Vector2d(250, 200)}) {
    EXPECT_LT(calib::EpipolarDistancePx(report.calibration.F, p, p + Eigen::Vector2d(-30, 0)), 1.0);
    EXPECT_GT(calib::EpipolarDistancePx(report.calibration.F, p, p + Eigen::Vector2d(0, 20)), 10.0);
  }
}

TEST(EstimateEpipolarGeometry, RealBooksPair) {
  const std::string dir = std::string(HNNSTEREO_SHARED_DIR) + "/datasets/opencv_books_uncalibrated";
  const cv::Mat left = cv::imread(dir + "/left.jpg", cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(dir + "/right.jpg", cv::IMREAD_GRAYSCALE);
  if (left.empty() || right.empty()) GTEST_SKIP() << "shared data not found in " << dir;
  const UncalibratedReport report = EstimateEpipolarGeometry(left, right);
  EXPECT_GE(report.fundamental.num_inliers, 30);
  EXPECT_LT(report.fundamental.mean_epipolar_distance_px, 1.0);
}

TEST(EstimateEpipolarGeometry, RefusesImagesWithoutStructure) {
  const cv::Mat flat(120, 160, CV_8UC1, cv::Scalar(90));
  EXPECT_THROW(EstimateEpipolarGeometry(flat, flat), std::runtime_error);
}

}  // namespace
}  // namespace hnnstereo::vision
