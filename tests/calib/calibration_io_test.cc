// File forms and bad input: CAL.yml round trip, Middlebury calib.txt, points files, TARGET_DIR.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "calib/calibration.h"
#include "calib/circle_calibration.h"
#include "calib/dlt.h"
#include "calib/epipolar.h"
#include "calib/known_points.h"
#include "synthetic_rig.h"

namespace hnnstereo::calib {
namespace {

namespace fs = std::filesystem;

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

// The error message of `f`, or "" when it does not throw std::runtime_error.
template <typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(MiddleburyCalib, ParsesAdirondackStyleText) {
  const std::string text =
      "cam0=[4161.221 0 1445.577; 0 4161.221 984.686; 0 0 1]\n"
      "cam1=[4161.221 0 1654.636; 0 4161.221 984.686; 0 0 1]\n"
      "doffs=209.059\nbaseline=176.252\nwidth=2880\nheight=1988\nndisp=280\n";
  const StereoCalibration cal = ParseMiddleburyCalib(text);
  EXPECT_TRUE(cal.rectified);
  EXPECT_EQ(cal.image_width, 2880);
  EXPECT_EQ(cal.image_height, 1988);
  EXPECT_NEAR(cal.C1.norm(), 0.0, 1e-9);
  EXPECT_NEAR((cal.C2 - Eigen::Vector3d(176.252, 0, 0)).norm(), 0.0, 1e-6);
  // Rectified: the epipolar line of (x, y) is the row y.
  const Eigen::Vector3d line = EpipolarLineInRight(cal.F, Eigen::Vector2d(1000, 500));
  EXPECT_NEAR(std::abs(line.y()), 1.0, 1e-9);
  EXPECT_NEAR(-line.z() / line.y(), 500.0, 1e-6);
  // Depth from disparity (datasets README): Z = b f / (d + doffs) for a point at 1000 mm.
  const Eigen::Vector3d X(100, 50, 1000);
  const double d = Project(cal.P1, X).x() - Project(cal.P2, X).x();
  EXPECT_NEAR(176.252 * 4161.221 / (d + 209.059), 1000.0, 1e-6);
  EXPECT_THROW(ParseMiddleburyCalib("cam0=[1 0 0; 0 1 0; 0 0 1]\n"), std::runtime_error);
}

TEST(MiddleburyCalib, ReadsSharedDatasetFile) {
  const std::string path =
      std::string(HNNSTEREO_SHARED_DIR) + "/datasets/middlebury2014_Q_Adirondack/calib.txt";
  if (!fs::exists(path)) GTEST_SKIP() << "no " << path;
  const StereoCalibration cal = LoadCalibration(path);
  EXPECT_TRUE(cal.rectified);
  EXPECT_GT(cal.image_width, 0);
  EXPECT_GT((cal.C2 - cal.C1).norm(), 100.0);
}

TEST(CalibrationFile, RoundTripKeepsEverything) {
  const testing::StereoRig rig = testing::ThesisRig();
  StereoCalibration cal;
  cal.P1 = rig.P1 / rig.P1(2, 3);
  cal.P2 = rig.P2 / rig.P2(2, 3);
  cal.image_width = 640;
  cal.image_height = 480;
  cal.DeriveFromProjections();
  cal.error_figures = {{"left_mae_px", 0.12}, {"right_rms_px", 0.2}};
  const std::string dir = testing::TemporaryDirectory("roundtrip");
  const std::string path = dir + "/cal.yml";
  SaveCalibration(cal, path);
  const StereoCalibration loaded = LoadCalibration(path);
  EXPECT_LT((loaded.P1 - cal.P1).norm(), 1e-9 * cal.P1.norm());
  EXPECT_LT((loaded.F - cal.F).norm(), 1e-12);
  EXPECT_LT((loaded.C2 - rig.C2).norm(), 1e-6);
  EXPECT_EQ(loaded.image_width, 640);
  // No temporary file is left beside it.
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) files += entry.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, 1);
}

TEST(KnownPoints, ParsesCommentsAndRejectsBadLines) {
  const KnownPoints points =
      ParseKnownPoints("# X Y Z u v\n\n1 2 3 4 5  # first\n6 7 8 9 10\n", "test");
  ASSERT_EQ(points.points3D_in_world.size(), 2u);
  EXPECT_EQ(points.image_points[1], Eigen::Vector2d(9, 10));
  EXPECT_NE(ErrorOf([] { ParseKnownPoints("1 2 3 4\n", "f"); }).find("line 1"), std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseKnownPoints("1 2 3 4 5\n1 nan 3 4 5\n", "f"); }).find("line 2"),
            std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseKnownPoints("1 2 3 4 x\n", "f"); }).find("not a number"),
            std::string::npos);
  EXPECT_NE(ErrorOf([] { ReadKnownPoints("/nonexistent/points.txt"); }).find("does not exist"),
            std::string::npos);
}

TEST(KnownPoints, PlanarPointsAreRefusedAndNothingIsWritten) {
  const testing::StereoRig rig = testing::ThesisRig();
  const std::string dir = testing::TemporaryDirectory("planar");
  std::string left, right;
  for (int i = 0; i < 12; ++i) {
    const Eigen::Vector3d X(60.0 + 10 * (i % 4), 360.0 + 15 * (i / 4), 0.0);
    const Eigen::Vector2d x1 = Project(rig.P1, X), x2 = Project(rig.P2, X);
    left += std::to_string(X.x()) + " " + std::to_string(X.y()) + " 0 " + std::to_string(x1.x()) +
            " " + std::to_string(x1.y()) + "\n";
    right += std::to_string(X.x()) + " " + std::to_string(X.y()) + " 0 " + std::to_string(x2.x()) +
             " " + std::to_string(x2.y()) + "\n";
  }
  WriteText(dir + "/left.txt", left);
  WriteText(dir + "/right.txt", right);
  const std::string error =
      ErrorOf([&] { CalibrateFromKnownPoints(dir + "/left.txt", dir + "/right.txt"); });
  EXPECT_NE(error.find("coplanar"), std::string::npos) << error;
  EXPECT_NE(error.find("left camera"), std::string::npos) << error;
}

// A file that ends inside an XML header made OpenCV's XML parser dereference a null pointer
// (fuzz_frame_yml; OpenCV reads "<?xml" as XML whatever format flag it is given): CAL.yml and
// target.yml are read as YAML only, and such a file is refused with one line.
TEST(CalibrationFile, XmlIsRefusedNotACrash) {
  const std::string dir = testing::TemporaryDirectory("xml_files");
  for (const std::string& text : {std::string("<?xml version="), std::string("\xEF\xBB\xBF<?xml"),
                                  std::string("<?xml version=\"1.0\"?>\n<opencv_storage>\n")}) {
    WriteText(dir + "/cal.yml", text);
    EXPECT_NE(ErrorOf([&] { LoadCalibration(dir + "/cal.yml"); }).find("is XML"), std::string::npos)
        << text;
    WriteText(dir + "/target.yml", text);
    EXPECT_NE(ErrorOf([&] { LoadTargetDirectory(dir); }).find("is XML"), std::string::npos) << text;
  }
}

// OpenCV's YAML parser looped forever when the first document's top level ended before the end
// of the text and a '-' stood three characters on (fuzz_frame_yml): an indented top level, or
// "...-" after it. CAL.yml and target.yml are one document whose keys start in column 1.
TEST(CalibrationFile, YamlThatHungOpenCvIsRefused) {
  const std::string dir = testing::TemporaryDirectory("hanging_yaml");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"%YAML:1.0\n -o\nK---\no\n", "line 2: the top level must be a map"},
      {"%YAML:1.0\n a: 1\nbcd-x\nz\n", "line 2: the top level must be a map"},
      {"%YAML:1.0\na: 1\n...-\nz\n", "line 3: '...' ends the YAML document"},
      {std::string("a: 1\0\n", 6), "NUL byte"}};
  for (const auto& [text, reason] : cases) {
    WriteText(dir + "/cal.yml", text);
    EXPECT_NE(ErrorOf([&] { LoadCalibration(dir + "/cal.yml"); }).find(reason), std::string::npos)
        << text;
    WriteText(dir + "/target.yml", text);
    EXPECT_NE(ErrorOf([&] { LoadTargetDirectory(dir); }).find(reason), std::string::npos) << text;
  }
}

TEST(TargetDirectory, MissingFolderAndFileAreClearErrors) {
  EXPECT_NE(ErrorOf([] { LoadTargetDirectory("/nonexistent/target_dir"); }).find("does not exist"),
            std::string::npos);
  const std::string dir = testing::TemporaryDirectory("no_target_yml");
  EXPECT_NE(ErrorOf([&] { LoadTargetDirectory(dir); }).find("no target.yml"), std::string::npos);
}

TEST(TargetDirectory, BadFieldsAreNamed) {
  const std::string dir = testing::TemporaryDirectory("bad_target");
  cv::imwrite(dir + "/l.png", cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)));
  cv::imwrite(dir + "/r.png", cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)));
  const std::string header = "%YAML:1.0\n---\nrows: 3\ncols: 3\n";
  WriteText(dir + "/target.yml", header +
                                     "pitch_mm: .nan\nheights:\n"
                                     "  - { left: l.png, right: r.png, origin_mm: [0, 0, 0] }\n");
  std::string error = ErrorOf([&] { LoadTargetDirectory(dir); });
  EXPECT_NE(error.find("pitch_mm"), std::string::npos) << error;
  WriteText(dir + "/target.yml", header +
                                     "pitch_mm: 25\nheights:\n"
                                     "  - { left: l.png, right: r.png, origin_mm: [0, .nan, 0] }\n"
                                     "  - { left: l.png, right: r.png, origin_mm: [0, 0, 50] }\n");
  error = ErrorOf([&] { LoadTargetDirectory(dir); });
  EXPECT_NE(error.find("non-finite"), std::string::npos) << error;
  WriteText(dir + "/target.yml", header +
                                     "pitch_mm: 25\nheights:\n"
                                     "  - { left: l.png, right: r.png, origin_mm: [0, 0, 0] }\n");
  error = ErrorOf([&] { LoadTargetDirectory(dir); });
  EXPECT_NE(error.find("two or more heights"), std::string::npos) << error;
  WriteText(dir + "/target.yml",
            header +
                "pitch_mm: 25\nheights:\n"
                "  - { left: l.png, right: missing.png, origin_mm: [0, 0, 0] }\n");
  error = ErrorOf([&] { LoadTargetDirectory(dir); });
  EXPECT_NE(error.find("missing.png"), std::string::npos) << error;
  WriteText(dir + "/target.yml", "rows: [unclosed\n");
  EXPECT_FALSE(ErrorOf([&] { LoadTargetDirectory(dir); }).empty());
}

TEST(TargetDirectory, SaveAndLoadAgree) {
  const std::string dir = testing::TemporaryDirectory("save_target");
  cv::imwrite(dir + "/l.png", cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)));
  TargetDescription target;
  target.grid.pitch_mm = 20.0;
  target.grid.circle_radius_mm = 5.0;
  for (int h = 0; h < 2; ++h) {
    target.placements.push_back(
        {"l.png", "l.png", WorldFromTargetFlat(Eigen::Vector3d(10, 20, 30.0 * h), 15.0 * h)});
  }
  SaveTargetDescription(target, dir + "/target.yml");
  const TargetDescription loaded = LoadTargetDirectory(dir);
  EXPECT_EQ(loaded.grid.pitch_mm, 20.0);
  ASSERT_EQ(loaded.placements.size(), 2u);
  EXPECT_LT(
      (loaded.placements[1].world_from_target - target.placements[1].world_from_target).norm(),
      1e-9);
  // The origin_mm + yaw_deg form gives the same pose.
  WriteText(dir + "/target.yml",
            "%YAML:1.0\n---\nrows: 3\ncols: 3\npitch_mm: 20\nheights:\n"
            "  - { left: l.png, right: l.png, origin_mm: [10, 20, 0], yaw_deg: 0 }\n"
            "  - { left: l.png, right: l.png, origin_mm: [10, 20, 30], yaw_deg: 15 }\n");
  const TargetDescription short_form = LoadTargetDirectory(dir);
  EXPECT_LT(
      (short_form.placements[1].world_from_target - target.placements[1].world_from_target).norm(),
      1e-9);
}

TEST(CircleCalibration, CalibratesFromGeneratedTargetDirectory) {
  const testing::StereoRig rig = testing::ThesisRig();
  const CircleGridGeometry grid;
  CircleTargetRenderOptions render;
  render.num_distractors = 4;
  const auto placements = testing::RenderRandomPlacements(rig, grid, 4, 99, render, true, 40, 60);
  ASSERT_EQ(placements.size(), 4u);
  const std::string dir = testing::TemporaryDirectory("circle_dir");
  testing::WriteTargetDirectory(placements, grid, dir);
  const CalibrationResult result = CalibrateCircleTarget(dir);
  ASSERT_EQ(result.report.cameras.size(), 2u);
  for (const auto& camera : result.report.cameras) {
    EXPECT_LT(camera.final.mae_px, 0.1) << camera.camera;
    EXPECT_EQ(camera.observations.size(), 36u);
    EXPECT_FALSE(camera.overlay.empty());
  }
  EXPECT_LT((result.calibration.C1 - rig.C1).norm(), 10.0);
  EXPECT_LT((result.calibration.C2 - rig.C2).norm(), 10.0);
  EXPECT_LT(result.report.mean_epipolar_distance_px, 0.2);
  EXPECT_EQ(result.calibration.image_width, 640);
  EXPECT_TRUE(result.calibration.Check().empty());
  // Outputs: CAL.yml, report, overlays - and CAL.yml loads back.
  const std::string out = dir + "/out";
  fs::create_directories(out);
  const auto written = WriteCalibrationOutputs(result, out + "/cal.yml", out + "/calib.json");
  EXPECT_EQ(written.size(), 4u);
  const StereoCalibration loaded = LoadCalibration(out + "/cal.yml");
  EXPECT_LT((loaded.C1 - result.calibration.C1).norm(), 1e-6);
  EXPECT_TRUE(fs::exists(out + "/cal_left.png"));
  EXPECT_NE(FormatReportTable(result.report).find("MAE"), std::string::npos);
}

TEST(CircleCalibration, WrongGridSizeNamesTheImage) {
  const testing::StereoRig rig = testing::ThesisRig();
  const CircleGridGeometry grid;
  const auto placements =
      testing::RenderRandomPlacements(rig, grid, 2, 5, CircleTargetRenderOptions{}, true, 40, 60);
  const std::string dir = testing::TemporaryDirectory("wrong_grid");
  CircleGridGeometry wrong = grid;
  wrong.cols = 4;
  testing::WriteTargetDirectory(placements, wrong, dir);
  const std::string error = ErrorOf([&] { CalibrateCircleTarget(dir); });
  EXPECT_NE(error.find("left_0.png"), std::string::npos) << error;
  EXPECT_NE(error.find("3 x 4 grid"), std::string::npos) << error;
}

}  // namespace
}  // namespace hnnstereo::calib
