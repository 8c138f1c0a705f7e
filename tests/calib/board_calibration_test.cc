// The board route (calib/board_calibration.h) on the renderer's distorted cell: intrinsics with
// distortion, stereo extrinsics and the table frame, each checked against the truth; target.yml
// round trip and refusals; the board's own corner order.
#include "calib/board_calibration.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/chessboard.h"
#include "calib/circle_calibration.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::calib {
namespace {

namespace fs = std::filesystem;

const std::vector<double> kDistortion = {-0.25, 0.08, 0.001, -0.001};

// Writes the board part of `target` and its images into `dir` (as `render` does).
void WriteBoardDirectory(const vision::RenderedTarget& target, const fs::path& dir) {
  fs::create_directories(dir);
  for (std::size_t i = 0; i < target.board.views.size(); ++i) {
    cv::imwrite((dir / target.board.views[i].left_image).string(), target.board_left_images[i]);
    cv::imwrite((dir / target.board.views[i].right_image).string(), target.board_right_images[i]);
  }
  SaveTargetDescription(target.description, (dir / "target.yml").string(),
                        [&](cv::FileStorage* storage) { WriteBoardTarget(target.board, storage); });
}

// Distorted pixel of world point X through a camera with K, D.
cv::Point2d Project(const ProjectionMatrix& P, const Eigen::Matrix3d& K,
                    const std::vector<double>& D, const Eigen::Vector3d& X) {
  const Eigen::Vector3d x = K.inverse() * (P * X.homogeneous());
  cv::Mat camera;
  cv::eigen2cv(K, camera);
  std::vector<cv::Point2d> pixels;
  cv::projectPoints(std::vector<cv::Point3d>{{x.x() / x.z(), x.y() / x.z(), 1.0}},
                    cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera, cv::Mat(D, true), pixels);
  return pixels[0];
}

// How well `calibrated` places the true cell: points of the work volume (a 240 x 200 mm grid on
// the table, 75 and 150 mm above it) that both true cameras see, triangulated through
// `calibrated`. The table frame's error: the largest error on the table (mm) and the rotation of
// the best rigid fit to the truth (deg); and the largest error in the whole volume (mm).
struct PlacementError {
  double table_worst_mm = 0.0, rotation_deg = 0.0, volume_worst_mm = 0.0;
};

PlacementError WorkVolumeError(const StereoCalibration& truth, const StereoCalibration& calibrated) {
  std::vector<Eigen::Vector3d> world, sensed;
  const Intrinsics& lens = *calibrated.intrinsics;
  for (double z : {0.0, 75.0, 150.0}) {
    for (double x = -20; x <= 220; x += 40) {
      for (double y = 285; y <= 485; y += 40) {
        const Eigen::Vector3d X(x, y, z);
        std::vector<cv::Point2d> pixel[2] = {
            {Project(truth.P1, truth.intrinsics->K1, truth.intrinsics->D1, X)},
            {Project(truth.P2, truth.intrinsics->K2, truth.intrinsics->D2, X)}};
        bool seen = true;
        for (const auto& p : pixel) {
          seen = seen && p[0].x >= 8 && p[0].y >= 8 && p[0].x <= truth.image_width - 9 &&
                 p[0].y <= truth.image_height - 9;
        }
        if (!seen) continue;
        const Eigen::Matrix3d* K[2] = {&lens.K1, &lens.K2};
        const std::vector<double>* D[2] = {&lens.D1, &lens.D2};
        Eigen::Vector2d ideal[2];
        for (int camera = 0; camera < 2; ++camera) {
          cv::Mat camera_matrix;
          cv::eigen2cv(*K[camera], camera_matrix);
          std::vector<cv::Point2d> undistorted;
          cv::undistortPoints(pixel[camera], undistorted, camera_matrix, cv::Mat(*D[camera], true),
                              cv::noArray(), camera_matrix,
                              cv::TermCriteria(cv::TermCriteria::COUNT, 20, 0.0));
          ideal[camera] = Eigen::Vector2d(undistorted[0].x, undistorted[0].y);
        }
        Eigen::Matrix4d A;
        A.row(0) = ideal[0].x() * calibrated.P1.row(2) - calibrated.P1.row(0);
        A.row(1) = ideal[0].y() * calibrated.P1.row(2) - calibrated.P1.row(1);
        A.row(2) = ideal[1].x() * calibrated.P2.row(2) - calibrated.P2.row(0);
        A.row(3) = ideal[1].y() * calibrated.P2.row(2) - calibrated.P2.row(1);
        Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
        world.push_back(X);
        sensed.push_back(svd.matrixV().col(3).hnormalized());
      }
    }
  }
  PlacementError error;
  Eigen::Matrix3Xd from(3, world.size()), to(3, world.size());
  for (std::size_t i = 0; i < world.size(); ++i) {
    const double e = (sensed[i] - world[i]).norm();
    error.volume_worst_mm = std::max(error.volume_worst_mm, e);
    if (world[i].z() == 0.0) error.table_worst_mm = std::max(error.table_worst_mm, e);
    from.col(static_cast<Eigen::Index>(i)) = sensed[i];
    to.col(static_cast<Eigen::Index>(i)) = world[i];
  }
  const Eigen::Matrix4d fit = Eigen::umeyama(from, to, false);
  error.rotation_deg =
      Eigen::AngleAxisd(Eigen::Matrix3d(fit.topLeftCorner<3, 3>())).angle() * 180.0 / M_PI;
  return error;
}

// Renders the cell's board views at `width` x `height` with `distortion`, calibrates from them
// and checks the figures of the acceptance: RMS <= 0.3 px per camera, the table frame within
// 0.5 mm and 0.1 deg.
void ExpectBoardCalibrationFits(const fs::path& dir, int width, int height,
                                const std::vector<double>& distortion) {
  vision::SceneRenderOptions options;
  options.seed = 11;
  options.cameras.SetResolution(width, height);
  options.cameras.distortion = distortion;
  const StereoCalibration truth = vision::PickCellCameras(options.cameras);
  WriteBoardDirectory(vision::RenderTargetPlacements(truth, options), dir);
  const std::optional<BoardTarget> board = LoadBoardTarget(dir.string());
  ASSERT_TRUE(board.has_value());
  const CalibrationResult result = CalibrateBoardTarget(*board);
  const std::string where = std::to_string(width) + " px" + (distortion.empty() ? ", pinhole" : "");
  for (const CameraCalibrationReport& camera : result.report.cameras) {
    EXPECT_LE(camera.final.rms_px, 0.3) << where << " " << camera.camera;
  }
  EXPECT_LE(result.report.mean_epipolar_distance_px, 0.2) << where;
  EXPECT_EQ(result.calibration.world_frame, "table");
  ASSERT_TRUE(result.calibration.world_from_left_camera.has_value());
  if (distortion.empty()) return;  // the truth of a pinhole cell carries no K D
  const PlacementError error = WorkVolumeError(truth, result.calibration);
  EXPECT_LE(error.table_worst_mm, 0.5) << where;
  EXPECT_LE(error.rotation_deg, 0.1) << where;
  EXPECT_LE(error.volume_worst_mm, 1.0) << where;
  std::cout << where << ": RMS " << result.report.cameras[0].final.rms_px << " / "
            << result.report.cameras[1].final.rms_px << " px, epipolar "
            << result.report.mean_epipolar_distance_px << " px; table worst "
            << error.table_worst_mm << " mm, rotation " << error.rotation_deg
            << " deg, work volume worst " << error.volume_worst_mm << " mm; table fit "
            << result.report.extra["table_fit_rms_mm"] << " mm RMS\n";
}

class BoardCalibration : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("hnnstereo_board_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(BoardCalibration, DistortedCellGivesIntrinsicsExtrinsicsAndTheTableFrame) {
  ExpectBoardCalibrationFits(dir_, 640, 480, kDistortion);
}

TEST_F(BoardCalibration, PinholeCellCalibratesAlike) {
  ExpectBoardCalibrationFits(dir_, 640, 480, {});
}

// Extended (about 30 s: the circle plates at 1280 x 1024 are rendered too).
TEST_F(BoardCalibration, DistortedCellAt1280x1024) {
  ExpectBoardCalibrationFits(dir_, 1280, 1024, kDistortion);
}

TEST_F(BoardCalibration, CalibrationFileKeepsTheTableFrame) {
  vision::SceneRenderOptions options;
  options.cameras.distortion = kDistortion;
  const StereoCalibration truth = vision::PickCellCameras(options.cameras);
  WriteBoardDirectory(vision::RenderTargetPlacements(truth, options), dir_);
  const CalibrationResult result = CalibrateBoardTarget(*LoadBoardTarget(dir_.string()));
  const std::string path = (dir_ / "cal.yml").string();
  SaveCalibration(result.calibration, path);
  const StereoCalibration loaded = LoadCalibration(path);
  EXPECT_EQ(loaded.world_frame, "table");
  ASSERT_TRUE(loaded.world_from_left_camera && loaded.intrinsics);
  EXPECT_LT((*loaded.world_from_left_camera - *result.calibration.world_from_left_camera).norm(),
            1e-9);
  EXPECT_EQ(loaded.intrinsics->D1.size(), 5u);
  // OpenCV reads it as it is documented.
  cv::FileStorage storage(path, cv::FileStorage::READ);
  cv::Mat pose;
  storage["world_from_left_camera"] >> pose;
  EXPECT_EQ(pose.rows, 4);
  EXPECT_EQ(static_cast<std::string>(storage["world_frame"]), "table");
  // The left camera sits where world_from_left_camera says: C1.
  EXPECT_LT((loaded.world_from_left_camera->block<3, 1>(0, 3) - loaded.C1).norm(), 1e-6);
}

TEST_F(BoardCalibration, TargetWithoutBoardIsTheCircleRoute) {
  vision::SceneRenderOptions options;
  const vision::RenderedTarget target =
      vision::RenderTargetPlacements(vision::PickCellCameras(options.cameras), options);
  fs::create_directories(dir_);
  SaveTargetDescription(target.description, (dir_ / "target.yml").string());
  EXPECT_FALSE(LoadBoardTarget(dir_.string()).has_value());
}

TEST_F(BoardCalibration, RefusesAmbiguousBoardsAndMissingTableViews) {
  BoardTarget target;
  target.views.resize(4);
  target.views[0].on_table = true;
  target.board.rows = 6;
  target.board.cols = 8;  // 6 + 8 even: a half turn looks the same
  EXPECT_NE(target.Check().find("odd"), std::string::npos);
  target.board.cols = 9;
  EXPECT_EQ(target.Check(), "");
  target.views[0].on_table = false;
  EXPECT_NE(target.Check().find("on_table"), std::string::npos);
  fs::create_directories(dir_);
  std::ofstream(dir_ / "target.yml") << "%YAML:1.0\n---\nboard: charuco\n";
  EXPECT_THROW(LoadBoardTarget(dir_.string()), std::runtime_error);
  std::ofstream(dir_ / "target.yml") << "%YAML:1.0\n---\nboard: chessboard\nboard_rows: 6\n"
                                        "board_cols: 9\nboard_square_mm: 20\nboard_views: []\n";
  EXPECT_THROW(LoadBoardTarget(dir_.string()), std::runtime_error);
}

// The corners come back in the board's own order however the image is turned or mirrored in
// the detector's eyes: corner 0 stays the same physical corner.
TEST(OrientChessboardCorners, SameCornerFirstWhateverTheDetectorsOrder) {
  vision::SceneRenderOptions options;
  const StereoCalibration cameras = vision::PickCellCameras(options.cameras);
  const vision::RenderedTarget target = vision::RenderTargetPlacements(cameras, options);
  const ChessboardGeometry& board = target.board.board;
  const cv::Mat& image = target.board_left_images[0];
  auto oriented = [&](const cv::Mat& grey) {
    auto corners = DetectChessboardCorners(grey, board.rows, board.cols, 5);
    EXPECT_TRUE(corners.has_value());
    OrientChessboardCorners(grey, board.rows, board.cols, &*corners);
    return *corners;
  };
  const std::vector<Eigen::Vector2d> upright = oriented(image);
  const Eigen::Vector3d corner0 =
      (target.board.views[0].world_from_board * Eigen::Vector4d(0, 0, 0, 1)).hnormalized();
  const Eigen::Vector3d x = cameras.P1 * corner0.homogeneous();
  EXPECT_LT((upright[0] - x.hnormalized()).norm(), 0.5);
  cv::Mat turned;
  cv::rotate(image, turned, cv::ROTATE_180);
  const std::vector<Eigen::Vector2d> after_turn = oriented(turned);
  const Eigen::Vector2d turned_back(image.cols - 1 - after_turn[0].x(),
                                    image.rows - 1 - after_turn[0].y());
  EXPECT_LT((turned_back - upright[0]).norm(), 0.5);
}

}  // namespace
}  // namespace hnnstereo::calib
