#include "vision/synth/circle_target_render.h"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

namespace hnnstereo::calib {
namespace {

constexpr int kShiftBits = 8;  // fillPoly fixed-point sub-pixel bits
constexpr double kShiftScale = 1 << kShiftBits;

}  // namespace

std::string CircleTargetRenderOptions::Check() const {
  std::ostringstream out;
  if (image_width < 16 || image_height < 16) {
    out << "render image size must be at least 16x16 (is " << image_width << "x" << image_height
        << ")";
  } else if (supersampling < 1 || supersampling > 16) {
    out << "CircleTargetRenderOptions.supersampling must be in [1, 16] (is " << supersampling
        << ")";
  } else if (blur_sigma_px < 0.0 || noise_sigma_grey < 0.0 || centre_jitter_px < 0.0) {
    out << "blur, noise and jitter must be >= 0";
  } else if (num_distractors < 0) {
    out << "CircleTargetRenderOptions.num_distractors must be >= 0 (is " << num_distractors << ")";
  } else if (plate_margin_mm < 0.0) {
    out << "CircleTargetRenderOptions.plate_margin_mm must be >= 0 (is " << plate_margin_mm << ")";
  }
  return out.str();
}

ProjectionMatrix LookAtCamera(double focal_px, const Eigen::Vector2d& principal_point_px,
                              const Eigen::Vector3d& centre_mm, const Eigen::Vector3d& look_at_mm,
                              const Eigen::Vector3d& up_in_world) {
  const Eigen::Vector3d z = (look_at_mm - centre_mm).normalized();
  Eigen::Vector3d y = -(up_in_world - up_in_world.dot(z) * z);
  if (y.norm() < 1e-9) throw std::invalid_argument("LookAtCamera: up is parallel to the view");
  y.normalize();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d cam_from_world_rotation;
  cam_from_world_rotation.row(0) = x.transpose();
  cam_from_world_rotation.row(1) = y.transpose();
  cam_from_world_rotation.row(2) = z.transpose();
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = K(1, 1) = focal_px;
  K.block<2, 1>(0, 2) = principal_point_px;
  ProjectionMatrix P;
  P.leftCols<3>() = K * cam_from_world_rotation;
  P.col(3) = -K * cam_from_world_rotation * centre_mm;
  return P;
}

namespace {

// The supersampled canvas a target is drawn on (options.supersampling times the image size, in
// fillPoly's fixed point), the camera and pose it is seen through, and the one random stream
// that jitters the circles, places the distractors and adds the noise, in that order.
class TargetCanvas {
 public:
  TargetCanvas(const ProjectionMatrix& P, const Eigen::Matrix4d& world_from_target,
               const CircleTargetRenderOptions& options)
      : P_(P), world_from_target_(world_from_target), options_(options),
        s_(options.supersampling), generator_(options.random_seed),
        big_(options.image_height * s_, options.image_width * s_, CV_8UC1,
             cv::Scalar(options.table_grey)) {}

  // The plate (the grid's extent plus plate_margin_mm) as an image polygon (px); clears
  // rendered->fully_visible when a corner falls outside the image.
  std::vector<cv::Point2f> DrawPlate(const CircleGridGeometry& grid,
                                     RenderedCircleTarget* rendered) {
    const double margin = options_.plate_margin_mm;
    const double width_mm = (grid.cols - 1) * grid.pitch_mm;
    const double height_mm = (grid.rows - 1) * grid.pitch_mm;
    const std::vector<Eigen::Vector2d> plate_corners = {
        ProjectTarget({-margin, -margin, 0.0}), ProjectTarget({width_mm + margin, -margin, 0.0}),
        ProjectTarget({width_mm + margin, height_mm + margin, 0.0}),
        ProjectTarget({-margin, height_mm + margin, 0.0})};
    std::vector<cv::Point> plate_polygon;
    std::vector<cv::Point2f> plate_polygon_px;
    rendered->fully_visible = true;
    for (const Eigen::Vector2d& corner : plate_corners) {
      plate_polygon.push_back(ToBig(corner));
      plate_polygon_px.emplace_back(static_cast<float>(corner.x()),
                                    static_cast<float>(corner.y()));
      if (corner.x() < 0 || corner.y() < 0 || corner.x() > options_.image_width - 1 ||
          corner.y() > options_.image_height - 1) {
        rendered->fully_visible = false;
      }
    }
    FillPolygon(plate_polygon, options_.plate_grey);
    return plate_polygon_px;
  }

  // The circles: their exact perspective outline, shifted by the jitter; their centres (px)
  // into rendered->centres_px.
  void DrawCircles(const CircleGridGeometry& grid, RenderedCircleTarget* rendered) {
    constexpr int kOutlineVertices = 180;
    for (int row = 0; row < grid.rows; ++row) {
      for (int col = 0; col < grid.cols; ++col) {
        const Eigen::Vector2d jitter(options_.centre_jitter_px * normal_(generator_),
                                     options_.centre_jitter_px * normal_(generator_));
        const Eigen::Vector3d centre = grid.PointInTarget(row, col);
        rendered->centres_px.push_back(ProjectTarget(centre) + jitter);
        std::vector<cv::Point> outline;
        for (int k = 0; k < kOutlineVertices; ++k) {
          const double angle = 2.0 * std::numbers::pi * k / kOutlineVertices;
          const Eigen::Vector3d rim = centre + grid.circle_radius_mm *
                                                   Eigen::Vector3d(std::cos(angle),
                                                                   std::sin(angle), 0);
          outline.push_back(ToBig(ProjectTarget(rim) + jitter));
        }
        FillPolygon(outline, options_.circle_grey);
      }
    }
  }

  // Distractors off the plate (at most 2000 tries): bright reflections, some with a dark mark
  // inside; the circular marks' centres into rendered->distractor_centres_px.
  void DrawDistractors(const std::vector<cv::Point2f>& plate_polygon_px,
                       RenderedCircleTarget* rendered) {
    std::vector<std::pair<Eigen::Vector2d, double>> placed;
    for (int d = 0, attempts = 0; d < options_.num_distractors && attempts < 2000; ++attempts) {
      const double outer_radius = 10.0 + 12.0 * uniform_(generator_);
      const Eigen::Vector2d centre(
          outer_radius + 2 + (options_.image_width - 2 * outer_radius - 4) * uniform_(generator_),
          outer_radius + 2 + (options_.image_height - 2 * outer_radius - 4) * uniform_(generator_));
      const double distance_to_plate = cv::pointPolygonTest(
          plate_polygon_px,
          cv::Point2f(static_cast<float>(centre.x()), static_cast<float>(centre.y())), true);
      if (distance_to_plate > -(outer_radius + 8.0)) continue;  // inside or touching the plate
      bool overlaps = false;
      for (const auto& [other, other_radius] : placed) {
        overlaps = overlaps || (other - centre).norm() < outer_radius + other_radius + 4.0;
      }
      if (overlaps) continue;
      placed.emplace_back(centre, outer_radius);
      ++d;
      DrawDistractor(centre, outer_radius, rendered);
    }
  }

  // The canvas averaged down to the image size, blurred, with Gaussian noise, as 8-bit grey.
  cv::Mat Finish() {
    cv::Mat image;
    cv::resize(big_, image, cv::Size(options_.image_width, options_.image_height), 0, 0,
               cv::INTER_AREA);
    cv::Mat image_float;
    image.convertTo(image_float, CV_32F);
    if (options_.blur_sigma_px > 0.0) {
      cv::GaussianBlur(image_float, image_float, cv::Size(0, 0), options_.blur_sigma_px);
    }
    if (options_.noise_sigma_grey > 0.0) {
      for (int y = 0; y < image_float.rows; ++y) {
        float* row = image_float.ptr<float>(y);
        for (int x = 0; x < image_float.cols; ++x) {
          row[x] += static_cast<float>(options_.noise_sigma_grey * normal_(generator_));
        }
      }
    }
    cv::Mat result;
    image_float.convertTo(result, CV_8U);  // rounds and saturates
    return result;
  }

 private:
  // Image point (original px) -> fixed-point supersampled coordinates.
  cv::Point ToBig(const Eigen::Vector2d& x) const {
    return cv::Point(static_cast<int>(std::lround(((x.x() + 0.5) * s_ - 0.5) * kShiftScale)),
                     static_cast<int>(std::lround(((x.y() + 0.5) * s_ - 0.5) * kShiftScale)));
  }
  int RadiusBig(double r) const { return static_cast<int>(std::lround(r * s_ * kShiftScale)); }

  Eigen::Vector2d ProjectTarget(const Eigen::Vector3d& point_in_target) const {
    const Eigen::Vector3d x = P_ * (world_from_target_ * point_in_target.homogeneous());
    if (!(x.z() > 0.0)) {
      throw std::invalid_argument("RenderCircleTarget: the target is behind the camera");
    }
    return Eigen::Vector2d(x.hnormalized());
  }

  void FillPolygon(const std::vector<cv::Point>& polygon, double grey) {
    cv::fillPoly(big_, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(grey),
                 cv::LINE_AA, kShiftBits);
  }

  // A bright disc of outer_radius px with one of four marks inside: a dark circle (a false
  // circle the grid search must reject), an elongated ellipse (a glint edge), a square, none.
  void DrawDistractor(const Eigen::Vector2d& centre, double outer_radius,
                      RenderedCircleTarget* rendered) {
    cv::circle(big_, ToBig(centre), RadiusBig(outer_radius), cv::Scalar(240), cv::FILLED,
               cv::LINE_AA, kShiftBits);
    const int kind = static_cast<int>(uniform_(generator_) * 4.0);
    const double mark_radius = 3.0 + (outer_radius - 7.0) * uniform_(generator_);
    const double angle_deg = 180.0 * uniform_(generator_);
    if (kind == 0) {
      cv::circle(big_, ToBig(centre), RadiusBig(mark_radius), cv::Scalar(options_.circle_grey),
                 cv::FILLED, cv::LINE_AA, kShiftBits);
      rendered->distractor_centres_px.push_back(centre);
    } else if (kind == 1) {
      cv::ellipse(big_, ToBig(centre),
                  cv::Size(RadiusBig(mark_radius), RadiusBig(mark_radius * 0.4)), angle_deg, 0,
                  360, cv::Scalar(options_.circle_grey), cv::FILLED, cv::LINE_AA, kShiftBits);
    } else if (kind == 2) {
      const cv::RotatedRect square(
          cv::Point2f(static_cast<float>(centre.x()), static_cast<float>(centre.y())),
          cv::Size2f(static_cast<float>(1.4 * mark_radius), static_cast<float>(1.4 * mark_radius)),
          static_cast<float>(angle_deg));
      cv::Point2f vertices[4];
      square.points(vertices);
      std::vector<cv::Point> polygon;
      for (const cv::Point2f& v : vertices) polygon.push_back(ToBig({v.x, v.y}));
      FillPolygon(polygon, options_.circle_grey);
    }
  }

  const ProjectionMatrix& P_;
  const Eigen::Matrix4d& world_from_target_;
  const CircleTargetRenderOptions& options_;
  const int s_;
  std::mt19937_64 generator_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  cv::Mat big_;
};

}  // namespace

RenderedCircleTarget RenderCircleTarget(const ProjectionMatrix& P,
                                        const Eigen::Matrix4d& world_from_target,
                                        const CircleGridGeometry& grid,
                                        const CircleTargetRenderOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (const std::string problem = grid.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  TargetCanvas canvas(P, world_from_target, options);
  RenderedCircleTarget rendered;
  const std::vector<cv::Point2f> plate_polygon_px = canvas.DrawPlate(grid, &rendered);
  canvas.DrawCircles(grid, &rendered);
  canvas.DrawDistractors(plate_polygon_px, &rendered);
  rendered.image = canvas.Finish();
  return rendered;
}

}  // namespace hnnstereo::calib
