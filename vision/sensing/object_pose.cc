#include "vision/sensing/object_pose.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace hnnstereo::vision {
namespace {

constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;

double Cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

double Quantile(std::vector<double> values, double q) {
  const auto k = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
  return values[k];
}

}  // namespace

std::string_view YawMethodName(YawMethod method) {
  return method == YawMethod::kMinAreaRectangle ? "rectangle" : "moments";
}

std::optional<YawMethod> ParseYawMethod(std::string_view name) {
  if (name == "rectangle") return YawMethod::kMinAreaRectangle;
  if (name == "moments") return YawMethod::kCentralMoments;
  return std::nullopt;
}

std::string ObjectPoseOptions::Check() const {
  std::ostringstream out;
  if (!(top_layer_mm > 0.0)) {
    out << "ObjectPoseOptions.top_layer_mm must be positive (is " << top_layer_mm << ")";
  } else if (!(max_circle_residual >= 0.0 && max_circle_residual < 1.0)) {
    out << "ObjectPoseOptions.max_circle_residual must be in [0, 1) (is " << max_circle_residual
        << ")";
  } else if (!(min_circle_inlier_fraction >= 0.0 && min_circle_inlier_fraction <= 1.0 &&
               circle_band_fraction >= 0.0 && circle_band_min_mm >= 0.0 &&
               min_rim_coverage >= 0.0 && min_rim_coverage <= 1.0 &&
               max_outside_circle_fraction >= 0.0 && max_outside_circle_fraction <= 1.0)) {
    out << "ObjectPoseOptions: min_circle_inlier_fraction, min_rim_coverage and "
           "max_outside_circle_fraction must be in [0, 1], circle_band_fraction and "
           "circle_band_min_mm >= 0";
  } else if (!(max_round_top_fill > 0.0)) {
    out << "ObjectPoseOptions.max_round_top_fill must be positive (is " << max_round_top_fill
        << ")";
  } else if (!(max_split_height_difference_mm >= 0.0 && max_hidden_fraction >= 0.0)) {
    out << "ObjectPoseOptions: max_split_height_difference_mm and max_hidden_fraction must be >= 0";
  } else if (!(max_gap_points >= 0 && gap_margin_mm >= 0.0 && std::isfinite(gap_margin_mm))) {
    out << "ObjectPoseOptions: max_gap_points and gap_margin_mm must be >= 0 (are " << max_gap_points
        << ", " << gap_margin_mm << ")";
  } else if (!(outline_band_fraction >= 0.0 && outline_band_fraction < 0.5 &&
               min_outline_fraction >= 0.0 && min_outline_fraction <= 1.0)) {
    out << "ObjectPoseOptions: outline_band_fraction must be in [0, 0.5) and "
           "min_outline_fraction in [0, 1]";
  } else if (!(min_outline_piece_fraction >= 0.0 && min_facing_side_mm >= 0.0 &&
               max_thin_piece_width_mm >= 0.0)) {
    out << "ObjectPoseOptions: min_outline_piece_fraction, min_facing_side_mm and "
           "max_thin_piece_width_mm must be >= 0 (are "
        << min_outline_piece_fraction << ", " << min_facing_side_mm << ", "
        << max_thin_piece_width_mm << ")";
  } else if (!(hidden_margin_mm >= 0.0 && std::isfinite(hidden_margin_mm))) {
    out << "ObjectPoseOptions.hidden_margin_mm must be >= 0 (is " << hidden_margin_mm << ")";
  } else if (!(min_edge_strip_aspect >= 0.0)) {
    out << "ObjectPoseOptions.min_edge_strip_aspect must be >= 0 (is " << min_edge_strip_aspect << ")";
  } else if (!(max_top_face_gap_mm >= 0.0)) {
    out << "ObjectPoseOptions.max_top_face_gap_mm must be >= 0 (is " << max_top_face_gap_mm << ")";
  } else if (!(min_top_group_points >= 0 && top_group_link_mm >= 0.0 &&
               max_trim_yaw_change_deg >= 0.0)) {
    out << "ObjectPoseOptions: min_top_group_points, top_group_link_mm and "
           "max_trim_yaw_change_deg must be >= 0 (are "
        << min_top_group_points << ", " << top_group_link_mm << ", " << max_trim_yaw_change_deg
        << ")";
  } else if (!(face_end_line_mm >= 0.0 && std::isfinite(face_end_line_mm))) {
    out << "ObjectPoseOptions.face_end_line_mm must be >= 0 (is " << face_end_line_mm << ")";
  } else if (!(min_top_group_fraction >= 0.0 && min_top_group_fraction <= 1.0)) {
    out << "ObjectPoseOptions.min_top_group_fraction must be in [0, 1] (is " << min_top_group_fraction
        << ")";
  } else if (!(min_top_level_difference_mm >= 0.0 && min_top_level_fraction >= 0.0 &&
               min_top_level_fraction <= 0.5 && min_top_level_separation >= 0.0)) {
    out << "ObjectPoseOptions: min_top_level_difference_mm and min_top_level_separation must be "
           ">= 0 and min_top_level_fraction in [0, 0.5] (are "
        << min_top_level_difference_mm << ", " << min_top_level_separation << ", "
        << min_top_level_fraction << ")";
  } else if (!(densest_slab_factor > 0.0)) {
    out << "ObjectPoseOptions.densest_slab_factor must be positive (is " << densest_slab_factor
        << ")";
  }
  return out.str();
}

double NormaliseAxisAngle(double angle_deg) {
  double angle = std::fmod(angle_deg, 180.0);
  if (angle <= -90.0) angle += 180.0;
  if (angle > 90.0) angle -= 180.0;
  return angle;
}

double YawFromCentralMoments(const std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 2) return 0.0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  double mu20 = 0, mu02 = 0, mu11 = 0;
  for (const auto& p : points) {
    const Eigen::Vector2d d = p - mean;
    mu20 += d.x() * d.x();
    mu02 += d.y() * d.y();
    mu11 += d.x() * d.y();
  }
  // Thesis 6.2.11: phi = 0.5 atan2(2 mu11, mu20 - mu02).
  return NormaliseAxisAngle(0.5 * std::atan2(2.0 * mu11, mu20 - mu02) * kDegreesPerRadian);
}

std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> points) {
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  points.erase(std::unique(points.begin(), points.end()), points.end());
  if (points.size() < 3) return points;
  std::vector<Eigen::Vector2d> hull(2 * points.size());
  std::size_t k = 0;
  for (const auto& p : points) {  // lower hull
    while (k >= 2 && Cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {  // upper hull
    while (k >= lower && Cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  return hull;
}

std::optional<Circle2D> FitCircle(const std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 3) return std::nullopt;
  // x^2 + y^2 + D x + E y + F = 0 in least squares, about the mean (conditioning).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector2d d = p - mean;
    const Eigen::Vector3d row(d.x(), d.y(), 1.0);
    normal += row * row.transpose();
    rhs -= row * d.squaredNorm();
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(normal);
  if (lu.rank() < 3) return std::nullopt;
  const Eigen::Vector3d def = lu.solve(rhs);
  Circle2D circle;
  const Eigen::Vector2d centre(-0.5 * def.x(), -0.5 * def.y());
  const double radius_squared = centre.squaredNorm() - def.z();
  if (!(radius_squared > 0.0)) return std::nullopt;
  circle.centre = centre + mean;
  circle.radius = std::sqrt(radius_squared);
  double sum = 0.0;
  for (const auto& p : points) {
    const double r = (p - circle.centre).norm() - circle.radius;
    sum += r * r;
  }
  circle.rms_residual = std::sqrt(sum / static_cast<double>(points.size()));
  return circle;
}

std::optional<Circle2D> FitCircleRobust(const std::vector<Eigen::Vector2d>& points, double band,
                                        double max_radius, int* inliers) {
  // Hand-written RANSAC (exhaustive over the candidate triples, so deterministic): OpenCV's
  // circle and ellipse fits (cv::fitEllipse*, cv::minEnclosingCircle) have no outlier
  // rejection, cv::HoughCircles works on images, and Eigen has no robust fit.
  if (inliers != nullptr) *inliers = 0;
  if (points.size() < 3) return std::nullopt;
  constexpr std::size_t kMaxCandidates = 40;  // 9880 triples
  std::vector<Eigen::Vector2d> candidates;
  if (points.size() <= kMaxCandidates) {
    candidates = points;
  } else {
    for (std::size_t k = 0; k < kMaxCandidates; ++k) {
      candidates.push_back(points[k * (points.size() - 1) / (kMaxCandidates - 1)]);
    }
  }
  const auto count_within = [&](const Eigen::Vector2d& centre, double radius) {
    int count = 0;
    for (const auto& p : points) {
      if (std::abs((p - centre).norm() - radius) <= band) ++count;
    }
    return count;
  };
  int best = 0;
  Eigen::Vector2d best_centre = Eigen::Vector2d::Zero();
  double best_radius = 0.0;
  const std::size_t n = candidates.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      for (std::size_t k = j + 1; k < n; ++k) {
        // Circumcentre: equidistant from the three points (two perpendicular bisectors).
        const Eigen::Vector2d a = candidates[i], b = candidates[j] - a, c = candidates[k] - a;
        const double det = 2.0 * (b.x() * c.y() - b.y() * c.x());
        if (std::abs(det) < 1e-9) continue;
        const Eigen::Vector2d offset((c.y() * b.squaredNorm() - b.y() * c.squaredNorm()) / det,
                                     (b.x() * c.squaredNorm() - c.x() * b.squaredNorm()) / det);
        const double radius = offset.norm();
        if (radius > max_radius) continue;
        const int count = count_within(a + offset, radius);
        if (count > best) {
          best = count;
          best_centre = a + offset;
          best_radius = radius;
        }
      }
    }
  }
  if (best < 3) return std::nullopt;
  // Least squares on the consensus, kept only when it holds at least as many points.
  std::vector<Eigen::Vector2d> consensus;
  for (const auto& p : points) {
    if (std::abs((p - best_centre).norm() - best_radius) <= band) consensus.push_back(p);
  }
  Circle2D circle;
  circle.centre = best_centre;
  circle.radius = best_radius;
  if (const auto refined = FitCircle(consensus);
      refined && refined->radius <= max_radius &&
      count_within(refined->centre, refined->radius) >= best) {
    circle = *refined;
  }
  double sum = 0.0;
  int count = 0;
  for (const auto& p : points) {
    const double r = (p - circle.centre).norm() - circle.radius;
    if (std::abs(r) > band) continue;
    sum += r * r;
    ++count;
  }
  circle.rms_residual = count > 0 ? std::sqrt(sum / count) : 0.0;
  if (inliers != nullptr) *inliers = count;
  return circle;
}

Rectangle2D MinAreaRectangle(const std::vector<Eigen::Vector2d>& points) {
  Rectangle2D best;
  const std::vector<Eigen::Vector2d> hull = ConvexHull(points);
  if (hull.empty()) return best;
  if (hull.size() == 1) {
    best.centre = hull[0];
    return best;
  }
  double best_area = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2d edge = hull[(i + 1) % hull.size()] - hull[i];
    if (edge.norm() < 1e-12) continue;
    const Eigen::Vector2d u = edge.normalized();
    const Eigen::Vector2d v(-u.y(), u.x());
    double u_min = 1e300, u_max = -1e300, v_min = 1e300, v_max = -1e300;
    for (const auto& p : hull) {
      u_min = std::min(u_min, p.dot(u));
      u_max = std::max(u_max, p.dot(u));
      v_min = std::min(v_min, p.dot(v));
      v_max = std::max(v_max, p.dot(v));
    }
    const double area = (u_max - u_min) * (v_max - v_min);
    if (area < best_area) {
      best_area = area;
      best.centre = 0.5 * (u_min + u_max) * u + 0.5 * (v_min + v_max) * v;
      const bool u_is_long = (u_max - u_min) >= (v_max - v_min);
      best.length = u_is_long ? u_max - u_min : v_max - v_min;
      best.width = u_is_long ? v_max - v_min : u_max - u_min;
      const Eigen::Vector2d long_axis = u_is_long ? u : v;
      best.yaw_deg = NormaliseAxisAngle(std::atan2(long_axis.y(), long_axis.x()) * kDegreesPerRadian);
    }
  }
  return best;
}

double DistanceToRectangleOutline(const Rectangle2D& rectangle, const Eigen::Vector2d& p) {
  const double yaw = rectangle.yaw_deg / kDegreesPerRadian;
  const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw)), v(-u.y(), u.x());
  const Eigen::Vector2d d = p - rectangle.centre;
  const double along = std::abs(d.dot(u)) - 0.5 * rectangle.length;
  const double across = std::abs(d.dot(v)) - 0.5 * rectangle.width;
  if (along <= 0.0 && across <= 0.0) return -std::max(along, across);  // inside
  return Eigen::Vector2d(std::max(along, 0.0), std::max(across, 0.0)).norm();
}

namespace {

// The face's far end, cut off with the small groups: a plain top's outline breaks into pieces
// where its edges are weak, and the pieces at its far end - two corners, each on the line of
// one of the sides that reach it - are fewer points than min_top_group_fraction of the largest
// (AFaceEndCutOffWithTheSmallGroupsComesBack). A dropped group comes back when
// most of its points lie within `line_mm` of the line of a side of the kept points' rectangle,
// beyond that rectangle's end, and the opposite side's line holds such a group beyond the same
// end: a face's end has two corners, a stray chain at the top height (a neighbour's edge in
// line with one side) has one. The two must reach equally far (within 3 mm): a
// face's end is straight. Hand-written: no library fits this.
std::vector<Eigen::Vector2d> RestoreFaceEnds(std::vector<Eigen::Vector2d> kept,
                                             const std::vector<std::vector<Eigen::Vector2d>>& groups,
                                             double line_mm) {
  if (line_mm <= 0.0 || groups.empty() || kept.size() < 3) return kept;
  const Rectangle2D rect = MinAreaRectangle(kept);
  const double yaw = rect.yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d along(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d across(-along.y(), along.x());
  // For each axis (length, width) and each end (-1, +1) of it, the groups beyond that end on
  // the lines of the two sides that meet it.
  std::vector<std::size_t> restore;
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::Vector2d& end_axis = axis == 0 ? along : across;
    const Eigen::Vector2d& side_axis = axis == 0 ? across : along;
    const double half_end = 0.5 * (axis == 0 ? rect.length : rect.width);
    const double half_side = 0.5 * (axis == 0 ? rect.width : rect.length);
    for (int end = -1; end <= 1; end += 2) {
      std::vector<std::size_t> on_side[2];
      double reach[2] = {0.0, 0.0};  // furthest point beyond the end on each side's line
      for (std::size_t g = 0; g < groups.size(); ++g) {
        int votes[2] = {0, 0};
        double furthest = 0.0;
        for (const Eigen::Vector2d& p : groups[g]) {
          const Eigen::Vector2d d = p - rect.centre;
          furthest = std::max(furthest, end * d.dot(end_axis) - half_end);
          const double s = d.dot(side_axis);
          if (std::abs(s + half_side) <= line_mm) ++votes[0];
          if (std::abs(s - half_side) <= line_mm) ++votes[1];
        }
        for (int side = 0; side < 2; ++side) {
          if (furthest > line_mm && 2 * votes[side] > static_cast<int>(groups[g].size())) {
            on_side[side].push_back(g);
            reach[side] = std::max(reach[side], furthest);
          }
        }
      }
      // The two corners of one end reach equally far (a face's end is straight).
      constexpr double kCornerReachToleranceMm = 3.0;
      if (!on_side[0].empty() && !on_side[1].empty() &&
          std::abs(reach[0] - reach[1]) <= kCornerReachToleranceMm) {
        for (const auto& side : on_side) restore.insert(restore.end(), side.begin(), side.end());
      }
    }
  }
  std::sort(restore.begin(), restore.end());
  restore.erase(std::unique(restore.begin(), restore.end()), restore.end());
  for (std::size_t g : restore) kept.insert(kept.end(), groups[g].begin(), groups[g].end());
  return kept;
}

}  // namespace

namespace {

// The top face's height (mm): the densest slab of heights (densest_slab_factor x top_layer_mm;
// ties: the higher), then the median of the layer within top_layer_mm of it, twice. `top_xy`
// receives the table-plane positions of that last layer's points.
double TopFaceHeight(const std::vector<double>& heights, const std::vector<Eigen::Vector2d>& all_xy,
                     const ObjectPoseOptions& options, std::vector<Eigen::Vector2d>* top_xy) {
  std::vector<double> sorted = heights;
  std::sort(sorted.begin(), sorted.end());
  const double slab = options.densest_slab_factor * options.top_layer_mm;
  std::size_t best_start = 0, best_count = 0;
  for (std::size_t i = 0, j = 0; i < sorted.size(); ++i) {
    j = std::max(j, i);
    while (j + 1 < sorted.size() && sorted[j + 1] <= sorted[i] + slab) ++j;
    if (j - i + 1 >= best_count) {
      best_count = j - i + 1;
      best_start = i;
    }
  }
  double height = sorted[best_start + best_count / 2];
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<double> layer;
    top_xy->clear();
    for (std::size_t k = 0; k < heights.size(); ++k) {
      if (std::abs(heights[k] - height) <= options.top_layer_mm) {
        layer.push_back(heights[k]);
        top_xy->push_back(all_xy[k]);
      }
    }
    height = Quantile(layer, 0.5);  // layer holds at least the guess itself
  }
  return height;
}

// The top points without the small groups (linked within top_group_link_mm, union-find; fewer
// than min_top_group_points or min_top_group_fraction of the largest): mismatches beyond an
// edge that stretch the rectangle across it. Where leaving them out turns the rectangle by more
// than max_trim_yaw_change_deg instead, they were the face's own corners and all are kept; a
// group in line with a face's end is restored (RestoreFaceEnds).
std::vector<Eigen::Vector2d> TrimSmallTopGroups(std::vector<Eigen::Vector2d> top_xy,
                                                const ObjectPoseOptions& options) {
  const double link_squared = options.top_group_link_mm * options.top_group_link_mm;
  std::vector<std::size_t> parent(top_xy.size());
  for (std::size_t a = 0; a < parent.size(); ++a) parent[a] = a;
  const auto root = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (std::size_t a = 0; a < top_xy.size(); ++a) {
    for (std::size_t b = a + 1; b < top_xy.size(); ++b) {
      if ((top_xy[a] - top_xy[b]).squaredNorm() <= link_squared) parent[root(a)] = root(b);
    }
  }
  std::vector<int> group_size(top_xy.size(), 0);
  for (std::size_t a = 0; a < top_xy.size(); ++a) ++group_size[root(a)];
  const int largest = group_size.empty() ? 0 : *std::max_element(group_size.begin(), group_size.end());
  const int min_group = std::max(options.min_top_group_points,
                                 static_cast<int>(std::ceil(options.min_top_group_fraction * largest)));
  std::vector<Eigen::Vector2d> kept;
  std::map<std::size_t, std::vector<Eigen::Vector2d>> dropped;  // by group root
  for (std::size_t a = 0; a < top_xy.size(); ++a) {
    if (group_size[root(a)] >= min_group) {
      kept.push_back(top_xy[a]);
    } else {
      dropped[root(a)].push_back(top_xy[a]);
    }
  }
  if (!kept.empty() && kept.size() < top_xy.size() &&
      std::abs(NormaliseAxisAngle(MinAreaRectangle(kept).yaw_deg -
                                  MinAreaRectangle(top_xy).yaw_deg)) <=
          options.max_trim_yaw_change_deg) {
    std::vector<std::vector<Eigen::Vector2d>> groups;
    for (auto& [group_root, group] : dropped) groups.push_back(std::move(group));
    return RestoreFaceEnds(std::move(kept), groups, options.face_end_line_mm);
  }
  return top_xy;
}

// ObjectPose::top_fill: the area of the top points' convex hull (shoelace) over their
// rectangle's; 0 for a rectangle of no area.
double HullFill(const std::vector<Eigen::Vector2d>& top_hull, const Rectangle2D& rectangle) {
  const double area = rectangle.length * rectangle.width;
  if (!(area > 0.0)) return 0.0;
  double hull_area = 0.0;
  for (std::size_t i = 0; i < top_hull.size(); ++i) {
    const Eigen::Vector2d& a = top_hull[i];
    const Eigen::Vector2d& b = top_hull[(i + 1) % top_hull.size()];
    hull_area += 0.5 * (a.x() * b.y() - a.y() * b.x());
  }
  return std::abs(hull_area) / area;
}

// The share of a circle's rim (10 degree bins) that top points within `band` (mm) of it cover;
// `outside` receives the count of top points beyond the band outside the circle.
double RimCoverage(const Circle2D& circle, const std::vector<Eigen::Vector2d>& top_xy, double band,
                   std::size_t* outside) {
  constexpr int kRimBins = 36;
  std::vector<bool> rim_bin(kRimBins, false);
  *outside = 0;
  for (const auto& p : top_xy) {
    const Eigen::Vector2d d = p - circle.centre;
    const double radial = d.norm() - circle.radius;
    if (radial > band) ++*outside;
    if (std::abs(radial) > band) continue;
    const double turn = (std::atan2(d.y(), d.x()) + std::numbers::pi) / (2.0 * std::numbers::pi);
    rim_bin[std::min(kRimBins - 1, static_cast<int>(turn * kRimBins))] = true;
  }
  return static_cast<double>(std::count(rim_bin.begin(), rim_bin.end(), true)) / kRimBins;
}

// The circle of a round top, or none: the top's hull fits a circle (rms residual below
// max_circle_residual x radius) whose rim the top points cover (min_rim_coverage) - the hull of
// a long strip keeps its vertices near its corners, on the rectangle's circumscribed circle -
// or, failing that, a robust fit holds min_circle_inlier_fraction of the hull with few points
// outside it (max_outside_circle_fraction). Needs a hull of 12 vertices and 60 top points (a
// fragment of a face can fit some circle by chance) and a top_fill up to max_round_top_fill.
std::optional<Circle2D> RoundTopCircle(const std::vector<Eigen::Vector2d>& top_xy,
                                       const std::vector<Eigen::Vector2d>& hull, double top_fill,
                                       const ObjectPoseOptions& options) {
  constexpr std::size_t kMinHullVertices = 12;  // a rectangle's hull can have as few as 4
  constexpr std::size_t kMinCirclePoints = 60;
  const bool enough = hull.size() >= kMinHullVertices && top_xy.size() >= kMinCirclePoints &&
                      !(top_fill > options.max_round_top_fill);
  if (!enough) return std::nullopt;
  double diameter = 0.0;
  for (std::size_t a = 0; a < hull.size(); ++a) {
    for (std::size_t b = a + 1; b < hull.size(); ++b) {
      diameter = std::max(diameter, (hull[a] - hull[b]).norm());
    }
  }
  const double band = std::max(options.circle_band_min_mm,
                               options.circle_band_fraction * 0.5 * diameter);
  std::size_t outside = 0;
  if (const auto circle = FitCircle(hull);
      circle && circle->rms_residual < options.max_circle_residual * circle->radius &&
      RimCoverage(*circle, top_xy, band, &outside) >= options.min_rim_coverage) {
    return circle;
  }
  if (!(options.min_circle_inlier_fraction > 0.0)) return std::nullopt;
  int inliers = 0;
  // No radius above the diameter: the visible part of a disc is at least a shallow cap.
  if (const auto circle = FitCircleRobust(hull, band, diameter, &inliers);
      circle && inliers >= options.min_circle_inlier_fraction * static_cast<double>(hull.size()) &&
      circle->rms_residual < options.max_circle_residual * circle->radius) {
    const double coverage = RimCoverage(*circle, top_xy, band, &outside);
    if (coverage >= options.min_rim_coverage &&
        static_cast<double>(outside) <=
            options.max_outside_circle_fraction * static_cast<double>(top_xy.size())) {
      return circle;
    }
  }
  return std::nullopt;
}

}  // namespace

ObjectPose EstimateObjectPose(const std::vector<Eigen::Vector3d>& points_in_world,
                              const std::vector<int>& indices, const ObjectPoseOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (indices.empty()) throw std::invalid_argument("EstimateObjectPose: empty cluster");
  ObjectPose pose;
  pose.point_indices = indices;
  pose.points = static_cast<int>(indices.size());
  std::vector<double> heights;
  std::vector<Eigen::Vector2d> all_xy;
  for (int i : indices) {
    const Eigen::Vector3d& p = points_in_world.at(static_cast<std::size_t>(i));
    heights.push_back(p.z());
    all_xy.push_back(p.head<2>());
  }
  std::vector<Eigen::Vector2d> top_xy;
  const double height = TopFaceHeight(heights, all_xy, options, &top_xy);
  pose.height_mm = height;
  pose.top_points = static_cast<int>(top_xy.size());
  if (options.min_top_group_points > 1) top_xy = TrimSmallTopGroups(std::move(top_xy), options);
  pose.top_rectangle = MinAreaRectangle(top_xy);

  pose.yaw_moments_deg = YawFromCentralMoments(all_xy);
  pose.yaw_deg = options.yaw_method == YawMethod::kMinAreaRectangle ? pose.top_rectangle.yaw_deg
                                                                     : pose.yaw_moments_deg;
  Eigen::Vector2d centre = pose.top_rectangle.centre;
  const std::vector<Eigen::Vector2d> top_hull = ConvexHull(top_xy);
  pose.top_fill = HullFill(top_hull, pose.top_rectangle);
  if (top_hull.size() >= 5) {
    if (const auto circle = FitCircle(top_hull)) pose.top_roundness = circle->rms_residual / circle->radius;
  }
  if (options.max_circle_residual > 0.0) {
    if (const auto circle = RoundTopCircle(top_xy, top_hull, pose.top_fill, options)) {
      pose.round = true;
      pose.circle_centre = circle->centre;
      pose.circle_radius = circle->radius;
      centre = circle->centre;
    }
  }
  if (!options.centroid_from_rectangle) {
    centre.setZero();
    for (const auto& p : all_xy) centre += p;
    centre /= static_cast<double>(all_xy.size());
  }
  pose.centroid = Eigen::Vector3d(centre.x(), centre.y(), height);
  return pose;
}

namespace {

bool InsideConvexPolygon(const std::vector<Eigen::Vector2d>& hull, const Eigen::Vector2d& point) {
  if (hull.size() < 3) return false;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    if (Cross(hull[i], hull[(i + 1) % hull.size()], point) < 0) return false;  // counter-clockwise
  }
  return true;
}

double SegmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double length_squared = ab.squaredNorm();
  const double t = length_squared > 0.0 ? std::clamp((p - a).dot(ab) / length_squared, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

// Smallest distance between the outlines of two convex polygons (0 when they overlap).
double HullGap(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  double gap = std::numeric_limits<double>::infinity();
  for (int pass = 0; pass < 2; ++pass) {
    const auto& from = pass == 0 ? a : b;
    const auto& to = pass == 0 ? b : a;
    for (const auto& p : from) {
      if (InsideConvexPolygon(to, p)) return 0.0;
      for (std::size_t i = 0; i < to.size(); ++i) {
        gap = std::min(gap, SegmentDistance(p, to[i], to[(i + 1) % to.size()]));
      }
    }
  }
  return gap;
}

// Point i belongs to neither piece a nor b, is not weak, and lies more than 2 top layers off the
// joint top's `height`: what the hidden-point and gap-point rules count.
bool OffTheJointTop(std::size_t i, const std::vector<Eigen::Vector3d>& points_in_world,
                    const std::vector<int>& cluster_of_point, int a, int b, double height,
                    const ObjectPoseOptions& options, const std::vector<bool>* weak) {
  if (cluster_of_point[i] == a || cluster_of_point[i] == b) return false;
  if (weak != nullptr && (*weak)[i]) return false;
  return std::abs(points_in_world[i].z() - height) > 2.0 * options.top_layer_mm;
}

// Distance from `point` to the outline of the convex polygon `hull` (inside or outside).
double DistanceToPolygonOutline(const std::vector<Eigen::Vector2d>& hull, const Eigen::Vector2d& point) {
  double distance = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < hull.size(); ++k) {
    distance = std::min(distance, SegmentDistance(point, hull[k], hull[(k + 1) % hull.size()]));
  }
  return distance;
}

// Points (not in clusters a or b, not weak) inside the hull of a's and b's top faces, more
// than hidden_margin_mm inside its outline, and more than 2 top layers below or above their
// height: a solid top face hides what is under it, and nothing stands on it. Its own sides and
// base edge lie under its outline: they are not hidden by it.
int PointsHiddenUnderJointTop(const std::vector<Eigen::Vector3d>& points_in_world,
                              const std::vector<int>& cluster_of_point, int a, int b,
                              const std::vector<Eigen::Vector2d>& hull, double height,
                              const ObjectPoseOptions& options, const std::vector<bool>* weak) {
  if (hull.size() < 3) return 0;
  Eigen::Vector2d low = hull[0], high = hull[0];
  for (const auto& p : hull) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  int count = 0;
  for (std::size_t i = 0; i < points_in_world.size(); ++i) {
    const Eigen::Vector3d& p = points_in_world[i];
    if (!OffTheJointTop(i, points_in_world, cluster_of_point, a, b, height, options, weak)) continue;
    if (p.x() < low.x() || p.y() < low.y() || p.x() > high.x() || p.y() > high.y()) continue;
    if (InsideConvexPolygon(hull, p.head<2>()) &&
        DistanceToPolygonOutline(hull, p.head<2>()) > options.hidden_margin_mm) {
      ++count;
    }
  }
  return count;
}

// Points (not in clusters a or b, not weak) seen more than 2 top layers below or above the
// joint top in the gap between two pieces: inside the hull of their joint top face, more than
// gap_margin_mm inside its outline (the part's sides and base edge lie under the outline of its
// face), and not under one piece's own top (a mismatch there says nothing about the gap). Two
// parts standing apart show the table, a lower part, or their own sides facing each other
// between them; the pieces of one face hide all of that.
int PointsSeenInTheGap(const std::vector<Eigen::Vector3d>& points_in_world,
                       const std::vector<int>& cluster_of_point, int a, int b,
                       const std::vector<Eigen::Vector2d>& joint_hull,
                       const std::vector<Eigen::Vector2d>& hull_a,
                       const std::vector<Eigen::Vector2d>& hull_b, double height,
                       const ObjectPoseOptions& options, const std::vector<bool>* weak) {
  if (joint_hull.size() < 3) return 0;
  int count = 0;
  for (std::size_t i = 0; i < points_in_world.size(); ++i) {
    if (!OffTheJointTop(i, points_in_world, cluster_of_point, a, b, height, options, weak)) continue;
    const Eigen::Vector2d xy = points_in_world[i].head<2>();
    if (!InsideConvexPolygon(joint_hull, xy) ||
        DistanceToPolygonOutline(joint_hull, xy) <= options.gap_margin_mm) {
      continue;
    }
    if (!InsideConvexPolygon(hull_a, xy) && !InsideConvexPolygon(hull_b, xy)) ++count;
  }
  return count;
}

// Fraction of the side of `piece`'s minimum-area rectangle that faces `towards` covered by the
// piece's points (1 mm bins within `band` of the side): a part's own edge facing the gap is a
// dense straight line; the cut across a split face is not.
double FacingSideCoverage(const std::vector<Eigen::Vector2d>& piece, const Eigen::Vector2d& towards,
                          double band, double min_side) {
  const Rectangle2D rectangle = MinAreaRectangle(piece);
  if (rectangle.length < 1.0) return 0.0;
  const double yaw = rectangle.yaw_deg / kDegreesPerRadian;
  const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw)), v(-u.y(), u.x());
  const Eigen::Vector2d to = towards - rectangle.centre;
  // The facing side: the one whose outward normal points most towards `towards`.
  const double along_u = to.dot(u) / (0.5 * rectangle.length);
  const double along_v = to.dot(v) / std::max(0.5 * rectangle.width, 1e-9);
  const bool across_u = std::abs(along_u) > std::abs(along_v);
  const Eigen::Vector2d normal = across_u ? (along_u > 0 ? u : -u) : (along_v > 0 ? v : -v);
  const Eigen::Vector2d direction = across_u ? v : u;
  const double offset = across_u ? 0.5 * rectangle.length : 0.5 * rectangle.width;
  const double side_length = across_u ? rectangle.width : rectangle.length;
  if (side_length < min_side) return 0.0;  // a thin piece's end is no edge
  const int bins = std::max(1, static_cast<int>(std::floor(side_length)));
  std::vector<bool> covered(static_cast<std::size_t>(bins), false);
  for (const auto& p : piece) {
    const Eigen::Vector2d d = p - rectangle.centre;
    if (offset - d.dot(normal) > band) continue;
    const double t = d.dot(direction) + 0.5 * side_length;
    const int bin = std::clamp(static_cast<int>(std::floor(t * bins / side_length)), 0, bins - 1);
    covered[static_cast<std::size_t>(bin)] = true;
  }
  return static_cast<double>(std::count(covered.begin(), covered.end(), true)) / bins;
}

}  // namespace

bool PiecesFaceEachOtherWithEdges(const std::vector<Eigen::Vector2d>& first,
                                  const std::vector<Eigen::Vector2d>& second,
                                  const ObjectPoseOptions& options) {
  if (first.size() < 3 || second.size() < 3) return false;
  Eigen::Vector2d first_centre = Eigen::Vector2d::Zero(), second_centre = Eigen::Vector2d::Zero();
  for (const auto& p : first) first_centre += p;
  for (const auto& p : second) second_centre += p;
  first_centre /= static_cast<double>(first.size());
  second_centre /= static_cast<double>(second.size());
  // Towards a line or a speck, a side shorter than min_facing_side_mm (an end) is no edge.
  const auto min_side_towards = [&](const std::vector<Eigen::Vector2d>& other) {
    return MinAreaRectangle(other).width <= options.max_thin_piece_width_mm ? options.min_facing_side_mm
                                                                           : 0.0;
  };
  return FacingSideCoverage(first, second_centre, options.facing_edge_band_mm,
                            min_side_towards(second)) >= options.min_facing_edge_coverage &&
         FacingSideCoverage(second, first_centre, options.facing_edge_band_mm,
                            min_side_towards(first)) >= options.min_facing_edge_coverage;
}

bool PiecesAreOppositeEndsOfOneFace(const std::vector<Eigen::Vector2d>& first,
                                    const std::vector<Eigen::Vector2d>& second,
                                    const ObjectPoseOptions& options) {
  if (first.size() < 3 || second.size() < 3) return false;
  const Rectangle2D a = MinAreaRectangle(first), b = MinAreaRectangle(second);

  if (std::abs(NormaliseAxisAngle(a.yaw_deg - b.yaw_deg)) > options.max_end_yaw_difference_deg) {
    return false;
  }
  if (std::abs(a.length - b.length) > options.max_end_length_difference * std::max(a.length, b.length)) {
    return false;
  }
  // Side by side across their long axis, not shifted along it.
  const double yaw = a.yaw_deg / kDegreesPerRadian;  // b's is within a few degrees
  const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw));
  return std::abs((b.centre - a.centre).dot(u)) <=
         options.max_end_length_difference * std::max(a.length, b.length);
}

bool PiecesOutlineOneFace(const std::vector<Eigen::Vector2d>& first,
                          const std::vector<Eigen::Vector2d>& second,
                          const ObjectPoseOptions& options) {
  if (first.size() < 3 || second.size() < 3) return false;
  std::vector<Eigen::Vector2d> joint = first;
  joint.insert(joint.end(), second.begin(), second.end());
  // A round face: the joint hull fits one circle (two arcs of one rim).
  const std::vector<Eigen::Vector2d> hull = ConvexHull(joint);
  if (options.max_circle_residual > 0.0 && hull.size() >= 12) {
    if (const auto circle = FitCircle(hull);
        circle && circle->rms_residual < options.max_circle_residual * circle->radius) {
      int on_rim = 0;
      for (const auto& p : joint) {
        if (std::abs((p - circle->centre).norm() - circle->radius) <=
            std::max(options.top_layer_mm, options.outline_band_fraction * circle->radius)) {
          ++on_rim;
        }
      }
      if (on_rim >= options.min_outline_fraction * static_cast<double>(joint.size())) return true;
    }
  }
  // A rectangular face: each piece lies along the joint rectangle's outline; two parts standing
  // apart put their inner sides deep inside it.
  const Rectangle2D rectangle = MinAreaRectangle(joint);
  // Pieces in line outline a strip, no face: every piece lies on a thin rectangle's outline
  // (PiecesInLineOutlineNoFaceAndTheBaseEdgeIsNotHidden).
  if (options.min_edge_strip_aspect > 0.0 &&
      rectangle.length >= options.min_edge_strip_aspect * rectangle.width) {
    return false;
  }
  const double band = std::max(options.top_layer_mm, options.outline_band_fraction * rectangle.width);
  for (const auto* piece : {&first, &second}) {
    if (MinAreaRectangle(*piece).length < options.min_outline_piece_fraction * rectangle.width) {
      return false;  // a speck, no stretch of the outline
    }
    int on_outline = 0;
    for (const auto& p : *piece) {
      if (DistanceToRectangleOutline(rectangle, p) <= band) ++on_outline;
    }
    if (on_outline < options.min_outline_fraction * static_cast<double>(piece->size())) return false;
  }
  return true;
}

namespace {

// A piece at least min_edge_strip_aspect times as long as wide: a stretch of a face's edge.
bool IsEdgeStrip(const std::vector<Eigen::Vector2d>& piece, const ObjectPoseOptions& options) {
  const Rectangle2D rectangle = MinAreaRectangle(piece);
  return rectangle.length > 0.0 && rectangle.length >= options.min_edge_strip_aspect * rectangle.width;
}

// The shape rules of the split-face join (the height and hidden-point rules come on top).
bool JoinAsOneFace(const std::vector<Eigen::Vector2d>& small, const std::vector<Eigen::Vector2d>& large,
                   double gap_mm, const ObjectPoseOptions& options) {
  if (!options.join_face_outlines) return gap_mm <= options.max_top_face_gap_mm;
  // Two edge strips of one plain face face each other with full sides too; a strip is no part's
  // face, and two that are a face's opposite ends and outline it together are that face.
  if (options.min_edge_strip_aspect > 0.0 && IsEdgeStrip(small, options) &&
      IsEdgeStrip(large, options) && PiecesAreOppositeEndsOfOneFace(small, large, options) &&
      PiecesOutlineOneFace(small, large, options)) {
    return true;
  }
  // Two parts whose own edges face each other never join, whatever they outline together.
  if (PiecesFaceEachOtherWithEdges(small, large, options)) return false;
  if (PiecesOutlineOneFace(small, large, options)) return true;
  if (gap_mm > options.max_top_face_gap_mm) {
    // A face's two strong ends (its sides along the epipolar lines are weak), each with the
    // marks near it: parallel, as long as each other, side by side; not two parts with edges.
    return PiecesAreOppositeEndsOfOneFace(small, large, options) &&
           !PiecesFaceEachOtherWithEdges(small, large, options);
  }
  // Near pieces: two parts whose own edges face each other across the gap stay apart (two tall
  // parts hide the table between them, so the hidden-point rule cannot see the gap).
  return !(options.join_face_outlines && PiecesFaceEachOtherWithEdges(small, large, options));
}

}  // namespace

std::vector<std::vector<int>> MergeTopFaceIslands(const std::vector<Eigen::Vector3d>& points_in_world,
                                                  std::vector<std::vector<int>> clusters,
                                                  const ObjectPoseOptions& options, int* merges,
                                                  const std::vector<bool>* weak,
                                                  const PiecesSeenApart& seen_apart) {
  if (weak != nullptr && weak->size() != points_in_world.size()) {
    throw std::invalid_argument("MergeTopFaceIslands: weak must have one flag per point");
  }
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const auto& a, const auto& b) { return a.size() > b.size(); });
  int merged = 0;
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<ObjectPose> poses;
    std::vector<std::vector<Eigen::Vector2d>> top_hulls;
    std::vector<std::vector<Eigen::Vector2d>> tops;
    for (const auto& cluster : clusters) {
      poses.push_back(EstimateObjectPose(points_in_world, cluster, options));
      std::vector<Eigen::Vector2d> top_xy;
      for (int i : cluster) {
        const Eigen::Vector3d& p = points_in_world[static_cast<std::size_t>(i)];
        if (std::abs(p.z() - poses.back().height_mm) <= options.top_layer_mm) top_xy.push_back(p.head<2>());
      }
      top_hulls.push_back(ConvexHull(top_xy));
      tops.push_back(std::move(top_xy));
    }
    std::vector<int> cluster_of_point(points_in_world.size(), -1);
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      for (int i : clusters[c]) cluster_of_point[static_cast<std::size_t>(i)] = static_cast<int>(c);
    }
    for (std::size_t small = clusters.size(); small-- > 1 && !changed;) {
      for (std::size_t large = 0; large < small && !changed; ++large) {
        if (std::abs(poses[small].height_mm - poses[large].height_mm) > options.top_layer_mm) continue;
        if (!InsideConvexPolygon(top_hulls[large], poses[small].top_rectangle.centre)) {
          std::vector<Eigen::Vector2d> joint = top_hulls[large];
          joint.insert(joint.end(), top_hulls[small].begin(), top_hulls[small].end());
          joint = ConvexHull(joint);
          const double height = 0.5 * (poses[small].height_mm + poses[large].height_mm);
          // A round top face is complete when its hull fits a circle: a piece outside that
          // circle belongs to something else - whichever of the two is round
          // (ARoundTopStaysApartFromABoxBesideIt).
          const auto outside_circle_of = [&](std::size_t round, std::size_t other) {
            return poses[round].round &&
                   std::any_of(top_hulls[other].begin(), top_hulls[other].end(),
                               [&](const Eigen::Vector2d& p) {
                                 return (p - poses[round].circle_centre).norm() >
                                        poses[round].circle_radius + options.top_layer_mm;
                               });
          };
          const bool outside_circle = outside_circle_of(large, small) || outside_circle_of(small, large);
          if (outside_circle || top_hulls[small].size() < 3 || top_hulls[large].size() < 3 ||
              std::abs(poses[small].height_mm - poses[large].height_mm) >
                  options.max_split_height_difference_mm ||
              !JoinAsOneFace(tops[small], tops[large],
                             HullGap(top_hulls[small], top_hulls[large]), options) ||
              PointsHiddenUnderJointTop(points_in_world, cluster_of_point, static_cast<int>(small),
                                        static_cast<int>(large), joint, height, options, weak) >
                  options.max_hidden_fraction *
                      static_cast<double>(clusters[small].size() + clusters[large].size()) ||
              PointsSeenInTheGap(points_in_world, cluster_of_point, static_cast<int>(small),
                                 static_cast<int>(large), joint, top_hulls[small], top_hulls[large],
                                 height, options, weak) > options.max_gap_points ||
              (seen_apart && seen_apart(tops[small], tops[large], height))) {
            continue;
          }
        }
        clusters[large].insert(clusters[large].end(), clusters[small].begin(), clusters[small].end());
        clusters.erase(clusters.begin() + static_cast<long>(small));
        ++merged;
        changed = true;
      }
    }
  }
  if (merges != nullptr) *merges = merged;
  return clusters;
}

namespace {

// Otsu's threshold on sorted heights: the split (each side at least `min_count` values) with
// the largest between-level variance k (n - k) (high - low)^2. score < 0: no split allowed.
struct LevelSplit {
  double score = -1.0;
  double threshold = 0.0;   // mm, midway between the two heights either side of the split
  double difference = 0.0;  // mm, the two levels' mean heights apart
};

LevelSplit OtsuSplit(const std::vector<double>& z, std::size_t min_count) {
  const std::size_t n = z.size();
  double total = 0.0;
  for (double v : z) total += v;
  LevelSplit best;
  double below_sum = 0.0;
  for (std::size_t k = 1; k < n; ++k) {
    below_sum += z[k - 1];
    if (k < std::max<std::size_t>(min_count, 1) || n - k < std::max<std::size_t>(min_count, 1)) continue;
    const double low = below_sum / static_cast<double>(k);
    const double high = (total - below_sum) / static_cast<double>(n - k);
    const double score = static_cast<double>(k) * static_cast<double>(n - k) * (high - low) * (high - low);
    if (score > best.score) {
      best.score = score;
      best.threshold = 0.5 * (z[k - 1] + z[k]);
      best.difference = high - low;
    }
  }
  return best;
}

// The level (0 low, 1 high) of each top point: its own by `threshold`, then that of most of
// its neighbours within top_group_link_mm (itself included; a tie keeps its own).
std::vector<int> SmoothedLevels(const std::vector<Eigen::Vector3d>& points_in_world,
                                const std::vector<int>& top, double threshold,
                                const ObjectPoseOptions& options) {
  std::vector<int> level(top.size());
  for (std::size_t a = 0; a < top.size(); ++a) {
    level[a] = points_in_world[static_cast<std::size_t>(top[a])].z() >= threshold ? 1 : 0;
  }
  const double link_squared = options.top_group_link_mm * options.top_group_link_mm;
  std::vector<int> smoothed(top.size());
  for (std::size_t a = 0; a < top.size(); ++a) {
    int votes[2] = {0, 0};
    const Eigen::Vector2d xy = points_in_world[static_cast<std::size_t>(top[a])].head<2>();
    for (std::size_t b = 0; b < top.size(); ++b) {
      if ((points_in_world[static_cast<std::size_t>(top[b])].head<2>() - xy).squaredNorm() <= link_squared) {
        ++votes[level[b]];
      }
    }
    smoothed[a] = votes[1] > votes[0] ? 1 : votes[1] < votes[0] ? 0 : level[a];
  }
  return smoothed;
}

// Whether the two levels are parts: each holds min_count top points and their centres lie
// min_top_level_separation x the top's length apart.
bool LevelsApart(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<int>& top,
                 const std::vector<int>& smoothed, std::size_t min_count, double top_length,
                 const ObjectPoseOptions& options) {
  Eigen::Vector2d centre[2] = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  std::size_t count[2] = {0, 0};
  for (std::size_t a = 0; a < top.size(); ++a) {
    centre[smoothed[a]] += points_in_world[static_cast<std::size_t>(top[a])].head<2>();
    ++count[smoothed[a]];
  }
  return !(count[0] < std::max<std::size_t>(min_count, 1) || count[1] < std::max<std::size_t>(min_count, 1) ||
           (centre[0] / static_cast<double>(count[0]) - centre[1] / static_cast<double>(count[1])).norm() <
               options.min_top_level_separation * top_length);
}

// The cluster's points by level: the top points by theirs, the others (sides, the lower face's
// rim below the layer) with their nearest top point's.
void AssignLevels(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<int>& cluster,
                  const std::vector<int>& top, const std::vector<int>& smoothed,
                  std::vector<int> parts[2]) {
  std::vector<int> level_of(points_in_world.size(), -1);
  for (std::size_t a = 0; a < top.size(); ++a) level_of[static_cast<std::size_t>(top[a])] = smoothed[a];
  for (int i : cluster) {
    int chosen = level_of[static_cast<std::size_t>(i)];
    if (chosen < 0) {
      double nearest = std::numeric_limits<double>::infinity();
      const Eigen::Vector2d xy = points_in_world[static_cast<std::size_t>(i)].head<2>();
      for (std::size_t a = 0; a < top.size(); ++a) {
        const double d = (points_in_world[static_cast<std::size_t>(top[a])].head<2>() - xy).squaredNorm();
        if (d < nearest) {
          nearest = d;
          chosen = smoothed[a];
        }
      }
    }
    parts[chosen].push_back(i);
  }
}

// Splits one cluster whose top layer holds two levels at least min_top_level_difference_mm
// apart (Otsu), each at least min_top_level_fraction of the layer, their centres apart: touching
// parts of unequal height. Returns false (no split) otherwise.
bool SplitCluster(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<int>& cluster,
                  const ObjectPoseOptions& options, std::vector<int> parts[2]) {
  const ObjectPose pose = EstimateObjectPose(points_in_world, cluster, options);
  std::vector<int> top;
  for (int i : cluster) {
    if (std::abs(points_in_world[static_cast<std::size_t>(i)].z() - pose.height_mm) <=
        options.top_layer_mm) {
      top.push_back(i);
    }
  }
  std::vector<double> z;
  for (int i : top) z.push_back(points_in_world[static_cast<std::size_t>(i)].z());
  std::sort(z.begin(), z.end());
  const auto min_count = static_cast<std::size_t>(
      std::ceil(options.min_top_level_fraction * static_cast<double>(z.size())));
  const LevelSplit best = OtsuSplit(z, min_count);
  if (best.score < 0.0 || best.difference < options.min_top_level_difference_mm) return false;
  const std::vector<int> smoothed = SmoothedLevels(points_in_world, top, best.threshold, options);
  if (!LevelsApart(points_in_world, top, smoothed, min_count, pose.top_rectangle.length, options)) {
    return false;
  }
  AssignLevels(points_in_world, cluster, top, smoothed, parts);
  return true;
}

}  // namespace

std::vector<std::vector<int>> SplitTopLevels(const std::vector<Eigen::Vector3d>& points_in_world,
                                             std::vector<std::vector<int>> clusters,
                                             const ObjectPoseOptions& options, int* splits) {
  int split = 0;
  if (options.min_top_level_difference_mm > 0.0) {
    std::vector<std::vector<int>> out;
    for (auto& cluster : clusters) {
      if (cluster.empty()) continue;
      std::vector<int> parts[2];
      if (!SplitCluster(points_in_world, cluster, options, parts)) {
        out.push_back(std::move(cluster));
        continue;
      }
      out.push_back(std::move(parts[0]));
      out.push_back(std::move(parts[1]));
      ++split;
    }
    clusters = std::move(out);
  }
  if (splits != nullptr) *splits = split;
  return clusters;
}

std::vector<ObjectPose> EstimateObjectPoses(const std::vector<Eigen::Vector3d>& points_in_world,
                                            const std::vector<std::vector<int>>& clusters,
                                            const ObjectPoseOptions& options) {
  std::vector<ObjectPose> poses;
  for (const auto& cluster : clusters) {
    if (!cluster.empty()) poses.push_back(EstimateObjectPose(points_in_world, cluster, options));
  }
  std::stable_sort(poses.begin(), poses.end(), [](const ObjectPose& a, const ObjectPose& b) {
    return a.height_mm > b.height_mm;
  });
  return poses;
}

}  // namespace hnnstereo::vision
