#include "calib/chessboard.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "calib/dlt.h"
#include "calib/fundamental.h"
#include "common/input_limits.h"

namespace hnnstereo::calib {

std::string ChessboardOptions::Check() const {
  std::ostringstream out;
  if (rows < 2 || cols < 2) {
    out << "chessboard --rows and --cols (inner corners) must be >= 2 (are " << rows << ", " << cols
        << ")";
  } else if (!(square_mm > 0.0) || !std::isfinite(square_mm)) {
    out << "chessboard --square must be > 0 mm (is " << square_mm << ")";
  } else if (left_images.size() != right_images.size()) {
    out << "chessboard: " << left_images.size() << " left images but " << right_images.size()
        << " right images";
  } else if (static_cast<int>(left_images.size()) < min_pairs) {
    out << "chessboard: at least " << min_pairs << " image pairs are needed (got "
        << left_images.size() << ")";
  } else if (subpixel_window < 3) {
    out << "chessboard subpixel_window must be >= 3 (is " << subpixel_window << ")";
  }
  return out.str();
}

std::optional<std::vector<Eigen::Vector2d>> DetectChessboardCorners(const cv::Mat& image, int rows,
                                                                    int cols, int subpixel_window) {
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else {
    grey = image;
  }
  std::vector<cv::Point2f> corners;
  const bool found =
      cv::findChessboardCorners(grey, cv::Size(cols, rows), corners,
                                cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
  if (!found) return std::nullopt;
  cv::cornerSubPix(grey, corners, cv::Size(subpixel_window, subpixel_window), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01));
  std::vector<Eigen::Vector2d> points;
  for (const cv::Point2f& p : corners) points.emplace_back(p.x, p.y);
  return points;
}

void OrientChessboardCorners(const cv::Mat& grey, int rows, int cols,
                             std::vector<Eigen::Vector2d>* corners) {
  std::vector<Eigen::Vector2d>& c = *corners;
  if (rows < 2 || cols < 3 || static_cast<int>(c.size()) != rows * cols) return;
  const Eigen::Vector2d d_col = c[1] - c[0], d_row = c[cols] - c[0];
  if (d_col.x() * d_row.y() - d_col.y() * d_row.x() > 0.0) {  // mirrored: reverse the rows
    for (int r = 0; r < rows / 2; ++r) {
      std::swap_ranges(c.begin() + r * cols, c.begin() + (r + 1) * cols,
                       c.begin() + (rows - 1 - r) * cols);
    }
  }
  // Mean grey at the centre of the square spanned by corners (0, col) and (1, col + 1).
  auto square_grey = [&](int col) {
    const Eigen::Vector2d centre = 0.25 * (c[col] + c[col + 1] + c[cols + col] + c[cols + col + 1]);
    cv::Mat patch;
    cv::getRectSubPix(grey, cv::Size(3, 3), cv::Point2f(static_cast<float>(centre.x()),
                                                        static_cast<float>(centre.y())), patch);
    return cv::mean(patch)[0];
  };
  if (square_grey(0) > square_grey(1)) std::reverse(c.begin(), c.end());  // turned 180 deg
}

namespace {

const char* const kCameraNames[2] = {"left", "right"};

// The board's inner corners in its own frame (mm, z = 0), row-major.
std::vector<cv::Point3f> BoardPoints(const ChessboardOptions& options) {
  std::vector<cv::Point3f> board;
  for (int r = 0; r < options.rows; ++r) {
    for (int c = 0; c < options.cols; ++c) {
      board.emplace_back(static_cast<float>(c * options.square_mm),
                         static_cast<float>(r * options.square_mm), 0.f);
    }
  }
  return board;
}

// The pairs in which both images show the board: its points and each camera's corners per
// view, the images where it was not found, each camera's image size and first used image.
struct ChessboardViews {
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> corners[2];
  /// Views whose board only this camera shows (ChessboardOptions::single_camera_views).
  std::vector<std::vector<cv::Point2f>> single_camera_corners[2];
  std::vector<std::string> skipped;
  cv::Size image_size[2];
  cv::Mat first_image[2];
};

// One camera's image of a pair, checked to exist and to be the size of its first image.
cv::Mat ReadPairImage(const std::string& path, int camera, cv::Size* image_size) {
  if (!std::filesystem::is_regular_file(path)) {
    throw std::runtime_error("chessboard image '" + path + "' does not exist");
  }
  cv::Mat image = ReadImageFileWithin(path, cv::IMREAD_GRAYSCALE);  // size-checked first
  if (image_size->area() == 0) {
    *image_size = image.size();
  } else if (image.size() != *image_size) {
    throw std::runtime_error("image '" + path + "' differs in size from the first " +
                             kCameraNames[camera] + " image");
  }
  return image;
}

// Detects the board in every pair; throws when fewer than min_pairs pairs show it.
ChessboardViews CollectViews(const ChessboardOptions& options,
                             const std::vector<cv::Point3f>& board,
                             const ChessboardImages& images) {
  ChessboardViews views;
  for (int camera = 0; camera < 2; ++camera) {
    const std::vector<cv::Mat>& camera_images = camera == 0 ? images.left : images.right;
    if (!camera_images.empty()) views.image_size[camera] = camera_images.front().size();
  }
  for (size_t pair = 0; pair < images.left.size() && pair < images.right.size(); ++pair) {
    std::optional<std::vector<Eigen::Vector2d>> found[2];
    const cv::Mat* pair_images[2] = {&images.left[pair], &images.right[pair]};
    for (int camera = 0; camera < 2; ++camera) {
      found[camera] = DetectChessboardCorners(*pair_images[camera], options.rows, options.cols,
                                              options.subpixel_window);
      if (found[camera] && options.orient_by_square_colour) {
        OrientChessboardCorners(*pair_images[camera], options.rows, options.cols, &*found[camera]);
      }
      if (!found[camera]) {
        views.skipped.push_back(camera == 0 ? options.left_images[pair]
                                            : options.right_images[pair]);
      }
    }
    const bool both = found[0] && found[1];
    if (!both && !options.single_camera_views) continue;
    if (both) views.object_points.push_back(board);
    for (int camera = 0; camera < 2; ++camera) {
      if (!found[camera]) continue;
      std::vector<cv::Point2f> view;
      for (const Eigen::Vector2d& p : *found[camera]) {
        view.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
      }
      (both ? views.corners : views.single_camera_corners)[camera].push_back(view);
      if (both && views.first_image[camera].empty()) views.first_image[camera] = *pair_images[camera];
    }
  }
  if (static_cast<int>(views.object_points.size()) < options.min_pairs) {
    throw std::runtime_error("the " + std::to_string(options.rows) + " x " +
                             std::to_string(options.cols) + " inner-corner board was found in " +
                             std::to_string(views.object_points.size()) + " pair(s), need " +
                             std::to_string(options.min_pairs) +
                             " (check --rows/--cols: inner corners, not squares)");
  }
  return views;
}

// One camera's intrinsics (cv::calibrateCamera, Zhang's method) into *K, *D, its RMS into *rms,
// and its report: every corner measured and reprojected, and the first view's overlay.
CameraCalibrationReport CalibrateOneCamera(const ChessboardViews& views, int camera,
                                           const std::vector<cv::Point3f>& board, int cols,
                                           int flags, cv::Mat* K, cv::Mat* D, double* rms) {
  std::vector<cv::Mat> rvecs, tvecs;
  std::vector<std::vector<cv::Point3f>> object_points = views.object_points;
  std::vector<std::vector<cv::Point2f>> corners = views.corners[camera];
  for (const auto& view : views.single_camera_corners[camera]) {
    object_points.push_back(board);
    corners.push_back(view);
  }
  *rms = cv::calibrateCamera(object_points, corners, views.image_size[camera], *K, *D, rvecs,
                             tvecs, flags);
  CameraCalibrationReport camera_report;
  camera_report.camera = kCameraNames[camera];
  std::vector<Eigen::Vector2d> residuals;
  for (size_t view = 0; view < object_points.size(); ++view) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object_points[view], rvecs[view], tvecs[view], *K, *D, projected);
    for (size_t i = 0; i < projected.size(); ++i) {
      CalibrationObservation observation;
      observation.point3D_in_world = Eigen::Vector3d(board[i].x, board[i].y, board[i].z);
      observation.measured_px = Eigen::Vector2d(corners[view][i].x, corners[view][i].y);
      observation.reprojected_px = Eigen::Vector2d(projected[i].x, projected[i].y);
      observation.view = static_cast<int>(view);
      observation.label = "r" + std::to_string(static_cast<int>(i) / cols) + "c" +
                          std::to_string(static_cast<int>(i) % cols);
      residuals.push_back(observation.reprojected_px - observation.measured_px);
      camera_report.observations.push_back(observation);
    }
  }
  camera_report.final = SummariseResiduals(residuals);
  camera_report.linear = camera_report.final;
  std::vector<CalibrationObservation> first_view;
  for (const auto& o : camera_report.observations) {
    if (o.view == 0) first_view.push_back(o);
  }
  camera_report.overlay = DrawCalibrationOverlay(views.first_image[camera], first_view);
  return camera_report;
}

// The stereo calibration from both cameras' intrinsics and the left-to-right pose R, T:
// P1 = K1 [I | 0], P2 = K2 [R | T] (world frame = left camera, mm).
StereoCalibration StereoFromIntrinsics(const cv::Mat (&K)[2], const cv::Mat (&D)[2],
                                       const cv::Mat& R, const cv::Mat& T,
                                       const cv::Size& image_size) {
  Intrinsics intrinsics;
  cv::cv2eigen(K[0], intrinsics.K1);
  cv::cv2eigen(K[1], intrinsics.K2);
  intrinsics.D1.assign(D[0].begin<double>(), D[0].end<double>());
  intrinsics.D2.assign(D[1].begin<double>(), D[1].end<double>());
  cv::cv2eigen(R, intrinsics.R);
  cv::cv2eigen(T, intrinsics.T);
  StereoCalibration calibration;
  calibration.P1.leftCols<3>() = intrinsics.K1;
  calibration.P1.col(3).setZero();
  calibration.P2.leftCols<3>() = intrinsics.K2 * intrinsics.R;
  calibration.P2.col(3) = intrinsics.K2 * intrinsics.T;
  calibration.intrinsics = intrinsics;
  calibration.image_width = image_size.width;
  calibration.image_height = image_size.height;
  calibration.DeriveFromProjections();
  return calibration;
}

// Every camera's corners undistorted (P and F apply to undistorted pixels).
void UndistortCorners(const ChessboardViews& views, const cv::Mat (&K)[2], const cv::Mat (&D)[2],
                      std::vector<Eigen::Vector2d> (&undistorted)[2]) {
  for (int camera = 0; camera < 2; ++camera) {
    for (const auto& view : views.corners[camera]) {
      std::vector<cv::Point2f> points;
      cv::undistortPoints(view, points, K[camera], D[camera], cv::noArray(), K[camera]);
      for (const cv::Point2f& p : points) undistorted[camera].emplace_back(p.x, p.y);
    }
  }
}

// The report's method-specific figures and notes.
void AddChessboardReportExtras(const ChessboardOptions& options, const ChessboardViews& views,
                               const double (&opencv_rms)[2], double stereo_rms,
                               CalibrationReport* report) {
  report->extra = {{"opencv_rms_left_px", opencv_rms[0]},
                   {"opencv_rms_right_px", opencv_rms[1]},
                   {"stereo_rms_px", stereo_rms},
                   {"num_pairs", views.object_points.size()},
                   {"skipped_images", views.skipped},
                   {"rows", options.rows},
                   {"cols", options.cols},
                   {"square_mm", options.square_mm},
                   {"world_frame", "left camera, mm"}};
  report->notes.push_back(
      "world frame = left camera frame (mm); P and F apply to "
      "undistorted pixels (D1, D2 in CAL.yml)");
  if (!views.skipped.empty()) {
    report->notes.push_back(std::to_string(views.skipped.size()) +
                            " image(s) without a detected board were skipped");
  }
}

}  // namespace

ChessboardImages LoadChessboardImages(const ChessboardOptions& options) {
  ChessboardImages images;
  cv::Size image_size[2];
  for (size_t pair = 0; pair < options.left_images.size(); ++pair) {
    images.left.push_back(ReadPairImage(options.left_images[pair], 0, &image_size[0]));
    if (pair < options.right_images.size()) {
      images.right.push_back(ReadPairImage(options.right_images[pair], 1, &image_size[1]));
    }
  }
  return images;
}

CalibrationResult CalibrateChessboard(const ChessboardOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::runtime_error(problem);
  }
  return CalibrateChessboard(options, LoadChessboardImages(options));
}

CalibrationResult CalibrateChessboard(const ChessboardOptions& options,
                                      const ChessboardImages& images) {
  const auto start = std::chrono::steady_clock::now();
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::runtime_error(problem);
  }
  const std::vector<cv::Point3f> board = BoardPoints(options);
  const ChessboardViews views = CollectViews(options, board, images);
  CalibrationResult result;
  result.report.method = "chessboard";
  result.report.num_views = static_cast<int>(views.object_points.size());
  cv::Mat K[2], D[2];
  double opencv_rms[2] = {0, 0};
  for (int camera = 0; camera < 2; ++camera) {
    result.report.cameras.push_back(CalibrateOneCamera(views, camera, board, options.cols,
                                                       options.fix_k3 ? cv::CALIB_FIX_K3 : 0,
                                                       &K[camera], &D[camera],
                                                       &opencv_rms[camera]));
  }
  cv::Mat R, T, E, F;
  const double stereo_rms = cv::stereoCalibrate(
      views.object_points, views.corners[0], views.corners[1], K[0], D[0], K[1], D[1],
      views.image_size[0], R, T, E, F, cv::CALIB_FIX_INTRINSIC,
      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-6));
  result.calibration = StereoFromIntrinsics(K, D, R, T, views.image_size[0]);
  StereoCalibration& calibration = result.calibration;
  calibration.world_frame = "left camera";
  result.report.cameras[0].camera_centre = calibration.C1;
  result.report.cameras[1].camera_centre = calibration.C2;
  std::vector<Eigen::Vector2d> undistorted[2];
  UndistortCorners(views, K, D, undistorted);
  result.report.num_epipolar_pairs = static_cast<int>(undistorted[0].size());
  result.report.mean_epipolar_distance_px =
      MeanEpipolarDistancePx(calibration.F, undistorted[0], undistorted[1]);
  AddChessboardReportExtras(options, views, opencv_rms, stereo_rms, &result.report);
  StoreErrorFigures(&result);
  calibration.error_figures.emplace_back("stereo_rms_px", stereo_rms);
  result.report.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hnnstereo::calib
