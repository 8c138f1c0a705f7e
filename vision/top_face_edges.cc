#include "vision/top_face_edges.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

// The rectangle as centre, unit axes and half extents: axis 0 along its length, axis 1 across.
struct Frame {
  Eigen::Vector2d centre;
  Eigen::Vector2d axis[2];
  double half[2];
};

Frame FrameOf(const Rectangle2D& r) {
  const double yaw = r.yaw_deg * std::numbers::pi / 180.0;
  Frame f;
  f.centre = r.centre;
  f.axis[0] = Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
  f.axis[1] = Eigen::Vector2d(-f.axis[0].y(), f.axis[0].x());
  f.half[0] = 0.5 * r.length;
  f.half[1] = 0.5 * r.width;
  return f;
}

// Side k of a frame: axis k / 2, sign + for even k.
struct Side {
  int axis;
  double sign;
};
Side SideOf(int k) { return {k / 2, k % 2 == 0 ? 1.0 : -1.0}; }

// The frame with side k moved outward by e (mm).
Frame Extended(Frame f, int k, double e) {
  const Side s = SideOf(k);
  f.half[s.axis] += 0.5 * e;
  f.centre += s.sign * 0.5 * e * f.axis[s.axis];
  return f;
}

class EdgeProbe {
 public:
  EdgeProbe(const Eigen::Matrix<double, 3, 4>& P, const cv::Mat& gx, const cv::Mat& gy,
            double height, double min_gradient)
      : P_(P), gx_(gx), gy_(gy), height_(height), min_gradient_(min_gradient) {}

  bool Project(const Eigen::Vector2d& xy, Eigen::Vector2d* uv) const {
    const Eigen::Vector3d x = P_ * Eigen::Vector4d(xy.x(), xy.y(), height_, 1.0);
    if (!(x.z() > 0.0)) return false;
    *uv = x.head<2>() / x.z();
    return uv->allFinite();
  }

  // Fraction of samples every `step` mm on the segment a-b (world, at the height) where the
  // image gradient across the segment's image reaches the threshold within 1 px across it.
  // `count` gets the number of samples.
  // Mean image gradient across the segment a-b (world, at the height) at its samples, no
  // tolerance: peaks on the edge's line.
  double Strength(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double step) const {
    const int n = static_cast<int>(std::floor((b - a).norm() / step)) + 1;
    Eigen::Vector2d ua, ub;
    if (!Project(a, &ua) || !Project(b, &ub) || (ub - ua).norm() <= 0.0) return 0.0;
    const Eigen::Vector2d t = (ub - ua).normalized();
    const Eigen::Vector2d normal(-t.y(), t.x());
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d xy = a + (b - a) * (n == 1 ? 0.5 : static_cast<double>(i) / (n - 1));
      Eigen::Vector2d uv;
      if (!Project(xy, &uv)) continue;
      const int u = static_cast<int>(std::lround(uv.x()));
      const int v = static_cast<int>(std::lround(uv.y()));
      if (u < 0 || v < 0 || u >= gx_.cols || v >= gx_.rows) continue;
      sum += std::abs(gx_.at<float>(v, u) * normal.x() + gy_.at<float>(v, u) * normal.y());
    }
    return sum / n;
  }

  double Support(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double step, int* count) const {
    const double length = (b - a).norm();
    const int n = static_cast<int>(std::floor(length / step)) + 1;
    *count = 0;
    if (length <= 0.0) return 0.0;
    Eigen::Vector2d ua, ub;
    if (!Project(a, &ua) || !Project(b, &ub) || (ub - ua).norm() <= 0.0) return 0.0;
    const Eigen::Vector2d t = (ub - ua).normalized();
    const Eigen::Vector2d normal(-t.y(), t.x());
    int supported = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d xy = a + (b - a) * (n == 1 ? 0.5 : static_cast<double>(i) / (n - 1));
      Eigen::Vector2d uv;
      ++*count;
      if (!Project(xy, &uv)) continue;
      for (int o = -1; o <= 1; ++o) {
        const int u = static_cast<int>(std::lround(uv.x() + o * normal.x()));
        const int v = static_cast<int>(std::lround(uv.y() + o * normal.y()));
        if (u < 0 || v < 0 || u >= gx_.cols || v >= gx_.rows) continue;
        const double across =
            std::abs(gx_.at<float>(v, u) * normal.x() + gy_.at<float>(v, u) * normal.y());
        if (across >= min_gradient_) {
          ++supported;
          break;
        }
      }
    }
    return static_cast<double>(supported) / n;
  }

 private:
  const Eigen::Matrix<double, 3, 4>& P_;
  const cv::Mat& gx_;
  const cv::Mat& gy_;
  double height_;
  double min_gradient_;
};

// Edge support of side k of frame f, without the corner margins.
double SideSupport(const EdgeProbe& probe, const Frame& f, int k, const TopFaceEdgeOptions& o) {
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  const double reach = f.half[other] - o.corner_margin_mm;
  if (reach <= 0.0) return 0.0;
  const Eigen::Vector2d mid = f.centre + s.sign * f.half[s.axis] * f.axis[s.axis];
  int count = 0;
  return probe.Support(mid - reach * f.axis[other], mid + reach * f.axis[other], o.step_mm, &count);
}

// Mean gradient across side k of frame f, without the corner margins.
double SideStrength(const EdgeProbe& probe, const Frame& f, int k, const TopFaceEdgeOptions& o) {
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  const double reach = f.half[other] - o.corner_margin_mm;
  if (reach <= 0.0) return 0.0;
  const Eigen::Vector2d mid = f.centre + s.sign * f.half[s.axis] * f.axis[s.axis];
  return probe.Strength(mid - reach * f.axis[other], mid + reach * f.axis[other], o.step_mm);
}

// Edge support of the two sides beside side k over its extension from `from` (the old half
// extent) to the frame's (the lower of the two); 1 when the extension is too short to sample.
double NeighbourSidesSupport(const EdgeProbe& probe, const Frame& f, int k, double from,
                             const TopFaceEdgeOptions& o) {
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  const double to = f.half[s.axis] - o.corner_margin_mm;
  // The old side lies at 2 * from - f.half from f's centre (f's centre moved by half the
  // extension); the samples run from there to the new side less the corner margin.
  const double start = s.sign * (2.0 * from - f.half[s.axis]);
  const double end = s.sign * to;
  if (std::abs(end - start) < 2.0 * o.step_mm) return 1.0;
  double lowest = 1.0;
  for (double across : {-1.0, 1.0}) {
    const Eigen::Vector2d base = f.centre + across * f.half[other] * f.axis[other];
    int count = 0;
    const double support = probe.Support(base + start * f.axis[s.axis], base + end * f.axis[s.axis],
                                         o.step_mm, &count);
    lowest = std::min(lowest, support);
  }
  return lowest;
}

bool Overlaps(const Frame& f, const Rectangle2D& other, double margin) {
  const cv::RotatedRect a(cv::Point2f(static_cast<float>(f.centre.x()), static_cast<float>(f.centre.y())),
                          cv::Size2f(static_cast<float>(2.0 * f.half[0] + 2.0 * margin),
                                     static_cast<float>(2.0 * f.half[1] + 2.0 * margin)),
                          static_cast<float>(std::atan2(f.axis[0].y(), f.axis[0].x()) * 180.0 /
                                             std::numbers::pi));
  const cv::RotatedRect b(cv::Point2f(static_cast<float>(other.centre.x()), static_cast<float>(other.centre.y())),
                          cv::Size2f(static_cast<float>(other.length), static_cast<float>(other.width)),
                          static_cast<float>(other.yaw_deg));
  std::vector<cv::Point2f> overlap;
  return cv::rotatedRectangleIntersection(a, b, overlap) != cv::INTERSECT_NONE;
}

// Strong points below the top seen through the strip that side k's extension adds (between the
// old side, at half extent `from`, and the new one, 1.5 mm inside both and inside the others).
int ContradictingPoints(const Frame& f, int k, double from, double height, double top_layer_mm,
                        const std::vector<Eigen::Vector3d>& points, const std::vector<bool>& weak,
                        const std::vector<Eigen::Vector3d>& camera_centres) {
  constexpr double kInsideMm = 1.5;
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  // Signed offsets along the side's axis from f's centre: the old side and the new one.
  const double old_side = 2.0 * from - f.half[s.axis];
  int count = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (weak[i] || !(points[i].z() < height - 2.0 * top_layer_mm)) continue;
    for (const Eigen::Vector3d& C : camera_centres) {
      if (!(C.z() > height)) continue;
      const double t = (height - C.z()) / (points[i].z() - C.z());
      const Eigen::Vector2d q = (C + t * (points[i] - C)).head<2>() - f.centre;
      const double along = s.sign * q.dot(f.axis[s.axis]);
      const double across = std::abs(q.dot(f.axis[other]));
      if (along > old_side + kInsideMm && along < f.half[s.axis] - kInsideMm &&
          across < f.half[other] - kInsideMm) {
        ++count;
        break;
      }
    }
  }
  return count;
}

// Of the part's top-layer points (within top_layer_mm of `height`), the fraction more than
// 1.5 mm beyond side k of frame f.
double FractionBeyondSide(const Frame& f, int k, double height, double top_layer_mm,
                          const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices) {
  constexpr double kBeyondMm = 1.5;
  const Side s = SideOf(k);
  int top = 0, beyond = 0;
  for (int i : indices) {
    const Eigen::Vector3d& p = points[static_cast<std::size_t>(i)];
    if (std::abs(p.z() - height) > top_layer_mm) continue;
    ++top;
    if (s.sign * (p.head<2>() - f.centre).dot(f.axis[s.axis]) > f.half[s.axis] + kBeyondMm) ++beyond;
  }
  return top > 0 ? static_cast<double>(beyond) / top : 1.0;
}

}  // namespace

std::string TopFaceEdgeOptions::Check() const {
  if (!(max_extension_mm >= 0.0)) return "top edges: max_extension_mm must be >= 0";
  if (!(step_mm > 0.0)) return "top edges: step_mm must be > 0";
  if (!(min_edge_gradient > 0.0)) return "top edges: min_edge_gradient must be > 0";
  if (!(min_end_support > 0.0 && min_end_support <= 1.0)) {
    return "top edges: min_end_support must be in (0, 1]";
  }
  if (!(min_side_support >= 0.0 && min_side_support <= 1.0)) {
    return "top edges: min_side_support must be in [0, 1]";
  }
  if (!(corner_margin_mm >= 0.0)) return "top edges: corner_margin_mm must be >= 0";
  if (!(max_inward_mm >= 0.0)) return "top edges: max_inward_mm must be >= 0";
  if (!(max_cut_fraction >= 0.0 && max_cut_fraction <= 1.0)) {
    return "top edges: max_cut_fraction must be in [0, 1]";
  }
  if (max_contradicting_points < 0) return "top edges: max_contradicting_points must be >= 0";
  return {};
}

TopFaceEdgeReport ExtendTopToImageEdges(ObjectPose* pose, const Eigen::Matrix<double, 3, 4>& P,
                                        const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                        const std::vector<Rectangle2D>& others,
                                        const std::vector<Eigen::Vector3d>& points,
                                        const std::vector<bool>& weak,
                                        const std::vector<Eigen::Vector3d>& camera_centres,
                                        double top_layer_mm, double max_length_mm,
                                        bool centroid_from_rectangle,
                                        const TopFaceEdgeOptions& options) {
  TopFaceEdgeReport report;
  if (pose->round || options.max_extension_mm <= 0.0 || gradient_x.empty()) return report;
  const EdgeProbe probe(P, gradient_x, gradient_y, pose->height_mm, options.min_edge_gradient);
  Frame f = FrameOf(pose->top_rectangle);
  for (int k = 0; k < 4; ++k) {
    const Side s = SideOf(k);
    // Is the side already at an image edge (within 1 mm)?
    double before = 0.0;
    for (double e = -1.0; e <= 1.0 + 1e-9; e += options.step_mm) {
      if (f.half[s.axis] + 0.5 * e <= 0.0) continue;
      before = std::max(before, SideSupport(probe, Extended(f, k, e), k, options));
    }
    report.end_support_before[k] = before;
    if (before >= options.min_end_support) continue;
    // A side that lies beyond the face's edge (points at the top height past it: mismatches,
    // a neighbour's points joined to the part) has no edge under it either, but the face's
    // edge lies inside it: moving it out would stretch the top further (default seeds 65019,
    // 65086: tops already 3.7 and 4.2 mm too wide found the walls' base edges beyond). It moves
    // in to that edge instead, when few of the top's points lie beyond it (default 85156: a
    // 43 x 36 mm top stretched 9.7 mm by a taller neighbour's points joined to it).
    double inside = 0.0;
    for (double e = -1.0 - options.step_mm; e >= -options.max_inward_mm - 1e-9; e -= options.step_mm) {
      if (f.half[s.axis] + 0.5 * e <= 2.0 * options.corner_margin_mm) break;
      if (SideSupport(probe, Extended(f, k, e), k, options) >= options.min_end_support) {
        inside = e;
        break;
      }
    }
    if (inside < 0.0) {
      ++report.edge_inside;
      // The support test passes a few pixels outside the edge: its line is where the gradient
      // peaks, within the next 3 mm inward.
      double best = inside, best_strength = SideStrength(probe, Extended(f, k, inside), k, options);
      for (double e = inside - options.step_mm; e >= inside - 3.0 - 1e-9; e -= options.step_mm) {
        if (f.half[s.axis] + 0.5 * e <= 2.0 * options.corner_margin_mm) break;
        const double strength = SideStrength(probe, Extended(f, k, e), k, options);
        if (strength > best_strength) {
          best = e;
          best_strength = strength;
        }
      }
      const Frame g = Extended(f, k, best);
      if (FractionBeyondSide(g, k, pose->height_mm, top_layer_mm, points, pose->point_indices) <=
          options.max_cut_fraction) {
        report.extension_mm[k] = best;
        f = g;
      }
      continue;
    }
    const double from = f.half[s.axis];
    double found = 0.0;
    for (double e = 1.0; e <= options.max_extension_mm + 1e-9; e += options.step_mm) {
      const Frame g = Extended(f, k, e);
      if (2.0 * std::max(g.half[0], g.half[1]) > max_length_mm) break;
      bool blocked = false;
      for (const Rectangle2D& other : others) blocked = blocked || Overlaps(g, other, 1.0);
      if (blocked) break;
      if (SideSupport(probe, g, k, options) >= options.min_end_support &&
          NeighbourSidesSupport(probe, g, k, from, options) >= options.min_side_support) {
        found = e;
        break;
      }
    }
    if (found <= 0.0) continue;
    // The support test passes up to a few pixels before the edge (the Sobel response is a
    // few pixels wide, the test allows 1 px): the edge's line is where the gradient across the
    // side peaks, within the next 3 mm.
    double best = found, best_strength = SideStrength(probe, Extended(f, k, found), k, options);
    for (double e = found + options.step_mm; e <= found + 3.0 + 1e-9; e += options.step_mm) {
      const Frame g = Extended(f, k, e);
      if (2.0 * std::max(g.half[0], g.half[1]) > max_length_mm) break;
      const double strength = SideStrength(probe, g, k, options);
      if (strength > best_strength) {
        best = e;
        best_strength = strength;
      }
    }
    const Frame g = Extended(f, k, best);
    if (ContradictingPoints(g, k, from, pose->height_mm, top_layer_mm, points, weak,
                            camera_centres) > options.max_contradicting_points) {
      ++report.refused_by_points;
      continue;
    }
    report.extension_mm[k] = best;
    f = g;
  }
  if (report.moved_mm() == 0.0) return report;
  if (f.half[1] > f.half[0]) {
    // The moves made the short side the long one: the yaw (the long side's direction) would
    // turn 90 degrees on edges that do not settle which side is longer (default seed 85026: a
    // 75 x 62 mm top of two touching parts). Keep the points' rectangle.
    report = TopFaceEdgeReport{};
    report.swapped_sides_refused = true;
    return report;
  }
  Rectangle2D& r = pose->top_rectangle;
  r.centre = f.centre;
  r.length = 2.0 * f.half[0];
  r.width = 2.0 * f.half[1];
  if (centroid_from_rectangle) {
    pose->centroid.x() = r.centre.x();
    pose->centroid.y() = r.centre.y();
  }
  return report;
}

}  // namespace hnnstereo::vision
