#include "vision/synth/board_render.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "vision/synth/lens_model.h"

namespace hnnstereo::vision {
namespace {

// Grey of the board at (x, y) in its frame (mm): squares indexed from the outer row/column, the
// square between inner corners (0, 0) and (1, 1) dark (calib::ChessboardGeometry).
double BoardGrey(double x, double y, const calib::ChessboardGeometry& board,
                 const BoardRenderOptions& options) {
  const double s = board.square_mm, m = board.margin_mm;
  const double width = board.cols * s, height = board.rows * s;  // squares span [-s, cols * s]
  if (x < -s - m || y < -s - m || x > width + m || y > height + m) return options.table_grey;
  if (x < -s || y < -s || x > width || y > height) return options.light_grey;
  const int column = static_cast<int>(std::floor(x / s)) + 1, row = static_cast<int>(std::floor(y / s)) + 1;
  return (row + column) % 2 == 0 ? options.dark_grey : options.light_grey;
}

// Whether the board with its border projects inside the image (2 px margin).
bool FullyVisible(const calib::ProjectionMatrix& P, const Eigen::Matrix4d& world_from_board,
                  const calib::ChessboardGeometry& board, const BoardRenderOptions& options) {
  const double s = board.square_mm, m = board.margin_mm;
  std::vector<cv::Point3d> outline;
  for (int i = 0; i <= 20; ++i) {
    const double t = i / 20.0;
    const double x0 = -s - m, x1 = board.cols * s + m, y0 = -s - m, y1 = board.rows * s + m;
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(x0 + t * (x1 - x0), y0),
                                     Eigen::Vector2d(x0 + t * (x1 - x0), y1),
                                     Eigen::Vector2d(x0, y0 + t * (y1 - y0)),
                                     Eigen::Vector2d(x1, y0 + t * (y1 - y0))}) {
      const Eigen::Vector4d X = world_from_board * Eigen::Vector4d(p.x(), p.y(), 0.0, 1.0);
      const Eigen::Vector3d x = P * X;
      if (!(x.z() > 0.0)) return false;
      const Eigen::Matrix3d K = CameraMatrixOf(P);
      const Eigen::Vector3d ray = K.inverse() * x;  // normalised camera coordinates
      outline.emplace_back(ray.x() / ray.z(), ray.y() / ray.z(), 1.0);
    }
  }
  cv::Mat camera;
  cv::eigen2cv(CameraMatrixOf(P), camera);
  std::vector<cv::Point2d> pixels;
  cv::projectPoints(outline, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera,
                    options.distortion.empty() ? cv::Mat() : cv::Mat(options.distortion, true),
                    pixels);
  for (const cv::Point2d& p : pixels) {
    if (p.x < 2 || p.y < 2 || p.x > options.image_width - 3 || p.y > options.image_height - 3) {
      return false;
    }
  }
  return true;
}

}  // namespace

RenderedBoard RenderChessboard(const calib::ProjectionMatrix& P,
                               const Eigen::Matrix4d& world_from_board,
                               const calib::ChessboardGeometry& board,
                               const BoardRenderOptions& options) {
  const int width = options.image_width, height = options.image_height, s = options.supersampling;
  const Eigen::Matrix3d K = CameraMatrixOf(P);
  const Eigen::Matrix3d M_inverse = P.leftCols<3>().inverse();
  const Eigen::Vector3d centre = -M_inverse * P.col(3);
  const Eigen::Matrix4d board_from_world = world_from_board.inverse();
  const Eigen::Vector3d origin = (board_from_world * centre.homogeneous()).hnormalized();
  const Eigen::Matrix3d rotation = board_from_world.topLeftCorner<3, 3>();
  // The pinhole image first; with distortion it is then resampled through the lens
  // (DistortIdealImage), which costs one inverse per pixel rather than per ray.
  cv::Mat radiance(height, width, CV_32F);
  cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      for (int u = 0; u < width; ++u) {
        double sum = 0.0;
        for (int i = 0; i < s; ++i) {
          for (int j = 0; j < s; ++j) {
            const Eigen::Vector3d pixel(u + (j + 0.5) / s - 0.5, v + (i + 0.5) / s - 0.5, 1.0);
            const Eigen::Vector3d direction = rotation * (M_inverse * pixel);
            const double t = -origin.z() / direction.z();  // the board's plane z = 0
            sum += t > 0.0 ? BoardGrey(origin.x() + t * direction.x(),
                                       origin.y() + t * direction.y(), board, options)
                           : options.table_grey;
          }
        }
        radiance.at<float>(v, u) = static_cast<float>(sum / (s * s));
      }
    }
  });
  radiance = DistortIdealImage(radiance, K, options.distortion);
  if (options.blur_sigma_px > 0.0) {
    cv::GaussianBlur(radiance, radiance, cv::Size(0, 0), options.blur_sigma_px);
  }
  std::mt19937_64 generator(options.random_seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_sigma_grey));
  if (options.noise_sigma_grey > 0.0) {
    for (int v = 0; v < height; ++v) {
      float* row = radiance.ptr<float>(v);
      for (int u = 0; u < width; ++u) row[u] += noise(generator);
    }
  }
  RenderedBoard rendered;
  radiance.convertTo(rendered.image, CV_8U);
  rendered.fully_visible = FullyVisible(P, world_from_board, board, options);
  return rendered;
}

}  // namespace hnnstereo::vision
