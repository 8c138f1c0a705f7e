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
  std::mt19937_64 generator(options.random_seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);

  const int s = options.supersampling;
  const int big_width = options.image_width * s;
  const int big_height = options.image_height * s;
  cv::Mat big(big_height, big_width, CV_8UC1, cv::Scalar(options.table_grey));

  // Image point (original px) -> fixed-point supersampled coordinates.
  auto to_big = [&](const Eigen::Vector2d& x) {
    return cv::Point(static_cast<int>(std::lround(((x.x() + 0.5) * s - 0.5) * kShiftScale)),
                     static_cast<int>(std::lround(((x.y() + 0.5) * s - 0.5) * kShiftScale)));
  };
  auto project_target = [&](const Eigen::Vector3d& point_in_target) {
    const Eigen::Vector3d x = P * (world_from_target * point_in_target.homogeneous());
    if (!(x.z() > 0.0)) {
      throw std::invalid_argument("RenderCircleTarget: the target is behind the camera");
    }
    return Eigen::Vector2d(x.hnormalized());
  };

  // The plate.
  const double margin = options.plate_margin_mm;
  const double width_mm = (grid.cols - 1) * grid.pitch_mm;
  const double height_mm = (grid.rows - 1) * grid.pitch_mm;
  const std::vector<Eigen::Vector2d> plate_corners = {
      project_target({-margin, -margin, 0.0}), project_target({width_mm + margin, -margin, 0.0}),
      project_target({width_mm + margin, height_mm + margin, 0.0}),
      project_target({-margin, height_mm + margin, 0.0})};
  std::vector<cv::Point> plate_polygon;
  std::vector<cv::Point2f> plate_polygon_px;
  RenderedCircleTarget rendered;
  rendered.fully_visible = true;
  for (const Eigen::Vector2d& corner : plate_corners) {
    plate_polygon.push_back(to_big(corner));
    plate_polygon_px.emplace_back(static_cast<float>(corner.x()), static_cast<float>(corner.y()));
    if (corner.x() < 0 || corner.y() < 0 || corner.x() > options.image_width - 1 ||
        corner.y() > options.image_height - 1) {
      rendered.fully_visible = false;
    }
  }
  cv::fillPoly(big, std::vector<std::vector<cv::Point>>{plate_polygon},
               cv::Scalar(options.plate_grey), cv::LINE_AA, kShiftBits);

  // The circles: their exact perspective outline, shifted by the jitter.
  constexpr int kOutlineVertices = 180;
  for (int row = 0; row < grid.rows; ++row) {
    for (int col = 0; col < grid.cols; ++col) {
      const Eigen::Vector2d jitter(options.centre_jitter_px * normal(generator),
                                   options.centre_jitter_px * normal(generator));
      const Eigen::Vector3d centre = grid.PointInTarget(row, col);
      rendered.centres_px.push_back(project_target(centre) + jitter);
      std::vector<cv::Point> outline;
      for (int k = 0; k < kOutlineVertices; ++k) {
        const double angle = 2.0 * std::numbers::pi * k / kOutlineVertices;
        const Eigen::Vector3d rim =
            centre + grid.circle_radius_mm * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0);
        outline.push_back(to_big(project_target(rim) + jitter));
      }
      cv::fillPoly(big, std::vector<std::vector<cv::Point>>{outline},
                   cv::Scalar(options.circle_grey), cv::LINE_AA, kShiftBits);
    }
  }

  // Distractors off the plate: bright reflections, some with a dark mark inside.
  std::vector<std::pair<Eigen::Vector2d, double>> placed;
  for (int d = 0, attempts = 0; d < options.num_distractors && attempts < 2000; ++attempts) {
    const double outer_radius = 10.0 + 12.0 * uniform(generator);
    const Eigen::Vector2d centre(
        outer_radius + 2 + (options.image_width - 2 * outer_radius - 4) * uniform(generator),
        outer_radius + 2 + (options.image_height - 2 * outer_radius - 4) * uniform(generator));
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
    const auto radius_big = [&](double r) {
      return static_cast<int>(std::lround(r * s * kShiftScale));
    };
    cv::circle(big, to_big(centre), radius_big(outer_radius), cv::Scalar(240), cv::FILLED,
               cv::LINE_AA, kShiftBits);
    const int kind = static_cast<int>(uniform(generator) * 4.0);
    const double mark_radius = 3.0 + (outer_radius - 7.0) * uniform(generator);
    const double angle_deg = 180.0 * uniform(generator);
    if (kind == 0) {  // circular mark: a false circle the grid search must reject
      cv::circle(big, to_big(centre), radius_big(mark_radius), cv::Scalar(options.circle_grey),
                 cv::FILLED, cv::LINE_AA, kShiftBits);
      rendered.distractor_centres_px.push_back(centre);
    } else if (kind == 1) {  // elongated ellipse (a glint edge)
      cv::ellipse(big, to_big(centre),
                  cv::Size(radius_big(mark_radius), radius_big(mark_radius * 0.4)), angle_deg, 0,
                  360, cv::Scalar(options.circle_grey), cv::FILLED, cv::LINE_AA, kShiftBits);
    } else if (kind == 2) {  // square mark
      const cv::RotatedRect square(
          cv::Point2f(static_cast<float>(centre.x()), static_cast<float>(centre.y())),
          cv::Size2f(static_cast<float>(1.4 * mark_radius), static_cast<float>(1.4 * mark_radius)),
          static_cast<float>(angle_deg));
      cv::Point2f vertices[4];
      square.points(vertices);
      std::vector<cv::Point> polygon;
      for (const cv::Point2f& v : vertices) polygon.push_back(to_big({v.x, v.y}));
      cv::fillPoly(big, std::vector<std::vector<cv::Point>>{polygon},
                   cv::Scalar(options.circle_grey), cv::LINE_AA, kShiftBits);
    }  // kind 3: a plain reflection
  }

  cv::Mat image;
  cv::resize(big, image, cv::Size(options.image_width, options.image_height), 0, 0, cv::INTER_AREA);
  cv::Mat image_float;
  image.convertTo(image_float, CV_32F);
  if (options.blur_sigma_px > 0.0) {
    cv::GaussianBlur(image_float, image_float, cv::Size(0, 0), options.blur_sigma_px);
  }
  if (options.noise_sigma_grey > 0.0) {
    for (int y = 0; y < image_float.rows; ++y) {
      float* row = image_float.ptr<float>(y);
      for (int x = 0; x < image_float.cols; ++x) {
        row[x] += static_cast<float>(options.noise_sigma_grey * normal(generator));
      }
    }
  }
  image_float.convertTo(rendered.image, CV_8U);  // rounds and saturates
  return rendered;
}

}  // namespace hnnstereo::calib
