// Acceptance on real data from ../shared/datasets (skipped when absent):
// OpenCV's 13 stereo chessboard pairs and the Oxford VGG "Merton College I" views.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "calib/chessboard.h"
#include "calib/dlt.h"
#include "calib/epipolar.h"
#include "calib/fundamental.h"

namespace hnnstereo::calib {
namespace {

namespace fs = std::filesystem;

const std::string kDatasets = std::string(HNNSTEREO_SHARED_DIR) + "/datasets/";

std::vector<std::string> ChessboardImages(const std::string& side) {
  std::vector<std::string> paths;
  for (int i : {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14}) {
    char name[32];
    std::snprintf(name, sizeof(name), "%s%02d.jpg", side.c_str(), i);
    paths.push_back(kDatasets + "opencv_stereo_calib_chessboard/" + name);
  }
  return paths;
}

// Acceptance: per-camera RMS within 0.05 px of OpenCV's own calibrateCamera on the same corners;
// mean distance of corners to the epipolar lines of their partners at most 0.3 px.
TEST(ChessboardAcceptance, OpenCvStereoSamplePairs) {
  if (!fs::exists(kDatasets + "opencv_stereo_calib_chessboard/left01.jpg")) {
    GTEST_SKIP() << "opencv_stereo_calib_chessboard not found under " << kDatasets;
  }
  ChessboardOptions options;
  options.rows = 6;
  options.cols = 9;
  options.square_mm = 25.0;
  options.left_images = ChessboardImages("left");
  options.right_images = ChessboardImages("right");
  const CalibrationResult result = CalibrateChessboard(options);
  ASSERT_EQ(result.report.num_views, 13);

  // OpenCV directly, as its stereo_calib sample does it, on the same images.
  double reference_rms[2];
  for (int camera = 0; camera < 2; ++camera) {
    const auto& paths = camera == 0 ? options.left_images : options.right_images;
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<std::vector<cv::Point3f>> objects;
    cv::Size size;
    for (const std::string& path : paths) {
      const cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
      size = grey.size();
      std::vector<cv::Point2f> view;
      ASSERT_TRUE(cv::findChessboardCorners(
          grey, cv::Size(9, 6), view, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE));
      cv::cornerSubPix(grey, view, cv::Size(11, 11), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01));
      corners.push_back(view);
      std::vector<cv::Point3f> board;
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 9; ++c)
          board.emplace_back(25.f * static_cast<float>(c), 25.f * static_cast<float>(r), 0.f);
      }
      objects.push_back(board);
    }
    cv::Mat K, D;
    std::vector<cv::Mat> rvecs, tvecs;
    reference_rms[camera] = cv::calibrateCamera(objects, corners, size, K, D, rvecs, tvecs);
  }
  const double ours[2] = {result.report.cameras[0].final.rms_px,
                          result.report.cameras[1].final.rms_px};
  std::printf(
      "[acceptance] chessboard: RMS left %.4f px (OpenCV %.4f), right %.4f px (OpenCV %.4f); "
      "stereo RMS %.4f px; mean epipolar distance %.4f px over %d corner pairs; |T| = %.2f mm\n",
      ours[0], reference_rms[0], ours[1], reference_rms[1],
      result.report.extra["stereo_rms_px"].get<double>(), result.report.mean_epipolar_distance_px,
      result.report.num_epipolar_pairs, result.calibration.intrinsics->T.norm());
  EXPECT_NEAR(ours[0], reference_rms[0], 0.05);
  EXPECT_NEAR(ours[1], reference_rms[1], 0.05);
  EXPECT_LE(result.report.mean_epipolar_distance_px, 0.3);
  // ORIGIN.md: |T| = 3.345 squares.
  EXPECT_NEAR(result.calibration.intrinsics->T.norm(), 3.345 * 25.0, 0.05 * 83.6);
  ASSERT_TRUE(result.calibration.intrinsics.has_value());
  EXPECT_EQ(result.calibration.intrinsics->D1.size(), 5u);
  EXPECT_TRUE(result.calibration.Check().empty());
}

std::vector<std::vector<double>> ReadRows(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::vector<double> row;
    std::string token;
    while (fields >> token) row.push_back(token == "*" ? -1.0 : std::stod(token));
    if (!row.empty()) rows.push_back(row);
  }
  return rows;
}

// Acceptance: DLT from the 3D points and their corners in views 1 and 2 gives mean reprojection
// error at most 0.2 px per view; F from those P: mean epipolar distance at most 0.5 px.
TEST(OxfordMertonAcceptance, DltAndFundamentalFromProjections) {
  const std::string dir = kDatasets + "multiview_oxford_merton1/";
  if (!fs::exists(dir + "3D/p3d")) GTEST_SKIP() << "multiview_oxford_merton1 not found";
  const auto points3D = ReadRows(dir + "3D/p3d");
  const auto matches = ReadRows(dir + "2D/nview-corners");
  const std::vector<std::vector<double>> corners[2] = {ReadRows(dir + "2D/001.corners"),
                                                       ReadRows(dir + "2D/002.corners")};
  ASSERT_EQ(points3D.size(), matches.size());
  DltReport dlt[2];
  for (int view = 0; view < 2; ++view) {
    std::vector<Eigen::Vector3d> world;
    std::vector<Eigen::Vector2d> image;
    for (size_t i = 0; i < matches.size(); ++i) {
      const int corner = static_cast<int>(matches[i][static_cast<size_t>(view)]);
      if (corner < 0) continue;
      world.emplace_back(points3D[i][0], points3D[i][1], points3D[i][2]);
      image.emplace_back(corners[view][static_cast<size_t>(corner)][0],
                         corners[view][static_cast<size_t>(corner)][1]);
    }
    dlt[view] = EstimateProjectionDlt(world, image);
    std::printf(
        "[acceptance] Merton view %d: %d points, reprojection MAE %.4f px (linear DLT %.4f), "
        "RMS %.4f px, max %.4f px\n",
        view + 1, dlt[view].num_points, dlt[view].final.mae_px, dlt[view].linear.mae_px,
        dlt[view].final.rms_px, dlt[view].final.max_px);
    EXPECT_LE(dlt[view].final.mae_px, 0.2) << "view " << view + 1;
  }
  const Eigen::Matrix3d F = FundamentalFromProjections(dlt[0].P, dlt[1].P);
  std::vector<Eigen::Vector2d> left, right;
  for (const auto& match : matches) {
    if (match[0] < 0 || match[1] < 0) continue;
    const auto& a = corners[0][static_cast<size_t>(match[0])];
    const auto& b = corners[1][static_cast<size_t>(match[1])];
    left.emplace_back(a[0], a[1]);
    right.emplace_back(b[0], b[1]);
  }
  const double mean_distance = MeanEpipolarDistancePx(F, left, right);
  // The 8-point RANSAC on the same matches, for comparison.
  const FundamentalReport ransac = EstimateFundamentalRansac(left, right);
  std::printf(
      "[acceptance] Merton F from DLT P1, P2: mean epipolar distance %.4f px over %zu matched "
      "corners; 8-point RANSAC: %d inliers, %.4f px\n",
      mean_distance, left.size(), ransac.num_inliers, ransac.mean_epipolar_distance_all_px);
  EXPECT_LE(mean_distance, 0.5);
  EXPECT_TRUE(ransac.success);
  EXPECT_LE(ransac.mean_epipolar_distance_px, 0.5);
}

}  // namespace
}  // namespace hnnstereo::calib
