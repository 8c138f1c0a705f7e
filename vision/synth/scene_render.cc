#include "vision/synth/scene_render.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

#include "common/atomic_file.h"
#include "vision/synth/board_render.h"
#include "vision/synth/circle_target_render.h"
#include "vision/synth/lens_model.h"
#include "common/image.h"

namespace hnnstereo::vision {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kEpsilonMm = 1e-6;

// ---- Procedural texture: value noise on an integer lattice, hashed (splitmix64). ----

std::uint64_t Mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double LatticeValue(std::int64_t ix, std::int64_t iy, std::uint64_t seed) {
  const std::uint64_t h = Mix(seed ^ Mix(static_cast<std::uint64_t>(ix) * 0x632be59bd9b4e019ULL ^
                                         static_cast<std::uint64_t>(iy)));
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);  // [0, 1)
}

double ValueNoise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3.0 - 2.0 * tx);
  ty = ty * ty * (3.0 - 2.0 * ty);
  const double v00 = LatticeValue(ix, iy, seed), v10 = LatticeValue(ix + 1, iy, seed);
  const double v01 = LatticeValue(ix, iy + 1, seed), v11 = LatticeValue(ix + 1, iy + 1, seed);
  return (v00 * (1 - tx) + v10 * tx) * (1 - ty) + (v01 * (1 - tx) + v11 * tx) * ty;
}

// Three octaves, result in [0, 1).
double FractalNoise(double x, double y, std::uint64_t seed) {
  return 0.5 * ValueNoise(x, y, seed) + 0.3 * ValueNoise(2.1 * x, 2.1 * y, seed + 1) +
         0.2 * ValueNoise(4.3 * x, 4.3 * y, seed + 2);
}

// ---- Geometry of the parts ----

struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;  // not normalised
};

enum class Surface { kNone, kTable, kTop, kSide };

struct Hit {
  double t = std::numeric_limits<double>::infinity();
  Surface surface = Surface::kNone;
  int object = -1;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d local = Eigen::Vector3d::Zero();  // hit point in the object's frame
};

Eigen::Matrix2d Rotation2D(double yaw_deg) {
  return Eigen::Rotation2Dd(yaw_deg * kPi / 180.0).toRotationMatrix();
}

// Intersection of `ray` with object `index` (nearest t > t_min), into `hit` when nearer;
// `object_from_world` is Rotation2D(object.yaw_deg).transpose().
void IntersectObject(const Ray& ray, const SceneObject& object,
                     const Eigen::Matrix2d& object_from_world, int index, double t_min, Hit* hit) {
  const Eigen::Vector2d o_xy = object_from_world * (ray.origin.head<2>() - object.centre_mm);
  const Eigen::Vector2d d_xy = object_from_world * ray.direction.head<2>();
  const Eigen::Vector3d o(o_xy.x(), o_xy.y(), ray.origin.z());
  const Eigen::Vector3d d(d_xy.x(), d_xy.y(), ray.direction.z());
  const double h = object.height_mm();
  auto take = [&](double t, Surface surface, const Eigen::Vector3d& local_normal) {
    if (t > t_min && t < hit->t) {
      hit->t = t;
      hit->surface = surface;
      hit->object = index;
      hit->local = o + t * d;
      const Eigen::Vector2d n_xy = object_from_world.transpose() * local_normal.head<2>();
      hit->normal = Eigen::Vector3d(n_xy.x(), n_xy.y(), local_normal.z());
    }
  };
  if (object.shape == SceneObject::Shape::kBox) {
    const Eigen::Vector3d lo(-0.5 * object.size_mm.x(), -0.5 * object.size_mm.y(), 0.0);
    const Eigen::Vector3d hi(0.5 * object.size_mm.x(), 0.5 * object.size_mm.y(), h);
    double t_enter = -std::numeric_limits<double>::infinity();
    double t_exit = std::numeric_limits<double>::infinity();
    int enter_axis = -1;
    double enter_sign = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(d[axis]) < 1e-15) {
        if (o[axis] < lo[axis] || o[axis] > hi[axis]) return;
        continue;
      }
      double t0 = (lo[axis] - o[axis]) / d[axis], t1 = (hi[axis] - o[axis]) / d[axis];
      double sign = -1.0;  // entering through the low face
      if (t0 > t1) {
        std::swap(t0, t1);
        sign = 1.0;
      }
      if (t0 > t_enter) {
        t_enter = t0;
        enter_axis = axis;
        enter_sign = sign;
      }
      t_exit = std::min(t_exit, t1);
    }
    if (enter_axis < 0 || t_enter > t_exit) return;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    normal[enter_axis] = enter_sign;
    take(t_enter, enter_axis == 2 && enter_sign > 0 ? Surface::kTop : Surface::kSide, normal);
  } else {
    const double r = 0.5 * object.size_mm.x();
    if (std::abs(d.z()) > 1e-15) {  // the top cap
      const double t = (h - o.z()) / d.z();
      const Eigen::Vector3d p = o + t * d;
      if (p.head<2>().squaredNorm() <= r * r) take(t, Surface::kTop, Eigen::Vector3d::UnitZ());
    }
    const double a = d.head<2>().squaredNorm();
    if (a > 1e-15) {  // the mantle, outside only
      const double b = 2.0 * o.head<2>().dot(d.head<2>());
      const double c = o.head<2>().squaredNorm() - r * r;
      const double discriminant = b * b - 4 * a * c;
      if (discriminant >= 0.0) {
        const double t = (-b - std::sqrt(discriminant)) / (2 * a);
        const Eigen::Vector3d p = o + t * d;
        if (p.z() >= 0.0 && p.z() <= h) {
          take(t, Surface::kSide, Eigen::Vector3d(p.x() / r, p.y() / r, 0.0));
        }
      }
    }
  }
}

// The objects as rays meet them: each one's rotation, computed once, and a bounding sphere.
// A ray whose line passes the sphere by more than its 1 mm margin cannot hit the object, so
// skipping it changes no hit; the others get the exact intersection (IntersectObject).
class RayCaster {
 public:
  explicit RayCaster(const std::vector<SceneObject>& objects) : objects_(objects) {
    for (const SceneObject& object : objects) {
      const double half_height = 0.5 * object.height_mm();
      const double half_footprint = object.shape == SceneObject::Shape::kBox
                                        ? 0.5 * object.size_mm.head<2>().norm()
                                        : 0.5 * object.size_mm.x();
      const double radius = std::hypot(half_footprint, half_height) + 1.0;
      bounds_.push_back({Rotation2D(object.yaw_deg).transpose(),
                         Eigen::Vector3d(object.centre_mm.x(), object.centre_mm.y(), half_height),
                         radius * radius});
    }
  }
  const std::vector<SceneObject>& objects() const { return objects_; }
  // The nearest hit with t > t_min: an object or the table z = 0.
  Hit Cast(const Ray& ray, double t_min) const;

 private:
  struct Bound {
    Eigen::Matrix2d object_from_world;
    Eigen::Vector3d centre;  // of the bounding sphere (mm)
    double radius_squared;   // mm^2, margin included
  };
  const std::vector<SceneObject>& objects_;
  std::vector<Bound> bounds_;
};

Hit RayCaster::Cast(const Ray& ray, double t_min) const {
  Hit hit;
  const double dd = ray.direction.squaredNorm();
  for (int i = 0; i < static_cast<int>(objects_.size()); ++i) {
    const Bound& bound = bounds_[static_cast<std::size_t>(i)];
    const Eigen::Vector3d w = bound.centre - ray.origin;
    const double wd = w.dot(ray.direction);
    if (w.squaredNorm() - wd * wd / dd > bound.radius_squared) continue;  // the line misses
    IntersectObject(ray, objects_[static_cast<std::size_t>(i)], bound.object_from_world, i, t_min,
                    &hit);
  }
  if (hit.surface == Surface::kNone) hit.object = -1;
  if (ray.direction.z() < 0.0) {  // the table z = 0
    const double t = -ray.origin.z() / ray.direction.z();
    if (t > t_min && t < hit.t) {
      hit.t = t;
      hit.surface = Surface::kTable;
      hit.object = -1;
      hit.normal = Eigen::Vector3d::UnitZ();
    }
  }
  return hit;
}

// An engraved mark on a top face (object frame, mm): a dark disc or a scratch.
struct Mark {
  Eigen::Vector2d centre;
  Eigen::Vector2d direction;  // unit; scratches only
  double radius;              // disc radius or half length
  bool scratch;
};

std::vector<Mark> MarksOf(const SceneObject& object) {
  std::mt19937_64 generator(object.texture_seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Mark> marks;
  const double half_x = 0.5 * object.size_mm.x(), half_y = 0.5 * object.size_mm.y();
  const int count = 4 + static_cast<int>(uniform(generator) * 5.0);
  for (int k = 0; k < count; ++k) {
    Mark mark;
    mark.scratch = uniform(generator) < 0.4;
    mark.radius = mark.scratch ? 3.0 + 5.0 * uniform(generator) : 1.2 + 2.0 * uniform(generator);
    const double angle = kPi * uniform(generator);
    mark.direction = Eigen::Vector2d(std::cos(angle), std::sin(angle));
    const double keep_x = std::max(0.0, half_x - mark.radius - 3.0);
    const double keep_y = std::max(0.0, half_y - mark.radius - 3.0);
    mark.centre = Eigen::Vector2d((2 * uniform(generator) - 1) * keep_x,
                                  (2 * uniform(generator) - 1) * keep_y);
    if (object.shape == SceneObject::Shape::kCylinder) mark.centre *= 0.6;
    marks.push_back(mark);
  }
  return marks;
}

struct Lighting {
  Eigen::Vector3d to_light = Eigen::Vector3d(0.35, -0.25, 1.0).normalized();
  double ambient = 0.28;
  double diffuse = 0.72;
};

// Radiance (0..~1.2) at a hit seen from `eye`.
double Shade(const Hit& hit, const Ray& ray, const RayCaster& caster,
             const std::vector<std::vector<Mark>>& marks, const SceneRenderOptions& options,
             const Lighting& light) {
  if (hit.surface == Surface::kNone) return 0.0;
  const Eigen::Vector3d point = ray.origin + hit.t * ray.direction;
  // Shadow: anything between the point and the light.
  const Ray shadow_ray{point + 1e-3 * hit.normal, light.to_light};
  const bool lit = caster.Cast(shadow_ray, 1e-6).object < 0;
  const double n_dot_l = std::max(0.0, hit.normal.dot(light.to_light));
  const double shading = light.ambient + light.diffuse * n_dot_l * (lit ? 1.0 : 0.0);
  if (hit.surface == Surface::kTable) {
    // Dark, textured, dusty: stains, grain, and bright dust specks (world-anchored).
    const std::uint64_t seed = Mix(options.seed * 7919 + 11);
    double albedo = options.table_albedo *
                    (0.55 + 0.5 * FractalNoise(point.x() / 9.0, point.y() / 9.0, seed) +
                     0.35 * ValueNoise(point.x() / 1.3, point.y() / 1.3, seed + 5));
    const double cell_mm = 4.0;
    const double cx = std::floor(point.x() / cell_mm), cy = std::floor(point.y() / cell_mm);
    const auto ix = static_cast<std::int64_t>(cx), iy = static_cast<std::int64_t>(cy);
    if (LatticeValue(ix, iy, seed + 9) < 0.05) {  // a speck of dust in this cell
      const Eigen::Vector2d speck((cx + 0.2 + 0.6 * LatticeValue(ix, iy, seed + 10)) * cell_mm,
                                  (cy + 0.2 + 0.6 * LatticeValue(ix, iy, seed + 11)) * cell_mm);
      const double radius = 0.35 + 0.5 * LatticeValue(ix, iy, seed + 12);
      if ((point.head<2>() - speck).norm() < radius) albedo += 0.12;
    }
    return albedo * shading;
  }
  const SceneObject& object = caster.objects()[static_cast<std::size_t>(hit.object)];
  const std::uint64_t seed = Mix(object.texture_seed);
  double albedo = object.albedo;
  if (hit.surface == Surface::kTop && options.top_texture == TopTexture::kPlain) {
    // Uniform metal: only the outline and the highlight.
  } else if (hit.surface == Surface::kTop) {
    // Brushed metal along the part's x axis, then the engraved marks.
    albedo *= 0.8 + 0.3 * FractalNoise(hit.local.x() / 12.0, hit.local.y() / 0.9, seed);
    for (const Mark& mark : marks[static_cast<std::size_t>(hit.object)]) {
      const Eigen::Vector2d offset = hit.local.head<2>() - mark.centre;
      if (mark.scratch) {
        const double along = offset.dot(mark.direction);
        const double across = std::abs(offset.x() * mark.direction.y() -
                                       offset.y() * mark.direction.x());
        if (std::abs(along) < mark.radius && across < 0.6) albedo *= 0.3;
      } else if (offset.norm() < mark.radius) {
        albedo *= 0.25;
      }
    }
  } else {
    const double around = hit.local.x() + hit.local.y();
    albedo *= 0.75 + 0.35 * FractalNoise(around / 2.0, hit.local.z() / 10.0, seed + 3);
  }
  // Metal: a Blinn-Phong highlight (view dependent, so the two images differ there).
  const Eigen::Vector3d to_eye = (-ray.direction).normalized();
  const Eigen::Vector3d half_vector = (to_eye + light.to_light).normalized();
  const double specular =
      lit ? 0.35 * std::pow(std::max(0.0, hit.normal.dot(half_vector)), 40.0) : 0.0;
  return albedo * shading + specular;
}

bool InsideImage(const calib::ProjectionMatrix& P, const Eigen::Vector3d& point, int width,
                 int height, int margin) {
  const Eigen::Vector3d x = P * point.homogeneous();
  if (!(x.z() > 0.0)) return false;
  const Eigen::Vector2d pixel = x.hnormalized();
  return pixel.x() >= margin && pixel.y() >= margin && pixel.x() <= width - 1 - margin &&
         pixel.y() <= height - 1 - margin;
}

// Separating-axis test on footprints: true when they are at least `gap` apart along some axis.
bool FootprintsApart(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b,
                     double gap) {
  for (const auto* polygon : {&a, &b}) {
    for (std::size_t i = 0; i < polygon->size(); ++i) {
      const Eigen::Vector2d edge = (*polygon)[(i + 1) % polygon->size()] - (*polygon)[i];
      const Eigen::Vector2d axis = Eigen::Vector2d(edge.y(), -edge.x()).normalized();
      double a_min = 1e300, a_max = -1e300, b_min = 1e300, b_max = -1e300;
      for (const auto& p : a) {
        a_min = std::min(a_min, p.dot(axis));
        a_max = std::max(a_max, p.dot(axis));
      }
      for (const auto& p : b) {
        b_min = std::min(b_min, p.dot(axis));
        b_max = std::max(b_max, p.dot(axis));
      }
      if (b_min - a_max >= gap || a_min - b_max >= gap) return true;
    }
  }
  return false;
}

// Fraction of the top face of objects[index] that camera centre `eye` sees unoccluded.
double TopVisibility(const std::vector<SceneObject>& objects, std::size_t index,
                     const Eigen::Vector3d& eye) {
  const SceneObject& object = objects[index];
  const Eigen::Matrix2d world_from_object = Rotation2D(object.yaw_deg);
  const RayCaster caster(objects);
  int seen = 0, total = 0;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      Eigen::Vector2d local(0.8 * (i / 4.0 - 0.5) * object.size_mm.x(),
                            0.8 * (j / 4.0 - 0.5) * object.size_mm.y());
      if (object.shape == SceneObject::Shape::kCylinder &&
          local.norm() > 0.4 * object.size_mm.x()) {
        continue;
      }
      const Eigen::Vector2d xy = object.centre_mm + world_from_object * local;
      const Eigen::Vector3d target(xy.x(), xy.y(), object.height_mm());
      const Ray ray{eye, target - eye};  // t = 1 at the target
      const Hit hit = caster.Cast(ray, 1e-9);
      ++total;
      if (hit.object == static_cast<int>(index) && std::abs(hit.t - 1.0) < 1e-6) ++seen;
    }
  }
  return total > 0 ? static_cast<double>(seen) / total : 0.0;
}

double NormalisedYaw(double yaw_deg) {
  double yaw = std::fmod(yaw_deg, 180.0);
  if (yaw <= -90.0) yaw += 180.0;
  if (yaw > 90.0) yaw -= 180.0;
  return yaw;
}

}  // namespace

std::vector<Eigen::Vector2d> SceneObject::Footprint() const {
  std::vector<Eigen::Vector2d> outline;
  const Eigen::Matrix2d world_from_object = Rotation2D(yaw_deg);
  if (shape == Shape::kBox) {
    const double hx = 0.5 * size_mm.x(), hy = 0.5 * size_mm.y();
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(-hx, -hy), Eigen::Vector2d(hx, -hy),
                                          Eigen::Vector2d(hx, hy), Eigen::Vector2d(-hx, hy)}) {
      outline.push_back(centre_mm + world_from_object * corner);
    }
  } else {
    // A polygon around the circle (circumscribed, so the SAT gap is conservative).
    constexpr int kVertices = 32;
    const double r = 0.5 * size_mm.x() / std::cos(kPi / kVertices);
    for (int k = 0; k < kVertices; ++k) {
      const double angle = 2.0 * kPi * k / kVertices;
      outline.push_back(centre_mm + r * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
    }
  }
  return outline;
}

std::string PickCellCameraOptions::Check() const {
  std::ostringstream out;
  if (image_width < 64 || image_height < 64) {
    out << "camera image size must be at least 64x64 (is " << image_width << "x" << image_height
        << ")";
  } else if (!(focal_px > 0.0)) {
    out << "PickCellCameraOptions.focal_px must be positive (is " << focal_px << ")";
  } else if (!(left_centre_mm.z() > 0.0 && right_centre_mm.z() > 0.0)) {
    out << "both cameras must be above the table (z > 0)";
  } else {
    out << CheckDistortion(distortion);
  }
  return out.str();
}

void PickCellCameraOptions::SetResolution(int width, int height) {
  if (width < 64 || height < 64 || width > 8192 || height > 8192) {
    throw std::invalid_argument("the image size must be 64-8192 px each way (is " +
                                std::to_string(width) + "x" + std::to_string(height) + ")");
  }
  const double scale = static_cast<double>(width) / image_width;
  focal_px *= scale;
  right_principal_offset_px *= scale;
  image_width = width;
  image_height = height;
}

std::pair<int, int> ParseResolution(const std::string& option, const std::string& text) {
  int width = 0, height = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> width >> x >> height) || (x != 'x' && x != 'X') || !(in >> std::ws).eof()) {
    throw std::invalid_argument(option + " must be WIDTHxHEIGHT in pixels, e.g. 1280x1024 (got '" +
                                text + "')");
  }
  return {width, height};
}

std::string SceneRenderOptions::Check() const {
  std::ostringstream out;
  if (const std::string camera_problem = cameras.Check(); !camera_problem.empty()) {
    out << camera_problem;
  } else if (num_objects < 0 || num_objects > 30) {
    out << "number of objects must be in [0, 30] (is " << num_objects << ")";
  } else if (!(min_height_mm > 0.0 && min_height_mm <= max_height_mm)) {
    out << "object heights need 0 < min_height_mm <= max_height_mm (are " << min_height_mm << ", "
        << max_height_mm << ")";
  } else if (!(max_height_mm < 0.8 * std::min(cameras.left_centre_mm.z(),
                                               cameras.right_centre_mm.z()))) {
    out << "max_height_mm " << max_height_mm << " is too close to the cameras";
  } else if (!(min_side_mm > 2.0 && min_side_mm <= max_side_mm)) {
    out << "object sides need 2 < min_side_mm <= max_side_mm (are " << min_side_mm << ", "
        << max_side_mm << ")";
  } else if (!(min_aspect >= 1.0 && max_side_mm >= min_aspect * min_side_mm)) {
    out << "min_aspect must be >= 1 and max_side_mm >= min_aspect * min_side_mm (are "
        << min_aspect << ", " << max_side_mm << ", " << min_side_mm << ")";
  } else if (!(cylinder_fraction >= 0.0 && cylinder_fraction <= 1.0)) {
    out << "cylinder_fraction must be in [0, 1] (is " << cylinder_fraction << ")";
  } else if (min_gap_mm < 0.0) {
    out << "min_gap_mm must be >= 0 (is " << min_gap_mm << ")";
  } else if (supersampling < 1 || supersampling > 8) {
    out << "supersampling must be in [1, 8] (is " << supersampling << ")";
  } else if (!(blur_sigma_px >= 0.0 && blur_sigma_px <= 10.0) ||
             !(noise_sigma_grey >= 0.0 && noise_sigma_grey <= 100.0)) {
    out << "blur must be in [0, 10] px and noise in [0, 100] grey levels (are " << blur_sigma_px
        << ", " << noise_sigma_grey << ")";
  } else if (!(min_brightness > 0.0 && min_brightness <= max_brightness && max_brightness <= 4.0)) {
    out << "brightness needs 0 < min_brightness <= max_brightness <= 4 (are " << min_brightness
        << ", " << max_brightness << ")";
  } else if (target_heights_mm.size() < 2) {
    out << "the calibration target needs at least two heights (has " << target_heights_mm.size()
        << ")";
  } else if (const std::string grid_problem = target_grid.Check(); !grid_problem.empty()) {
    out << grid_problem;
  } else if (const std::string board_problem = board.Check(); !board_problem.empty()) {
    out << board_problem;
  }
  return out.str();
}

calib::StereoCalibration PickCellCameras(const PickCellCameraOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  const Eigen::Vector2d principal(0.5 * (options.image_width - 1), 0.5 * (options.image_height - 1));
  calib::StereoCalibration cameras;
  // Slightly different lenses and aims, as two real cameras have.
  cameras.P1 = calib::LookAtCamera(options.focal_px, principal, options.left_centre_mm,
                                   options.work_centre_mm + Eigen::Vector3d(0, 8, 0),
                                   Eigen::Vector3d::UnitY());
  cameras.P2 = calib::LookAtCamera(options.focal_px * 1.01, principal + options.right_principal_offset_px,
                                   options.right_centre_mm,
                                   options.work_centre_mm + Eigen::Vector3d(3, -6, 0),
                                   Eigen::Vector3d::UnitY());
  cameras.image_width = options.image_width;
  cameras.image_height = options.image_height;
  cameras.DeriveFromProjections();
  if (!options.distortion.empty()) {
    // P then maps to undistorted pixels, as a calibration with K D R T does (calibration.md).
    calib::Intrinsics lens;
    lens.K1 = CameraMatrixOf(cameras.P1);
    lens.K2 = CameraMatrixOf(cameras.P2);
    lens.D1 = lens.D2 = options.distortion;
    Eigen::Matrix4d left_from_world = Eigen::Matrix4d::Identity(), right_from_world = left_from_world;
    left_from_world.topRows<3>() = lens.K1.inverse() * cameras.P1;
    right_from_world.topRows<3>() = lens.K2.inverse() * cameras.P2;
    const Eigen::Matrix4d right_from_left = right_from_world * left_from_world.inverse();
    lens.R = right_from_left.topLeftCorner<3, 3>();
    lens.T = right_from_left.block<3, 1>(0, 3);
    cameras.intrinsics = lens;
    cameras.world_frame = "table";
    cameras.world_from_left_camera = left_from_world.inverse();
  }
  return cameras;
}

cv::Mat RenderView(const calib::ProjectionMatrix& P, const std::vector<SceneObject>& objects,
                   const SceneRenderOptions& options, std::uint64_t noise_seed) {
  const int width = options.cameras.image_width, height = options.cameras.image_height;
  const Eigen::Matrix3d M = P.leftCols<3>();
  const Eigen::Matrix3d M_inverse = M.inverse();
  const Eigen::Vector3d centre = -M_inverse * P.col(3);
  std::vector<std::vector<Mark>> marks;
  for (const SceneObject& object : objects) marks.push_back(MarksOf(object));
  const double gain = SceneBrightness(options);
  const Lighting light;
  const RayCaster caster(objects);
  const int s = options.supersampling;
  const std::vector<double>& distortion = options.cameras.distortion;
  const Eigen::Matrix3d K = distortion.empty() ? Eigen::Matrix3d::Identity() : CameraMatrixOf(P);
  cv::Mat radiance(height, width, CV_32F);
  cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      float* out = radiance.ptr<float>(v);
      // With distortion, each sample's ideal pixel (its pinhole ray), a row at a time.
      std::vector<cv::Point2d> ideal;
      if (!distortion.empty()) {
        for (int u = 0; u < width; ++u) {
          for (int i = 0; i < s; ++i) {
            for (int j = 0; j < s; ++j) {
              ideal.emplace_back(u + (j + 0.5) / s - 0.5, v + (i + 0.5) / s - 0.5);
            }
          }
        }
        ideal = IdealPixels(ideal, K, distortion);
      }
      for (int u = 0; u < width; ++u) {
        double sum = 0.0;
        for (int i = 0; i < s; ++i) {
          for (int j = 0; j < s; ++j) {
            Eigen::Vector3d pixel(u + (j + 0.5) / s - 0.5, v + (i + 0.5) / s - 0.5, 1.0);
            if (!ideal.empty()) {
              const cv::Point2d& x = ideal[static_cast<std::size_t>((u * s + i) * s + j)];
              pixel = Eigen::Vector3d(x.x, x.y, 1.0);
            }
            const Ray ray{centre, M_inverse * pixel};
            sum += Shade(caster.Cast(ray, kEpsilonMm), ray, caster, marks, options, light);
          }
        }
        out[u] = static_cast<float>(255.0 * gain * sum / (s * s));
      }
    }
  });
  if (options.blur_sigma_px > 0.0) {
    cv::GaussianBlur(radiance, radiance, cv::Size(0, 0), options.blur_sigma_px);
  }
  std::mt19937_64 generator(noise_seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_sigma_grey));
  cv::Mat image(height, width, CV_8U);
  for (int v = 0; v < height; ++v) {
    const float* in = radiance.ptr<float>(v);
    auto* out = image.ptr<std::uint8_t>(v);
    for (int u = 0; u < width; ++u) {
      const float value = in[u] + (options.noise_sigma_grey > 0.0 ? noise(generator) : 0.0f);
      out[u] = cv::saturate_cast<std::uint8_t>(value);
    }
  }
  return image;
}

std::string_view TopTextureName(TopTexture texture) {
  return texture == TopTexture::kPlain ? "plain" : "random";
}

std::optional<TopTexture> ParseTopTexture(std::string_view name) {
  if (name == "plain") return TopTexture::kPlain;
  if (name == "random") return TopTexture::kRandom;
  return std::nullopt;
}

double SceneBrightness(const SceneRenderOptions& options) {
  if (options.min_brightness == options.max_brightness) return options.min_brightness;
  // Its own stream, so that a brightness range never changes which parts a seed draws.
  std::mt19937_64 generator(Mix(options.seed * 0x5851f42d4c957f2dULL + 17));
  std::uniform_real_distribution<double> uniform(options.min_brightness, options.max_brightness);
  return uniform(generator);
}

namespace {

// The parts of the scene, or nullopt when part *failed_part (0-based) of an asked-for count
// found no place in 4000 tries.
std::optional<std::vector<SceneObject>> TryPlaceObjects(const SceneRenderOptions& options,
                                                        const calib::StereoCalibration& cameras,
                                                        int* failed_part) {
  std::vector<SceneObject> objects;
  std::mt19937_64 generator(Mix(options.seed));
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const int count = options.num_objects > 0
                        ? options.num_objects
                        : 1 + static_cast<int>(std::min(8.0, std::floor(9.0 * uniform(generator))));
  const int width = options.cameras.image_width, height = options.cameras.image_height;
  const Eigen::Vector2d work_centre = options.cameras.work_centre_mm.head<2>();
  for (int k = 0; k < count; ++k) {
    bool placed = false;
    for (int attempt = 0; attempt < 4000 && !placed; ++attempt) {
      SceneObject object;
      object.shape = uniform(generator) < options.cylinder_fraction ? SceneObject::Shape::kCylinder
                                                                    : SceneObject::Shape::kBox;
      const double height_mm =
          options.min_height_mm + (options.max_height_mm - options.min_height_mm) * uniform(generator);
      const double side_range = options.max_side_mm - options.min_side_mm;
      if (object.shape == SceneObject::Shape::kBox) {
        // Width first, then a length at least min_aspect times longer (capped at max_side).
        const double widest = options.max_side_mm / options.min_aspect;
        const double width_mm = options.min_side_mm + (widest - options.min_side_mm) * uniform(generator);
        const double shortest_length = width_mm * options.min_aspect;
        const double length_mm =
            shortest_length + (options.max_side_mm - shortest_length) * uniform(generator);
        object.size_mm = Eigen::Vector3d(length_mm, width_mm, height_mm);
        object.yaw_deg = NormalisedYaw(-90.0 + 180.0 * uniform(generator));
      } else {
        const double diameter = options.min_side_mm + side_range * uniform(generator);
        object.size_mm = Eigen::Vector3d(diameter, diameter, height_mm);
        object.yaw_deg = 0.0;
      }
      object.centre_mm =
          work_centre + Eigen::Vector2d((2 * uniform(generator) - 1) * options.work_half_width_mm,
                                        (2 * uniform(generator) - 1) * options.work_half_depth_mm);
      object.albedo = 0.5 + 0.25 * uniform(generator);
      object.texture_seed = Mix(options.seed * 1000003 + static_cast<std::uint64_t>(k) * 7 +
                                static_cast<std::uint64_t>(attempt));
      const std::vector<Eigen::Vector2d> footprint = object.Footprint();
      bool ok = true;
      for (const SceneObject& other : objects) {
        ok = ok && FootprintsApart(footprint, other.Footprint(), options.min_gap_mm);
      }
      for (const Eigen::Vector2d& corner : footprint) {
        for (double z : {0.0, object.height_mm()}) {
          for (const auto* P : {&cameras.P1, &cameras.P2}) {
            ok = ok && InsideImage(*P, Eigen::Vector3d(corner.x(), corner.y(), z), width, height,
                                   options.image_margin_px);
          }
        }
      }
      if (!ok) continue;
      std::vector<SceneObject> trial = objects;
      trial.push_back(object);
      for (std::size_t i = 0; i < trial.size() && ok; ++i) {
        ok = TopVisibility(trial, i, cameras.C1) >= options.min_top_visibility &&
             TopVisibility(trial, i, cameras.C2) >= options.min_top_visibility;
      }
      if (!ok) continue;
      objects = std::move(trial);
      placed = true;
    }
    // A count the seed drew is a wish: the scene holds the parts that fit (scene_render_test,
    // ASeedDrawingMorePartsThanFitGetsThoseThatFit). A count the caller asked for is a contract.
    if (!placed && options.num_objects == 0) break;
    if (!placed) {
      *failed_part = k;
      return std::nullopt;
    }
  }
  std::stable_sort(objects.begin(), objects.end(), [](const SceneObject& a, const SceneObject& b) {
    return a.height_mm() > b.height_mm();
  });
  return objects;
}

// TryPlaceObjects; when an asked-for count does not fit and options.shrink_to_fit, again with
// the top-face sides and the gap scaled by kShrinkStep per try (a scene that fits at the sizes
// asked is never changed). *scale receives the factor used.
std::vector<SceneObject> PlaceObjects(const SceneRenderOptions& options,
                                      const calib::StereoCalibration& cameras,
                                      double* scale = nullptr) {
  constexpr double kShrinkStep = 0.85;
  constexpr int kShrinkTries = 8;  // down to 0.85^8 = 0.27 of the sizes asked
  SceneRenderOptions scaled = options;
  double factor = 1.0;
  int failed_part = 0;
  for (int shrink = 0;; ++shrink) {
    if (auto objects = TryPlaceObjects(scaled, cameras, &failed_part)) {
      if (scale != nullptr) *scale = factor;
      return *std::move(objects);
    }
    if (!options.shrink_to_fit || shrink == kShrinkTries) break;
    factor *= kShrinkStep;
    scaled.min_side_mm = options.min_side_mm * factor;
    scaled.max_side_mm = options.max_side_mm * factor;
    scaled.min_gap_mm = options.min_gap_mm * factor;
  }
  throw std::invalid_argument("cannot place part " + std::to_string(failed_part + 1) + " of " +
                              std::to_string(options.num_objects) +
                              " in the work area (too many parts for --size-range and --min-gap)");
}

}  // namespace

std::vector<SceneObject> PlaceSceneObjects(const SceneRenderOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  return PlaceObjects(options, PickCellCameras(options.cameras));
}

RenderedScene RenderScene(const SceneRenderOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  RenderedScene scene;
  scene.seed = options.seed;
  scene.cameras = PickCellCameras(options.cameras);
  scene.objects = PlaceObjects(options, scene.cameras, &scene.size_scale);
  scene.left = RenderView(scene.cameras.P1, scene.objects, options, Mix(options.seed * 2 + 1));
  scene.right = RenderView(scene.cameras.P2, scene.objects, options, Mix(options.seed * 2 + 2));
  return scene;
}

std::vector<calib::BoardView> BoardViewPoses(const SceneRenderOptions& options) {
  const calib::ChessboardGeometry& board = options.board;
  const Eigen::Vector3d board_centre(0.5 * (board.cols - 1) * board.square_mm,
                                     0.5 * (board.rows - 1) * board.square_mm, 0.0);
  // Centre offset from the work centre (mm), yaw, tilt about the board's x and y (deg).
  struct Pose {
    Eigen::Vector3d offset;
    double yaw_deg, tilt_x_deg, tilt_y_deg;
    bool on_table;
  };
  const std::vector<Pose> poses = {
      {{0, 0, 0}, 4, 0, 0, true},           {{-50, -30, 40}, 0, -20, 20, false},
      {{-50, 30, 40}, 0, 20, 20, false},    {{50, -30, 40}, 0, -20, -20, false},
      {{50, 30, 40}, 0, 20, -20, false},    {{0, 0, 100}, 0, 25, 0, false},
      {{0, 0, 100}, 0, -25, 0, false},      {{0, 0, 100}, 0, 0, 25, false},
      {{0, 0, 100}, 0, 0, -25, false},      {{0, 0, 150}, 0, 20, 0, false},
      {{0, -10, 150}, 0, -15, 0, false},    {{0, 0, 60}, 15, 10, -10, false},
      // Near the images' corners, where distortion is largest; some only one camera sees whole.
      {{-72, 62, 30}, 0, 0, 0, false},      {{72, 62, 30}, 0, 0, 0, false},
      {{-72, -55, 30}, 0, 0, 0, false},     {{72, -55, 30}, 0, 0, 0, false},
      {{-72, -68, 30}, 0, 0, 0, false},     {{72, -68, 30}, 0, 0, 0, false},
      {{-72, 52, 30}, 0, 0, 0, false},      {{72, 52, 30}, 0, 0, 0, false}};
  std::vector<calib::BoardView> views;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Pose& pose = poses[i];
    Eigen::Affine3d world_from_board =
        Eigen::Translation3d(options.cameras.work_centre_mm + pose.offset) *
        Eigen::AngleAxisd(pose.yaw_deg * kPi / 180.0, Eigen::Vector3d::UnitZ()) *
        Eigen::AngleAxisd(pose.tilt_x_deg * kPi / 180.0, Eigen::Vector3d::UnitX()) *
        Eigen::AngleAxisd(pose.tilt_y_deg * kPi / 180.0, Eigen::Vector3d::UnitY()) *
        Eigen::Translation3d(-board_centre);
    calib::BoardView view;
    view.world_from_board = world_from_board.matrix();
    view.on_table = pose.on_table;
    view.left_image = "board_left_" + std::to_string(i) + ".png";
    view.right_image = "board_right_" + std::to_string(i) + ".png";
    views.push_back(view);
  }
  return views;
}

namespace {

// The board views of target/ (BoardViewPoses) into target->board and its images.
void RenderBoardViews(const calib::StereoCalibration& cameras, const SceneRenderOptions& options,
                      RenderedTarget* target) {
  target->board.board = options.board;
  target->board.views = BoardViewPoses(options);
  BoardRenderOptions render;
  render.image_width = options.cameras.image_width;
  render.image_height = options.cameras.image_height;
  render.blur_sigma_px = std::max(0.5, options.blur_sigma_px);
  render.noise_sigma_grey = options.noise_sigma_grey;
  render.distortion = options.cameras.distortion;
  for (std::size_t i = 0; i < target->board.views.size(); ++i) {
    const calib::BoardView& view = target->board.views[i];
    render.random_seed = Mix(options.seed * 100 + 50 + i * 2);
    const RenderedBoard left = RenderChessboard(cameras.P1, view.world_from_board, options.board,
                                                render);
    render.random_seed = Mix(options.seed * 100 + 51 + i * 2);
    const RenderedBoard right = RenderChessboard(cameras.P2, view.world_from_board, options.board,
                                                 render);
    if (!left.fully_visible && !right.fully_visible) {
      throw std::invalid_argument("the calibration board of view " + std::to_string(i) +
                                  " is not fully visible in either image");
    }
    target->board_left_images.push_back(left.image);
    target->board_right_images.push_back(right.image);
  }
}

}  // namespace

RenderedTarget RenderTargetPlacements(const calib::StereoCalibration& cameras,
                                      const SceneRenderOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  // Offsets and yaws vary per placement so that the points fill the work volume.
  const std::vector<Eigen::Vector2d> offsets = {{0, 0}, {-30, 15}, {30, -15}, {-25, -12}, {25, 12}};
  const std::vector<double> yaws = {0.0, 8.0, -6.0, 12.0, -10.0};
  const calib::CircleGridGeometry& grid = options.target_grid;
  calib::CircleTargetRenderOptions render;
  render.image_width = options.cameras.image_width;
  render.image_height = options.cameras.image_height;
  render.blur_sigma_px = std::max(0.5, options.blur_sigma_px);
  render.noise_sigma_grey = options.noise_sigma_grey;
  RenderedTarget target;
  target.description.grid = grid;
  target.description.dark_circles = true;
  for (std::size_t h = 0; h < options.target_heights_mm.size(); ++h) {
    const double yaw = yaws[h % yaws.size()];
    const Eigen::Vector3d centre =
        options.cameras.work_centre_mm +
        Eigen::Vector3d(offsets[h % offsets.size()].x(), offsets[h % offsets.size()].y(),
                        options.target_heights_mm[h]);
    const Eigen::Vector3d half_extent(0.5 * (grid.cols - 1) * grid.pitch_mm,
                                      0.5 * (grid.rows - 1) * grid.pitch_mm, 0.0);
    const Eigen::Matrix4d at_centre = calib::WorldFromTargetFlat(centre, yaw);
    const Eigen::Vector3d origin = (at_centre * (-half_extent).homogeneous()).hnormalized();
    calib::TargetPlacement placement;
    placement.world_from_target = calib::WorldFromTargetFlat(origin, yaw);
    placement.left_image = "left_" + std::to_string(h) + ".png";
    placement.right_image = "right_" + std::to_string(h) + ".png";
    render.random_seed = Mix(options.seed * 100 + h * 2);
    const calib::RenderedCircleTarget left =
        calib::RenderCircleTarget(cameras.P1, placement.world_from_target, grid, render);
    render.random_seed = Mix(options.seed * 100 + h * 2 + 1);
    const calib::RenderedCircleTarget right =
        calib::RenderCircleTarget(cameras.P2, placement.world_from_target, grid, render);
    if (!left.fully_visible || !right.fully_visible) {
      throw std::invalid_argument("the calibration target at height " +
                                  std::to_string(options.target_heights_mm[h]) +
                                  " mm is not fully visible in both images");
    }
    // A circle plate is drawn as a pinhole image, then resampled through the lens.
    target.left_images.push_back(
        DistortIdealImage(left.image, CameraMatrixOf(cameras.P1), options.cameras.distortion));
    target.right_images.push_back(
        DistortIdealImage(right.image, CameraMatrixOf(cameras.P2), options.cameras.distortion));
    target.description.placements.push_back(placement);
  }
  RenderBoardViews(cameras, options, &target);
  return target;
}

nlohmann::json TruthJson(const RenderedScene& scene) {
  nlohmann::json objects = nlohmann::json::array();
  int id = 1;
  for (const SceneObject& object : scene.objects) {
    objects.push_back({{"id", id++},
                       {"centroid", {object.centre_mm.x(), object.centre_mm.y(), object.height_mm()}},
                       {"height", object.height_mm()},
                       {"yaw_deg", object.yaw_deg},
                       {"points", 0},
                       {"shape", object.ShapeName()},
                       {"size", {object.size_mm.x(), object.size_mm.y(), object.size_mm.z()}}});
  }
  return {{"units", "mm"}, {"seed", scene.seed}, {"objects", objects}};
}

std::vector<SceneObject> LoadTruthObjects(const std::string& truth_json_path) {
  std::ifstream input(truth_json_path);
  if (!input) throw std::runtime_error("truth file '" + truth_json_path + "' cannot be read");
  std::vector<SceneObject> objects;
  try {
    const nlohmann::json truth = nlohmann::json::parse(input);
    for (const nlohmann::json& entry : truth.at("objects")) {
      SceneObject object;
      const std::string shape = entry.at("shape").get<std::string>();
      if (shape != "box" && shape != "cylinder") {
        throw std::runtime_error("unknown shape '" + shape + "'");
      }
      object.shape = shape == "box" ? SceneObject::Shape::kBox : SceneObject::Shape::kCylinder;
      const auto centroid = entry.at("centroid").get<std::vector<double>>();
      const auto size = entry.at("size").get<std::vector<double>>();
      if (centroid.size() != 3 || size.size() != 3) throw std::runtime_error("bad centroid/size");
      object.centre_mm = Eigen::Vector2d(centroid[0], centroid[1]);
      object.size_mm = Eigen::Vector3d(size[0], size[1], size[2]);
      object.yaw_deg = entry.at("yaw_deg").get<double>();
      objects.push_back(object);
    }
  } catch (const std::exception& error) {
    throw std::runtime_error("truth file '" + truth_json_path + "' is invalid: " + error.what());
  }
  return objects;
}

void WriteSceneDirectory(const RenderedScene& scene, const RenderedTarget& target,
                         const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::create_directories(fs::path(dir) / "target", error);
  if (error) throw std::runtime_error("cannot create folder '" + dir + "/target': " + error.message());
  WritePngAtomically(dir + "/left.png", scene.left);
  WritePngAtomically(dir + "/right.png", scene.right);
  calib::SaveCalibration(scene.cameras, dir + "/calib.yml");
  calib::WriteFileAtomically(dir + "/truth.json", TruthJson(scene).dump(2) + "\n");
  for (std::size_t h = 0; h < target.description.placements.size(); ++h) {
    WritePngAtomically(dir + "/target/" + target.description.placements[h].left_image,
                       target.left_images[h]);
    WritePngAtomically(dir + "/target/" + target.description.placements[h].right_image,
                       target.right_images[h]);
  }
  for (std::size_t i = 0; i < target.board.views.size(); ++i) {
    WritePngAtomically(dir + "/target/" + target.board.views[i].left_image,
                       target.board_left_images[i]);
    WritePngAtomically(dir + "/target/" + target.board.views[i].right_image,
                       target.board_right_images[i]);
  }
  calib::SaveTargetDescription(target.description, dir + "/target/target.yml",
                               [&](cv::FileStorage* storage) {
                                 if (!target.board.views.empty()) {
                                   calib::WriteBoardTarget(target.board, storage);
                                 }
                               });
}

}  // namespace hnnstereo::vision
