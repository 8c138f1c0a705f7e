#include "calib/board_calibration.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>

#include "calib/chessboard.h"
#include "calib/target_file.h"
#include "common/input_limits.h"

namespace hnnstereo::calib {
namespace fs = std::filesystem;

std::string ChessboardGeometry::Check() const {
  std::ostringstream out;
  if (rows < 2 || cols < 3) {
    out << "board_rows must be >= 2 and board_cols >= 3 (inner corners; are " << rows << ", "
        << cols << ")";
  } else if ((rows + cols) % 2 != 1) {
    out << "board_rows + board_cols must be odd, so that the board's orientation shows (are "
        << rows << ", " << cols << ")";
  } else if (!(square_mm > 0.0) || !std::isfinite(square_mm)) {
    out << "board_square_mm must be > 0 (is " << square_mm << ")";
  } else if (!(margin_mm >= 0.0) || !std::isfinite(margin_mm)) {
    out << "board margin_mm must be >= 0 (is " << margin_mm << ")";
  }
  return out.str();
}

std::vector<Eigen::Vector3d> ChessboardGeometry::Corners() const {
  std::vector<Eigen::Vector3d> corners;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) corners.emplace_back(c * square_mm, r * square_mm, 0.0);
  }
  return corners;
}

std::string BoardTarget::Check() const {
  if (std::string problem = board.Check(); !problem.empty()) return problem;
  int on_table = 0;
  for (const BoardView& view : views) on_table += view.on_table ? 1 : 0;
  if (views.size() < 3) {
    return "board_views: at least 3 views are needed (has " + std::to_string(views.size()) + ")";
  }
  if (on_table == 0) return "board_views: no view has on_table: 1 (it fixes the table frame)";
  return {};
}

void WriteBoardTarget(const BoardTarget& target, cv::FileStorage* storage) {
  cv::FileStorage& out = *storage;
  out << "board" << "chessboard";
  out << "board_rows" << target.board.rows << "board_cols" << target.board.cols;
  out << "board_square_mm" << target.board.square_mm;
  out << "board_views" << "[";
  for (const BoardView& view : target.views) {
    cv::Mat pose;
    cv::eigen2cv(view.world_from_board, pose);
    out << "{" << "left" << view.left_image << "right" << view.right_image << "on_table"
        << static_cast<int>(view.on_table) << "world_from_target" << pose << "}";
  }
  out << "]";
}

namespace {

std::string Where(const std::string& path) { return TargetFileName(path); }

std::string ResolvedImage(const cv::FileNode& node, const char* key, const fs::path& dir,
                          const std::string& where) {
  if (!node[key].isString()) throw std::runtime_error(where + " has no '" + key + "' image");
  const fs::path image(static_cast<std::string>(node[key]));
  const fs::path resolved = image.is_absolute() ? image : dir / image;
  if (!fs::is_regular_file(resolved)) {
    throw std::runtime_error(where + ": image '" + resolved.string() + "' does not exist");
  }
  return resolved.string();
}

BoardView ReadBoardView(const cv::FileNode& node, const fs::path& dir, const std::string& where) {
  BoardView view;
  view.left_image = ResolvedImage(node, "left", dir, where);
  view.right_image = ResolvedImage(node, "right", dir, where);
  view.on_table = !node["on_table"].empty() && static_cast<double>(node["on_table"]) != 0.0;
  cv::Mat pose;
  if (!node["world_from_target"].empty()) node["world_from_target"] >> pose;
  if (!pose.empty()) {
    if (pose.rows != 4 || pose.cols != 4) throw std::runtime_error(where + ": pose is not 4x4");
    pose.convertTo(pose, CV_64F);
    cv::cv2eigen(pose, view.world_from_board);
  } else if (view.on_table) {
    throw std::runtime_error(where + " lies on the table but has no world_from_target");
  }
  const Eigen::Matrix3d rotation = view.world_from_board.topLeftCorner<3, 3>();
  if (!view.world_from_board.allFinite() ||
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      view.world_from_board.block<3, 1>(0, 3).cwiseAbs().maxCoeff() > TextInputLimits{}.max_abs_mm) {
    throw std::runtime_error(where + ": world_from_target must be a finite rotation + translation");
  }
  return view;
}

// Two views' undistorted pixels -> points in the left camera frame (linear triangulation,
// H&Z 12.2) through P1 = K1 [I | 0], P2 = K2 [R | T].
std::vector<Eigen::Vector3d> TriangulateInLeftFrame(const Intrinsics& lens,
                                                    const std::vector<cv::Point2d>& left,
                                                    const std::vector<cv::Point2d>& right) {
  ProjectionMatrix P1, P2;
  P1 << lens.K1, Eigen::Vector3d::Zero();
  P2 << lens.K2 * lens.R, lens.K2 * lens.T;
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < left.size(); ++i) {
    Eigen::Matrix4d A;
    A.row(0) = left[i].x * P1.row(2) - P1.row(0);
    A.row(1) = left[i].y * P1.row(2) - P1.row(1);
    A.row(2) = right[i].x * P2.row(2) - P2.row(0);
    A.row(3) = right[i].y * P2.row(2) - P2.row(1);
    Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
    points.push_back(svd.matrixV().col(3).hnormalized());
  }
  return points;
}

// One camera's corners of a view on the table, in the board's own order, distorted pixels.
std::vector<cv::Point2d> TableCorners(const std::string& path, const ChessboardGeometry& board,
                                      int subpixel_window) {
  const cv::Mat grey = ReadImageFileWithin(path, cv::IMREAD_GRAYSCALE);
  auto corners = DetectChessboardCorners(grey, board.rows, board.cols, subpixel_window);
  if (!corners) {
    throw std::runtime_error("the board on the table is not found in '" + path + "'");
  }
  OrientChessboardCorners(grey, board.rows, board.cols, &*corners);
  std::vector<cv::Point2d> points;
  for (const Eigen::Vector2d& p : *corners) points.emplace_back(p.x(), p.y());
  return points;
}

// The table views' corners: measured pixels per camera and their world points.
struct TableObservations {
  std::vector<cv::Point2d> pixels[2];
  std::vector<Eigen::Vector3d> world;
};

TableObservations ObserveTable(const BoardTarget& target, int subpixel_window) {
  TableObservations table;
  const std::vector<Eigen::Vector3d> corners = target.board.Corners();
  for (const BoardView& view : target.views) {
    if (!view.on_table) continue;
    for (int camera = 0; camera < 2; ++camera) {
      const auto pixels = TableCorners(camera == 0 ? view.left_image : view.right_image,
                                       target.board, subpixel_window);
      table.pixels[camera].insert(table.pixels[camera].end(), pixels.begin(), pixels.end());
    }
    for (const Eigen::Vector3d& corner : corners) {
      table.world.push_back((view.world_from_board * corner.homogeneous()).hnormalized());
    }
  }
  return table;
}

cv::Mat ToCv(const Eigen::MatrixXd& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}

// RMS (px) of `pixels` against the world points projected through a camera with distortion.
double ReprojectionRmsPx(const std::vector<Eigen::Vector3d>& world,
                         const std::vector<cv::Point2d>& pixels, const Eigen::Matrix4d& cam_from_world,
                         const Eigen::Matrix3d& K, const std::vector<double>& D) {
  std::vector<cv::Point3d> in_camera;
  for (const Eigen::Vector3d& X : world) {
    const Eigen::Vector3d x = (cam_from_world * X.homogeneous()).hnormalized();
    in_camera.emplace_back(x.x(), x.y(), x.z());
  }
  std::vector<cv::Point2d> projected;
  cv::projectPoints(in_camera, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), ToCv(K), cv::Mat(D, true),
                    projected);
  double sum = 0.0;
  for (std::size_t i = 0; i < projected.size(); ++i) {
    const cv::Point2d d = projected[i] - pixels[i];
    sum += d.dot(d);
  }
  return std::sqrt(sum / static_cast<double>(std::max<std::size_t>(1, projected.size())));
}

// World_from_left from the table views (rigid fit of the triangulated corners); moves the
// calibration's world frame onto the table and records the fit in the report.
void FixTableFrame(const BoardTarget& target, int subpixel_window, CalibrationResult* result) {
  StereoCalibration& calibration = result->calibration;
  const Intrinsics& lens = *calibration.intrinsics;
  TableObservations table = ObserveTable(target, subpixel_window);
  std::vector<cv::Point2d> undistorted[2];
  const Eigen::Matrix3d* K[2] = {&lens.K1, &lens.K2};
  const std::vector<double>* D[2] = {&lens.D1, &lens.D2};
  for (int camera = 0; camera < 2; ++camera) {
    cv::undistortPoints(table.pixels[camera], undistorted[camera], ToCv(*K[camera]),
                        cv::Mat(*D[camera], true), cv::noArray(), ToCv(*K[camera]),
                        cv::TermCriteria(cv::TermCriteria::COUNT, 20, 0.0));
  }
  const std::vector<Eigen::Vector3d> in_left = TriangulateInLeftFrame(lens, undistorted[0],
                                                                      undistorted[1]);
  Eigen::Matrix3Xd source(3, in_left.size()), destination(3, in_left.size());
  for (std::size_t i = 0; i < in_left.size(); ++i) {
    source.col(static_cast<Eigen::Index>(i)) = in_left[i];
    destination.col(static_cast<Eigen::Index>(i)) = table.world[i];
  }
  const Eigen::Matrix4d world_from_left = Eigen::umeyama(source, destination, false);
  const Eigen::Matrix3Xd fitted =
      (world_from_left * source.colwise().homogeneous()).colwise().hnormalized();
  const double fit_rms_mm =
      std::sqrt((fitted - destination).colwise().squaredNorm().mean());
  const Eigen::Matrix4d left_from_world = world_from_left.inverse();
  calibration.P1 = calibration.P1 * left_from_world;
  calibration.P2 = calibration.P2 * left_from_world;
  calibration.DeriveFromProjections();
  calibration.world_frame = "table";
  calibration.world_from_left_camera = world_from_left;
  Eigen::Matrix4d right_from_left = Eigen::Matrix4d::Identity();
  right_from_left.topLeftCorner<3, 3>() = lens.R;
  right_from_left.block<3, 1>(0, 3) = lens.T;
  const double rms_left =
      ReprojectionRmsPx(table.world, table.pixels[0], left_from_world, lens.K1, lens.D1);
  const double rms_right = ReprojectionRmsPx(table.world, table.pixels[1],
                                             right_from_left * left_from_world, lens.K2, lens.D2);
  calibration.error_figures.emplace_back("table_fit_rms_mm", fit_rms_mm);
  CalibrationReport& report = result->report;
  report.cameras[0].camera_centre = calibration.C1;
  report.cameras[1].camera_centre = calibration.C2;
  report.extra["world_frame"] = "table (z = 0 on the table, z up, mm)";
  report.extra["table_views"] = static_cast<int>(table.world.size() / target.board.Corners().size());
  report.extra["table_fit_rms_mm"] = fit_rms_mm;
  report.extra["table_reprojection_rms_left_px"] = rms_left;
  report.extra["table_reprojection_rms_right_px"] = rms_right;
  report.notes.clear();
  std::ostringstream note;
  note.precision(3);
  note << "world frame = the table, from " << report.extra["table_views"].get<int>()
       << " board view(s) on it: rigid fit " << fit_rms_mm
       << " mm RMS, reprojection " << rms_left << " / " << rms_right
       << " px; P and F apply to undistorted pixels (D1, D2 in CAL.yml)";
  report.notes.push_back(note.str());
}

}  // namespace

std::optional<BoardTarget> LoadBoardTarget(const std::string& target_dir) {
  const fs::path dir(target_dir);
  const std::string path = (dir / "target.yml").string();
  if (!fs::is_directory(dir)) throw std::runtime_error("target folder '" + target_dir + "' does not exist");
  if (!fs::is_regular_file(path)) {
    throw std::runtime_error("target folder '" + target_dir + "' has no target.yml");
  }
  BoardTarget target;
  try {
    cv::FileStorage storage = OpenTargetFile(path);
    const cv::FileNode root = storage.root();
    if (root["board"].empty()) return std::nullopt;
    if (!root["board"].isString() || static_cast<std::string>(root["board"]) != "chessboard") {
      throw std::runtime_error(Where(path) + ": 'board' must be 'chessboard'");
    }
    for (const auto& [key, value] : {std::pair<const char*, int*>{"board_rows", &target.board.rows},
                                     {"board_cols", &target.board.cols}}) {
      if (!root[key].isInt()) throw std::runtime_error(Where(path) + ": '" + key + "' is not a whole number");
      *value = static_cast<int>(root[key]);
    }
    if (!root["board_square_mm"].isReal() && !root["board_square_mm"].isInt()) {
      throw std::runtime_error(Where(path) + ": 'board_square_mm' is not a number");
    }
    target.board.square_mm = static_cast<double>(root["board_square_mm"]);
    const cv::FileNode views = root["board_views"];
    if (!views.isSeq()) throw std::runtime_error(Where(path) + ": 'board_views' is not a list");
    int index = 0;
    for (cv::FileNodeIterator it = views.begin(); it != views.end(); ++it, ++index) {
      target.views.push_back(
          ReadBoardView(*it, dir, Where(path) + ": board view " + std::to_string(index)));
    }
  } catch (const cv::Exception& e) {
    throw std::runtime_error(Where(path) + " is not valid OpenCV YAML: " + e.err);
  }
  if (const std::string problem = target.Check(); !problem.empty()) {
    throw std::runtime_error(Where(path) + ": " + problem);
  }
  return target;
}

std::string BoardCalibrationOptions::Check() const {
  if (subpixel_window < 3) {
    return "board subpixel_window must be >= 3 (is " + std::to_string(subpixel_window) + ")";
  }
  return {};
}

CalibrationResult CalibrateBoardTarget(const BoardTarget& target,
                                       const BoardCalibrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& problem : {target.Check(), options.Check()}) {
    if (!problem.empty()) throw std::runtime_error(problem);
  }
  ChessboardOptions chessboard;
  chessboard.rows = target.board.rows;
  chessboard.cols = target.board.cols;
  chessboard.square_mm = target.board.square_mm;
  chessboard.subpixel_window = options.subpixel_window;
  chessboard.orient_by_square_colour = true;
  chessboard.fix_k3 = options.fix_k3;
  chessboard.single_camera_views = true;
  for (const BoardView& view : target.views) {
    chessboard.left_images.push_back(view.left_image);
    chessboard.right_images.push_back(view.right_image);
  }
  CalibrationResult result = CalibrateChessboard(chessboard);
  FixTableFrame(target, options.subpixel_window, &result);
  result.report.method = "board";
  result.report.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hnnstereo::calib
