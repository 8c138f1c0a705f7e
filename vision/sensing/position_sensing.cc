#include "vision/sensing/position_sensing.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "calib/epipolar.h"
#include "vision/stereo/correlation.h"
#include "vision/stereo/lens_matching.h"
#include "vision/stereo/setup_checks.h"
#include "vision/sensing/triangulation.h"
#include "common/timing.h"

namespace hnnstereo::vision {
namespace {

// Points of other parts count for ObjectPose::touching_points from this height (mm) up: a
// part's own base edge and the table lie below it.
constexpr double kTouchMinHeightMm = 5.0;

using common::MillisecondsSince;

// ObjectPose::points_above_top: the strong points of a pose's own cluster more than
// `top_layer_mm` above its top. ObjectPose::touching_points: the strong points of the other
// poses' clusters, at least `min_height_mm` above the table (a part's own base edge lies at the
// table), that lie within `reach_mm` of its top face's rectangle in the table plane, or that
// stand more than `top_layer_mm` above its top and whose ray from either camera centre crosses
// the plane of its top within `reach_mm` of that rectangle: a taller neighbour that hides part
// of the top from a camera cuts the rectangle short of the neighbour's points.
// ObjectPose::taller_touching_points: those of the former (within `reach_mm` in the table
// plane) that stand more than `top_layer_mm` above its top.
void CountTouchingPoints(const std::vector<Eigen::Vector3d>& points, const std::vector<bool>& weak,
                         const std::vector<Eigen::Vector3d>& camera_centres, double reach_mm,
                         double min_height_mm, double top_layer_mm,
                         std::vector<ObjectPose>* poses) {
  std::vector<int> owner(points.size(), -1);
  for (std::size_t a = 0; a < poses->size(); ++a) {
    for (int i : (*poses)[a].point_indices) {
      owner[static_cast<std::size_t>(i)] = static_cast<int>(a);
    }
  }
  for (std::size_t a = 0; a < poses->size(); ++a) {
    ObjectPose& pose = (*poses)[a];
    const Rectangle2D& r = pose.top_rectangle;
    const double angle = r.yaw_deg * std::numbers::pi / 180.0;
    const Eigen::Vector2d along(std::cos(angle), std::sin(angle));
    const Eigen::Vector2d across(-along.y(), along.x());
    const auto near_rectangle = [&](const Eigen::Vector2d& xy) {
      const Eigen::Vector2d d = xy - r.centre;
      return std::abs(d.dot(along)) <= 0.5 * r.length + reach_mm &&
             std::abs(d.dot(across)) <= 0.5 * r.width + reach_mm;
    };
    const double top = pose.height_mm;
    pose.touching_points = 0;
    pose.points_above_top = 0;
    pose.taller_touching_points = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (owner[i] == static_cast<int>(a) && !weak[i] && points[i].z() > top + top_layer_mm) {
        ++pose.points_above_top;
      }
      // Only other parts' points: strong points that joined no part lie all around every part
      // (its sides, mismatches), touching or not.
      if (owner[i] < 0 || owner[i] == static_cast<int>(a) || weak[i] ||
          points[i].z() < min_height_mm) {
        continue;
      }
      bool near = near_rectangle(points[i].head<2>());
      const bool beside = near;  // in the table plane, not by a ray
      const bool above = points[i].z() > top + top_layer_mm;
      for (std::size_t c = 0; !near && above && c < camera_centres.size(); ++c) {
        // Where the ray from camera c through the point meets the plane z = top.
        const Eigen::Vector3d& C = camera_centres[c];
        if (!(C.z() > points[i].z())) continue;
        const double t = (top - C.z()) / (points[i].z() - C.z());
        near = near_rectangle((C + t * (points[i] - C)).head<2>());
      }
      if (near) ++pose.touching_points;
      if (beside && above) ++pose.taller_touching_points;
    }
  }
}

// The four corners of `r` in the table plane.
std::vector<Eigen::Vector2d> Corners(const Rectangle2D& r) {
  const double yaw = r.yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d along = 0.5 * r.length * Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d across = 0.5 * r.width * Eigen::Vector2d(-std::sin(yaw), std::cos(yaw));
  return {r.centre - along - across, r.centre + along - across, r.centre + along + across,
          r.centre - along + across};
}

// Distance (mm) between two rectangles in the table plane: 0 when they overlap, else the
// smallest distance from a corner of one to the other (two disjoint convex polygons are
// closest at a vertex of one of them).
double RectangleGap(const Rectangle2D& a, const Rectangle2D& b) {
  const auto rotated = [](const Rectangle2D& r) {
    return cv::RotatedRect(cv::Point2f(static_cast<float>(r.centre.x()), static_cast<float>(r.centre.y())),
                           cv::Size2f(static_cast<float>(r.length), static_cast<float>(r.width)),
                           static_cast<float>(r.yaw_deg));
  };
  std::vector<cv::Point2f> overlap;
  if (cv::rotatedRectangleIntersection(rotated(a), rotated(b), overlap) != cv::INTERSECT_NONE) {
    return 0.0;
  }
  // Disjoint: every corner lies outside the other rectangle.
  double gap = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& p : Corners(a)) gap = std::min(gap, DistanceToRectangleOutline(b, p));
  for (const Eigen::Vector2d& p : Corners(b)) gap = std::min(gap, DistanceToRectangleOutline(a, p));
  return gap;
}

// The table-plane rectangle that `pose`'s top face fills: its top rectangle, or its circle's
// square when round.
Rectangle2D TopFootprint(const ObjectPose& pose) {
  if (!pose.round) return pose.top_rectangle;
  const double diameter = 2.0 * pose.circle_radius;
  return Rectangle2D{pose.circle_centre, diameter, diameter, 0.0};
}

// The outline of `pose`'s top face in the table plane, counter-clockwise: its rectangle's
// corners, or 32 points of its circle when round.
std::vector<Eigen::Vector2d> TopOutline(const ObjectPose& pose) {
  if (!pose.round) return Corners(pose.top_rectangle);
  constexpr int kCirclePoints = 32;
  std::vector<Eigen::Vector2d> outline;
  for (int k = 0; k < kCirclePoints; ++k) {
    const double angle = 2.0 * std::numbers::pi * k / kCirclePoints;
    outline.push_back(pose.circle_centre +
                      pose.circle_radius * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
  }
  return outline;
}

// Distance (mm) along the ray from `origin` in direction `direction` (unit) to where it enters
// the convex polygon `polygon` (counter-clockwise, table plane); +infinity when it misses it,
// 0 when it starts inside. Cyrus-Beck clipping.
double RayEntryIntoConvexPolygon(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction,
                                 const std::vector<Eigen::Vector2d>& polygon) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  double enter = 0.0, leave = kInfinity;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d edge = polygon[(i + 1) % polygon.size()] - polygon[i];
    const Eigen::Vector2d outward(edge.y(), -edge.x());  // counter-clockwise polygon
    const double distance = outward.dot(origin - polygon[i]);  // > 0: outside this edge
    const double rate = outward.dot(direction);
    if (rate == 0.0) {
      if (distance > 0.0) return kInfinity;
      continue;
    }
    const double t = -distance / rate;
    if (rate < 0.0) {
      enter = std::max(enter, t);
    } else {
      leave = std::min(leave, t);
    }
  }
  return enter <= leave ? enter : kInfinity;
}

// ObjectPose::shadow_strip_mm of a box top: per side, rays every 1 mm along the side (2 mm
// from the corners) go outward to the nearest taller part's top outline (more than
// `top_layer_mm` above this top; a part's walls stand under its outline) within
// `max_strip_mm`. When at least half of them reach one, more than 2 mm out (median), the
// strip between is empty if at most `max_points` strong points at any height lie in it (more
// than 1 mm from both). The widest such strip's median width; 0 when none.
double EmptyStripToTallerPart(const std::vector<ObjectPose>& poses, std::size_t self,
                              const std::vector<Eigen::Vector3d>& points,
                              const std::vector<bool>& weak, double top_layer_mm,
                              double max_strip_mm, int max_points) {
  const ObjectPose& pose = poses[self];
  const Rectangle2D& r = pose.top_rectangle;
  const double yaw = r.yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d along(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d across(-along.y(), along.x());
  std::vector<std::vector<Eigen::Vector2d>> taller;
  for (std::size_t b = 0; b < poses.size(); ++b) {
    if (b != self && poses[b].height_mm > pose.height_mm + top_layer_mm) {
      taller.push_back(TopOutline(poses[b]));
    }
  }
  if (taller.empty()) return 0.0;
  double widest = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d outward = (k % 2 == 0 ? 1.0 : -1.0) * (k < 2 ? along : across);
    const Eigen::Vector2d lateral = k < 2 ? across : along;
    const double half_out = 0.5 * (k < 2 ? r.length : r.width);
    const double half_side = 0.5 * (k < 2 ? r.width : r.length) - 2.0;
    if (half_side <= 0.0) continue;
    std::vector<double> widths;  // per ray that meets a taller part in reach
    int rays = 0;
    double lateral_min = std::numeric_limits<double>::infinity(), lateral_max = -lateral_min;
    for (double l = -half_side; l <= half_side; l += 1.0, ++rays) {
      const Eigen::Vector2d origin = r.centre + half_out * outward + l * lateral;
      double nearest = std::numeric_limits<double>::infinity();
      for (const auto& outline : taller) {
        nearest = std::min(nearest, RayEntryIntoConvexPolygon(origin, outward, outline));
      }
      if (nearest <= max_strip_mm) {
        widths.push_back(nearest);
        lateral_min = std::min(lateral_min, l);
        lateral_max = std::max(lateral_max, l);
      }
    }
    if (widths.empty() || 2 * static_cast<int>(widths.size()) < rays) continue;
    std::nth_element(widths.begin(), widths.begin() + widths.size() / 2, widths.end());
    const double width = widths[widths.size() / 2];
    if (width <= 2.0) continue;  // nothing between them
    int inside = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (weak[i]) continue;
      const Eigen::Vector2d d = points[i].head<2>() - r.centre;
      const double out = d.dot(outward) - half_out, side = d.dot(lateral);
      if (out > 1.0 && out < width - 1.0 && side >= lateral_min && side <= lateral_max) ++inside;
    }
    if (inside <= max_points) widest = std::max(widest, width);
  }
  return widest;
}

// Whether the outline of `pose`'s top face - its rectangle's corners, or 32 points of its
// circle when round - at its height projects within `margin_px` of the border of either image
// (of `image_size`; captured through `lens` when not null), or beyond it.
bool OutlineNearImageBorder(const ObjectPose& pose, const calib::StereoCalibration& calibration,
                            const StereoLens* lens, const cv::Size& image_size, double margin_px) {
  const std::vector<Eigen::Vector2d> outline = TopOutline(pose);
  for (int camera = 0; camera < 2; ++camera) {
    const calib::ProjectionMatrix& P = camera == 0 ? calibration.P1 : calibration.P2;
    for (const Eigen::Vector2d& xy : outline) {
      const Eigen::Vector3d x = P * Eigen::Vector4d(xy.x(), xy.y(), pose.height_mm, 1.0);
      if (!(x.z() > 0.0)) return true;  // behind the camera: not in view
      Eigen::Vector2d uv = x.hnormalized();
      // Through a lens (point route) the border is the captured image's.
      if (lens != nullptr) uv = (camera == 0 ? lens->left : lens->right).Distort(uv);
      const double u = uv.x(), v = uv.y();
      // Pixel centres run from 0 to cols - 1 (OpenCV convention).
      if (!(u >= margin_px && v >= margin_px && u <= image_size.width - 1 - margin_px &&
            v <= image_size.height - 1 - margin_px)) {
        return true;
      }
    }
  }
  return false;
}

}  // namespace

MatcherOptions PickCellMatcherOptions() {
  MatcherOptions options;
  options.features.detector = FeatureDetector::kCanny;
  options.candidates.rectified = false;
  options.candidates.max_epipolar_distance_px = 2.0;
  options.candidates.z_range_mm = std::make_pair(-5.0, 200.0);
  options.candidates.top_k = 8;
  options.energy.support_radius_px = 8.0;
  // hnn-default's objective (geometric consistency times similarity, docs/accuracy.md) and
  // dynamics (the decisions stop rule: on the stress scenes it senses as the energy rule does,
  // in less time; docs/sensing.md), taken from the preset so that a change of it reaches `pick`
  // and `serve` (tests/vision/pick_cell_settings_test.cc).
  const MatcherPreset preset = AccurateDefaultPreset();
  options.energy.objective = preset.matcher.energy.objective;
  options.dynamics = preset.matcher.dynamics;
  // The dusty table gives thousands of edge points that all lie at z = 0; the cap (kept spread
  // over the image) bounds the epipolar gating, which dominates the time.
  options.features.max_features = 4000;
  return options;
}

RefinementOptions PickCellRefinementOptions() {
  RefinementOptions options;
  options.epipolar_snap = true;
  options.epipolar_subpixel = true;
  return options;
}

PositionSensingOptions PositionSensingOptions::ScaledForImage(const cv::Size& size) const {
  PositionSensingOptions scaled = *this;
  if (reference_image_width_px <= 0 || size.width <= reference_image_width_px) return scaled;
  const double s = static_cast<double>(size.width) / reference_image_width_px;
  scaled.image_border_px = image_border_px * s;
  if (matcher.features.max_features > 0) {
    const double cap = matcher.features.max_features * std::pow(s, feature_cap_exponent);
    scaled.matcher.features.max_features = static_cast<int>(std::lround(cap));
    const double points = std::pow(s, 0.5 * feature_cap_exponent);
    scaled.min_strong_points = static_cast<int>(std::lround(min_strong_points * points));
    scaled.min_strong_points_whole_top =
        static_cast<int>(std::lround(min_strong_points_whole_top * points));
  }
  return scaled;
}

std::string PositionSensingOptions::Check() const {
  if (std::string problem = matcher.Check(); !problem.empty()) return problem;
  if (matcher.candidates.rectified) {
    return "position sensing needs a calibrated, unrectified pair (candidates.rectified is set)";
  }
  if (!(min_edge_epipolar_angle_deg >= 0.0 && min_edge_epipolar_angle_deg < 90.0)) {
    return "min_edge_epipolar_angle_deg must be in [0, 90)";
  }
  if (min_strong_points < 1) return "min_strong_points must be >= 1";
  if (min_strong_points_whole_top < 0) return "min_strong_points_whole_top must be >= 0";
  if (!(min_top_fraction >= 0.0 && min_top_fraction <= 1.0)) return "min_top_fraction must be in [0, 1]";
  if (!(min_top_width_mm >= 0.0)) return "min_top_width_mm must be >= 0";
  if (!(min_top_fill >= 0.0 && min_top_fill <= 1.0)) return "min_top_fill must be in [0, 1]";
  if (!(min_round_top_fill >= 0.0 && min_round_top_fill <= 1.0)) {
    return "min_round_top_fill must be in [0, 1]";
  }
  if (!(touch_reach_mm >= 0.0)) return "touch_reach_mm must be >= 0";
  if (touch_min_points < 1) return "touch_min_points must be >= 1";
  if (min_points_above_top < 0) return "min_points_above_top must be >= 0";
  if (!(min_touching_top_fill >= 0.0 && min_touching_top_fill <= 1.0)) {
    return "min_touching_top_fill must be in [0, 1]";
  }
  if (!(min_whole_top_width_mm >= 0.0)) return "min_whole_top_width_mm must be >= 0";
  if (!(max_whole_top_length_mm >= 0.0)) return "max_whole_top_length_mm must be >= 0";
  if (!(left_out_piece_reach_mm >= 0.0)) return "left_out_piece_reach_mm must be >= 0";
  if (!(shadow_strip_reach_mm >= 0.0)) return "shadow_strip_reach_mm must be >= 0";
  if (max_shadow_strip_points < 0) return "max_shadow_strip_points must be >= 0";
  if (!(max_round_top_roundness >= 0.0)) return "max_round_top_roundness must be >= 0";
  if (min_taller_touching_points < 0) return "min_taller_touching_points must be >= 0";
  if (!(image_border_px >= 0.0 && std::isfinite(image_border_px))) {
    return "image_border_px must be >= 0";
  }
  if (!(max_reprojection_error_px > 0.0)) {
    std::ostringstream out;
    out << "max_reprojection_error_px must be positive (is " << max_reprojection_error_px << ")";
    return out.str();
  }
  if (reference_image_width_px < 0) return "reference_image_width_px must be >= 0 (0: no scaling)";
  if (!(feature_cap_exponent >= 0.0 && feature_cap_exponent <= 2.0)) {
    return "feature_cap_exponent must be in [0, 2]";
  }
  if (std::string problem = top_edges.Check(); !problem.empty()) return problem;
  if (std::string problem = refinement.Check(); !problem.empty()) return problem;
  if (refinement.subpixel) return "refinement.subpixel is for rectified pairs: use epipolar_subpixel";
  if (std::string problem = grid.Check(); !problem.empty()) return problem;
  if (std::string problem = leader.Check(); !problem.empty()) return problem;
  return pose.Check();
}

namespace {

// The left image's 3 x 3 Sobel gradients, taken once, when the first stage needs them (the
// edge-angle test, the island joins' image veto, the image fit), in the pixels P1 projects to:
// through the point route's `lens` (`grey` as captured, P1 in undistorted pixels) they are the
// captured image's, looked up per undistorted pixel (GradientsPerUndistortedPixel); null: the
// image's own.
struct LeftGradients {
  const cv::Mat& grey;
  const StereoLens* lens;
  cv::Mat x, y;

  void Need() {
    if (!x.empty()) return;
    cv::Sobel(grey, x, CV_32F, 1, 0, 3);
    cv::Sobel(grey, y, CV_32F, 0, 1, 3);
    if (lens != nullptr) GradientsPerUndistortedPixel(x, y, lens->left, &x, &y);
  }
};

// Whether the left image's edge at a match runs within asin(min_sine) of its epipolar line:
// sin(angle between edge and line) = |gradient . line direction| / |gradient|, with the left
// epipolar line of the right point l1 = F^T x2 (H&Z 9.2). Such a match's depth is uncertain
// along the edge (PositionSensingOptions::min_edge_epipolar_angle_deg).
bool EdgeAlongEpipolar(const StereoMatch& stereo_match, const LeftGradients& gradients,
                       const Eigen::Matrix3d& F, double min_sine) {
  const cv::Mat& grey = gradients.grey;
  const int u = std::clamp(static_cast<int>(std::lround(stereo_match.left.x())), 0, grey.cols - 1);
  const int v = std::clamp(static_cast<int>(std::lround(stereo_match.left.y())), 0, grey.rows - 1);
  const Eigen::Vector2d gradient(gradients.x.at<float>(v, u), gradients.y.at<float>(v, u));
  const Eigen::Vector3d line = F.transpose() * stereo_match.right.cast<double>().homogeneous();
  const Eigen::Vector2d direction = Eigen::Vector2d(line.y(), -line.x()).normalized();
  return gradient.norm() > 0.0 && direction.allFinite() &&
         std::abs(gradient.dot(direction)) < min_sine * gradient.norm();
}

// Stage 1: linear triangulation of every match from both P (thesis 6.2.9); rejects degenerate,
// behind-camera and large-residual points and marks the weak ones (edge along the epipolar line).
void TriangulateMatches(const calib::StereoCalibration& calibration,
                        const PositionSensingOptions& options, LeftGradients* gradients,
                        PositionSensingReport* report) {
  double residual_sum = 0.0;
  const bool test_edges = options.min_edge_epipolar_angle_deg > 0.0 && !gradients->grey.empty();
  if (test_edges) gradients->Need();
  const double min_sine = std::sin(options.min_edge_epipolar_angle_deg * std::numbers::pi / 180.0);
  for (std::size_t m = 0; m < report->match.matches.size(); ++m) {
    const StereoMatch& stereo_match = report->match.matches[m];
    const bool weak = test_edges && EdgeAlongEpipolar(stereo_match, *gradients, calibration.F, min_sine);
    const auto point = TriangulateLinear(calibration.P1, calibration.P2,
                                         stereo_match.left.cast<double>(),
                                         stereo_match.right.cast<double>());
    if (!point) {
      ++report->triangulation.degenerate;
    } else if (!point->in_front) {
      ++report->triangulation.behind_camera;
    } else if (!(point->reprojection_error_px <= options.max_reprojection_error_px)) {
      ++report->triangulation.large_residual;
    } else {
      report->points_in_world.push_back(point->point_in_world);
      report->match_of_point.push_back(static_cast<int>(m));
      report->reprojection_error_px.push_back(point->reprojection_error_px);
      report->weak.push_back(weak);
      if (weak) ++report->triangulation.edge_along_epipolar;
      residual_sum += point->reprojection_error_px;
    }
  }
  report->triangulation.accepted = static_cast<int>(report->points_in_world.size());
  if (report->triangulation.accepted > 0) {
    report->triangulation.mean_residual_px = residual_sum / report->triangulation.accepted;
  }
}

// The pose options of the clustering method: the thesis's leader clustering takes the centroid
// as the cluster's mean and the yaw from central moments.
ObjectPoseOptions PoseOptionsFor(const PositionSensingOptions& options) {
  ObjectPoseOptions pose_options = options.pose;
  if (options.clustering == ClusteringMethod::kThesisLeader) {
    pose_options.centroid_from_rectangle = false;
    pose_options.yaw_method = YawMethod::kCentralMoments;
  }
  return pose_options;
}

// Poses come from the strong points only (weak ones joined the clustering): a cluster with at
// least min(10, size) strong points drops its weak ones (labelled -1).
void KeepStrongPoints(PositionSensingReport* report) {
  for (auto& cluster : report->clustering.clusters) {
    std::vector<int> strong;
    for (int i : cluster) {
      if (!report->weak[static_cast<std::size_t>(i)]) strong.push_back(i);
    }
    if (static_cast<int>(strong.size()) >= std::min<int>(10, static_cast<int>(cluster.size()))) {
      for (int i : cluster) {
        if (report->weak[static_cast<std::size_t>(i)]) report->clustering.labels[static_cast<std::size_t>(i)] = -1;
      }
      cluster = std::move(strong);
    }
  }
}

// The veto on joining two top-face islands (MergeTopFaceIslands' PiecesSeenApart): two pieces
// whose joint top would be longer than any part are two parts (`too_long`), and so are two
// pieces the left image shows an edge between along their sides but not across their ends
// (`look`, LookAcrossGap).
struct IslandsSeenApart {
  const PositionSensingOptions& options;
  const calib::ProjectionMatrix& P1;
  const LeftGradients& gradients;
  bool look = false;
  bool too_long = false;

  bool operator()(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b,
                  double height) const {
    if (too_long) {
      std::vector<Eigen::Vector2d> joint = a;
      joint.insert(joint.end(), b.begin(), b.end());
      if (MinAreaRectangle(joint).length > options.max_whole_top_length_mm) return true;
    }
    if (!look) return false;
    const std::optional<GapBetweenPieces> gap =
        LookAcrossGap(a, b, height, P1, gradients.x, gradients.y, options.top_edges);
    return gap && gap->sides_support < options.top_edges.min_side_support &&
           gap->ends_support >= options.top_edges.min_end_support;
  }
};

// Stage 3 (grid clustering only): joins the islands of one top face, splits touching parts of
// unequal height the grid joined (never a pose between them), and relabels the points.
void RefineGridClusters(const calib::StereoCalibration& calibration,
                        const PositionSensingOptions& options, const ObjectPoseOptions& pose_options,
                        LeftGradients* gradients, PositionSensingReport* report) {
  if (options.merge_top_face_islands) {
    PiecesSeenApart seen_apart = nullptr;
    const bool look = options.join_islands_seen_as_one_face && !gradients->grey.empty();
    const bool too_long =
        options.keep_apart_longer_than_any_part && options.max_whole_top_length_mm > 0.0;
    if (look) gradients->Need();
    if (look || too_long) {
      seen_apart = IslandsSeenApart{options, calibration.P1, *gradients, look, too_long};
    }
    report->clustering.clusters =
        MergeTopFaceIslands(report->points_in_world, report->clustering.clusters, pose_options,
                            &report->island_merges, &report->weak, seen_apart);
  }
  report->clustering.clusters = SplitTopLevels(report->points_in_world, report->clustering.clusters,
                                               pose_options, &report->top_level_splits);
  std::fill(report->clustering.labels.begin(), report->clustering.labels.end(), -1);
  for (std::size_t c = 0; c < report->clustering.clusters.size(); ++c) {
    for (int i : report->clustering.clusters[c]) {
      report->clustering.labels[static_cast<std::size_t>(i)] = static_cast<int>(c);
    }
  }
}

// Stage 4: drops clusters too small, without a top face, narrower than min_top_width_mm, or a
// line across parts (longer than any part, narrower than any). A small cluster is kept for now
// when it may be a whole top face (dropped later if flagged); the counts are of clusters at
// least min_strong_points strong. Returns the poses of the narrow pieces dropped (for
// piece_left_out).
std::vector<ObjectPose> DropSmallClusters(const PositionSensingOptions& options,
                                          const ObjectPoseOptions& pose_options,
                                          PositionSensingReport* report) {
  std::vector<ObjectPose> narrow_pieces;
  std::erase_if(report->clustering.clusters, [&](const std::vector<int>& cluster) {
    const bool below = static_cast<int>(cluster.size()) < options.min_strong_points;
    bool small = below && !(options.min_strong_points_whole_top > 0 &&
                            static_cast<int>(cluster.size()) >= options.min_strong_points_whole_top);
    if (!small && (options.min_top_fraction > 0.0 || options.min_top_width_mm > 0.0)) {
      ObjectPose pose = EstimateObjectPose(report->points_in_world, cluster, pose_options);
      if (pose.top_points < options.min_top_fraction * pose.points) {
        small = true;
        if (!below) ++report->without_top_face;
      } else if (pose.top_rectangle.width < options.min_top_width_mm) {
        small = true;
        if (!below) {
          ++report->narrow_top_face;
          narrow_pieces.push_back(std::move(pose));
        }
      } else if (options.max_whole_top_length_mm > 0.0 &&
                 pose.top_rectangle.length > options.max_whole_top_length_mm &&
                 pose.top_rectangle.width < options.min_whole_top_width_mm) {
        small = true;
        if (!below) ++report->narrow_top_face;
      }
    }
    if (small) {
      report->clustering.n_in_small_clusters += static_cast<int>(cluster.size());
      for (int i : cluster) report->clustering.labels[static_cast<std::size_t>(i)] = -1;
    }
    return small;
  });
  return narrow_pieces;
}

// Sets ObjectPose::merged from the pose's own shape and its neighbours' points: a partial or
// joined top (fill, roundness), a neighbour's points beside it, a taller part beside it, a
// sliver, a top longer than any part, a left-out narrow piece at its height beside it, a top
// cut by the field of view (PositionSensingOptions documents each threshold).
void FlagPose(const calib::StereoCalibration& calibration, const PositionSensingOptions& options,
              const ObjectPoseOptions& pose_options, const LeftGradients& gradients,
              const std::vector<ObjectPose>& narrow_pieces, ObjectPose* pose_out) {
  const cv::Mat& left_grey = gradients.grey;
  ObjectPose& pose = *pose_out;
  // A disc fills pi / 4 of its square: a top whose hull is near a circle is no merge.
  pose.merged = !pose.round && pose.top_fill < options.min_top_fill &&
                (pose.top_roundness > options.max_round_top_roundness ||
                 pose.top_fill < options.min_round_top_fill);
  // Beside a neighbour, only a full rectangle (or a round top) is trusted.
  const bool touching =
      pose.touching_points >= options.touch_min_points ||
      (options.min_points_above_top > 0 && pose.points_above_top >= options.min_points_above_top);
  if (!pose.round && touching && pose.top_fill < options.min_touching_top_fill) {
    pose.merged = true;
  }
  // A taller part touching a box hides a strip of its top from the camera on its side; cut
  // straight, the rest is still a full rectangle.
  if (!pose.round && options.min_taller_touching_points > 0 &&
      pose.taller_touching_points >= options.min_taller_touching_points) {
    pose.merged = true;
  }
  // A sliver of a face (a disc seen along a short arc, one edge of a box) is no face.
  if (!pose.round && pose.top_rectangle.width < options.min_whole_top_width_mm) {
    pose.merged = true;
  }
  // A top longer than any part is parts joined.
  if (options.max_whole_top_length_mm > 0.0 &&
      pose.top_rectangle.length > options.max_whole_top_length_mm) {
    pose.merged = true;
  }
  // A line of points at this top's height beside it, left out as too narrow to be a part,
  // may be a piece of this top the island merge did not join.
  for (const ObjectPose& piece : narrow_pieces) {
    if (options.left_out_piece_reach_mm > 0.0 &&
        std::abs(piece.height_mm - pose.height_mm) <= pose_options.top_layer_mm &&
        RectangleGap(piece.top_rectangle, pose.top_rectangle) <= options.left_out_piece_reach_mm) {
      pose.piece_left_out = true;
      pose.merged = true;
    }
  }
  // A top cut by the field of view is a piece of a face.
  if (options.image_border_px > 0.0 && !left_grey.empty()) {
    pose.at_image_border =
        OutlineNearImageBorder(pose, calibration, gradients.lens, left_grey.size(),
                               options.image_border_px);
    if (pose.at_image_border) pose.merged = true;
  }
}

// A sliver reported at a top's height beside it (flagged as narrower than any part) may be a
// piece of that top the island merge did not join, as a left-out line is: flags the top.
void FlagTopsBesideSlivers(const PositionSensingOptions& options,
                           const ObjectPoseOptions& pose_options, PositionSensingReport* report) {
  for (std::size_t a = 0; options.flag_tops_beside_slivers && a < report->objects.size(); ++a) {
    ObjectPose& pose = report->objects[a];
    if (pose.merged) continue;
    for (std::size_t b = 0; b < report->objects.size(); ++b) {
      const ObjectPose& piece = report->objects[b];
      if (b == a || piece.round || piece.top_rectangle.width >= options.min_whole_top_width_mm ||
          std::abs(piece.height_mm - pose.height_mm) > pose_options.max_split_height_difference_mm ||
          RectangleGap(piece.top_rectangle, TopFootprint(pose)) > options.left_out_piece_reach_mm) {
        continue;
      }
      pose.piece_left_out = true;
      pose.merged = true;
      ++report->merged;
      break;
    }
  }
}

// Fits each box top to the left image's edges (ExtendTopToImageEdges, TurnTopToImageEdges),
// keeping out of the other parts' tops (a round one as its circle's square); flags a top with a
// side the fit could not place when flag_unplaced_sides.
void FitTopsToImageEdges(const calib::StereoCalibration& calibration,
                         const PositionSensingOptions& options,
                         const ObjectPoseOptions& pose_options, const LeftGradients& gradients,
                         PositionSensingReport* report) {
  const std::vector<Eigen::Vector3d> camera_centres = {calibration.C1, calibration.C2};
  for (std::size_t a = 0; a < report->objects.size(); ++a) {
    std::vector<Rectangle2D> others;
    for (std::size_t b = 0; b < report->objects.size(); ++b) {
      if (b == a) continue;
      others.push_back(TopFootprint(report->objects[b]));
    }
    const double max_length = options.max_whole_top_length_mm > 0.0
                                  ? options.max_whole_top_length_mm
                                  : std::numeric_limits<double>::infinity();
    const TopFaceEdgeReport extension = ExtendTopToImageEdges(
        &report->objects[a],
        {calibration.P1, gradients.x, gradients.y, others, report->points_in_world, report->weak,
         camera_centres, pose_options.top_layer_mm, max_length,
         pose_options.centroid_from_rectangle},
        options.top_edges);
    report->objects[a].image_edge_moved_mm = extension.moved_mm();
    TurnTopToImageEdges(&report->objects[a], calibration.P1, gradients.x, gradients.y,
                        pose_options.yaw_method == YawMethod::kMinAreaRectangle, options.top_edges);
    report->objects[a].unplaced_sides = extension.unplaced_sides;
    if (options.flag_unplaced_sides && extension.unplaced_sides > 0 && !report->objects[a].merged) {
      report->objects[a].merged = true;
      ++report->merged;
    }
  }
}

// Flags a box whose top has an empty strip between a side and a taller part (the taller part's
// shadow may hide the rest of its top; EmptyStripToTallerPart).
void FlagShadowStrips(const PositionSensingOptions& options, const ObjectPoseOptions& pose_options,
                      PositionSensingReport* report) {
  for (std::size_t a = 0; options.shadow_strip_reach_mm > 0.0 && a < report->objects.size(); ++a) {
    ObjectPose& pose = report->objects[a];
    if (pose.round) continue;
    pose.shadow_strip_mm = EmptyStripToTallerPart(
        report->objects, a, report->points_in_world, report->weak, pose_options.top_layer_mm,
        options.shadow_strip_reach_mm, options.max_shadow_strip_points);
    if (pose.shadow_strip_mm > 0.0 && !pose.merged) {
      pose.merged = true;
      ++report->merged;
    }
  }
}

// Drops every flagged part below min_strong_points (its points become small-cluster points).
// Returns whether any was dropped, so that the poses are estimated again without it.
bool DropFlaggedSmallParts(const PositionSensingOptions& options, PositionSensingReport* report) {
  bool dropped = false;
  for (const ObjectPose& pose : report->objects) {
    if (pose.points >= options.min_strong_points || !pose.merged) continue;
    ++report->small_flagged;
    report->clustering.n_in_small_clusters += pose.points;
    for (int i : pose.point_indices) report->clustering.labels[static_cast<std::size_t>(i)] = -1;
    std::erase_if(report->clustering.clusters, [&](const std::vector<int>& cluster) {
      return !cluster.empty() && !pose.point_indices.empty() &&
             cluster.front() == pose.point_indices.front();
    });
    dropped = true;
  }
  return dropped;
}

// Stage 5: the poses and their flags. A part below min_strong_points is reported only when no
// check flags it; one that is flagged is dropped and the poses are estimated again without it,
// so that its points flag no neighbour (touching points, the image fit's blocking).
void EstimateAndFlagPoses(const calib::StereoCalibration& calibration,
                          const PositionSensingOptions& options,
                          const ObjectPoseOptions& pose_options,
                          const std::vector<ObjectPose>& narrow_pieces, LeftGradients* gradients,
                          PositionSensingReport* report) {
  const cv::Mat& left_grey = gradients->grey;
  for (bool again = true; again;) {
    report->merged = 0;
    report->objects =
        EstimateObjectPoses(report->points_in_world, report->clustering.clusters, pose_options);
    CountTouchingPoints(report->points_in_world, report->weak,
                        {calibration.C1, calibration.C2},
                        options.touch_reach_mm, kTouchMinHeightMm, pose_options.top_layer_mm,
                        &report->objects);
    for (ObjectPose& pose : report->objects) {
      FlagPose(calibration, options, pose_options, *gradients, narrow_pieces, &pose);
      if (pose.merged) ++report->merged;
    }
    FlagTopsBesideSlivers(options, pose_options, report);
    if (options.extend_tops_to_image_edges && !left_grey.empty()) {
      gradients->Need();
      FitTopsToImageEdges(calibration, options, pose_options, *gradients, report);
    }
    FlagShadowStrips(options, pose_options, report);
    again = DropFlaggedSmallParts(options, report);
  }
}

}  // namespace

namespace {

// SensePositionsFromMatches with `options` already scaled to the images (ScaledForImage).
// `lens`: the point route's (matches in undistorted pixels, `left_grey` as captured), or null.
PositionSensingReport SenseScaledFromMatches(MatchReport match,
                                             const calib::StereoCalibration& calibration,
                                             const PositionSensingOptions& options,
                                             const cv::Mat& left_grey, const StereoLens* lens) {
  if (const std::string problem = calibration.Check(); !problem.empty()) {
    throw std::invalid_argument("calibration: " + problem);
  }
  // The rig every stage reads: the camera centres derived here, once, from P1 and P2 (a
  // calibration built by hand may not have filled C1, C2).
  calib::StereoCalibration rig = calibration;
  rig.C1 = calib::CameraCentre(rig.P1);
  rig.C2 = calib::CameraCentre(rig.P2);
  PositionSensingReport report;
  report.match = std::move(match);
  report.timing_ms.match = report.match.timing_ms.total;
  LeftGradients gradients{left_grey, lens, {}, {}};

  auto start = std::chrono::steady_clock::now();
  TriangulateMatches(rig, options, &gradients, &report);
  report.timing_ms.triangulate = MillisecondsSince(start);

  start = std::chrono::steady_clock::now();
  report.clustering = options.clustering == ClusteringMethod::kGrid
                          ? ClusterOnGrid(report.points_in_world, options.grid)
                          : ClusterByHeightLeader(report.points_in_world, options.leader);
  report.timing_ms.cluster = MillisecondsSince(start);

  start = std::chrono::steady_clock::now();
  const ObjectPoseOptions pose_options = PoseOptionsFor(options);
  KeepStrongPoints(&report);
  if (options.clustering == ClusteringMethod::kGrid) {
    RefineGridClusters(rig, options, pose_options, &gradients, &report);
  }
  const std::vector<ObjectPose> narrow_pieces = DropSmallClusters(options, pose_options, &report);
  EstimateAndFlagPoses(rig, options, pose_options, narrow_pieces, &gradients, &report);
  report.timing_ms.pose = MillisecondsSince(start);
  report.timing_ms.total = report.timing_ms.match + report.timing_ms.triangulate +
                           report.timing_ms.cluster + report.timing_ms.pose;
  return report;
}

// What the options were scaled by, for the report.
void NoteScale(const PositionSensingOptions& scaled, const cv::Size& size,
               PositionSensingReport* report) {
  if (scaled.reference_image_width_px > 0 && size.width > scaled.reference_image_width_px) {
    report->image_scale = static_cast<double>(size.width) / scaled.reference_image_width_px;
  }
  report->max_features = scaled.matcher.features.max_features;
}

// Match, refine and sense a pair with the options scaled to it; through `lens` (the point
// route: the images as captured) when not null.
PositionSensingReport SenseOnImages(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                    const calib::StereoCalibration& calibration,
                                    const PositionSensingOptions& scaled,
                                    const std::shared_ptr<const StereoLens>& lens,
                                    ocl::Runtime* runtime) {
  const MatcherOptions matcher =
      lens ? MatcherThroughLens(scaled.matcher, left_grey, right_grey, lens) : scaled.matcher;
  MatchReport match = MatchStereo(left_grey, right_grey, &calibration, matcher, runtime);
  const auto start = std::chrono::steady_clock::now();
  if (lens) {
    RefineMatchesThroughLens(left_grey, right_grey, calibration, matcher, scaled.refinement, *lens,
                             &match);
  } else {
    RefineMatches(left_grey, right_grey, &calibration, matcher, scaled.refinement, &match);
  }
  const double refine_ms = MillisecondsSince(start);
  PositionSensingReport report =
      SenseScaledFromMatches(std::move(match), calibration, scaled, left_grey, lens.get());
  NoteScale(scaled, left_grey.size(), &report);
  report.timing_ms.refine = refine_ms;
  report.timing_ms.total += refine_ms;
  return report;
}

}  // namespace

PositionSensingReport SensePositionsFromMatches(MatchReport match,
                                                const calib::StereoCalibration& calibration,
                                                const PositionSensingOptions& options,
                                                const cv::Mat& left_grey) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  const PositionSensingOptions scaled = options.ScaledForImage(left_grey.size());
  PositionSensingReport report =
      SenseScaledFromMatches(std::move(match), calibration, scaled, left_grey, nullptr);
  NoteScale(scaled, left_grey.size(), &report);
  return report;
}

PositionSensingReport SensePositions(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                     const calib::StereoCalibration& calibration,
                                     const PositionSensingOptions& options, ocl::Runtime* runtime) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (calibration.rectified) {
    throw std::invalid_argument("position sensing needs the cell's CAL.yml (world frame with the "
                                "table at z = 0), not a rectified calib.txt");
  }
  // P and F hold for the calibrated image size only.
  if (const std::string problem = calibration.ImageSizeProblem(left_grey.cols, left_grey.rows);
      !problem.empty()) {
    throw std::invalid_argument("the calibration " + problem);
  }
  // One image given twice would give a fake part at a fake height (vision/setup_checks.h).
  CheckDistinctViews(left_grey, right_grey);
  const PositionSensingOptions scaled = options.ScaledForImage(left_grey.size());
  const std::shared_ptr<const StereoLens> lens = LensOf(calibration);
  if (lens && options.lens_route == LensRoute::kImages) {
    const auto start = std::chrono::steady_clock::now();
    const cv::Mat left = UndistortImage(left_grey, lens->left.K, lens->left.D);
    const cv::Mat right = UndistortImage(right_grey, lens->right.K, lens->right.D);
    const double undistort_ms = MillisecondsSince(start);
    PositionSensingReport report = SenseOnImages(left, right, calibration, scaled, nullptr, runtime);
    report.timing_ms.match += undistort_ms;
    report.timing_ms.total += undistort_ms;
    return report;
  }
  return SenseOnImages(left_grey, right_grey, calibration, scaled, lens, runtime);
}

nlohmann::json ObjectsJson(const PositionSensingReport& report,
                           const PositionSensingOptions& options) {
  nlohmann::json objects = nlohmann::json::array();
  int id = 1;
  for (const ObjectPose& pose : report.objects) {
    objects.push_back(
        {{"id", id++},
         {"centroid", {pose.centroid.x(), pose.centroid.y(), pose.centroid.z()}},
         {"height", pose.height_mm},
         // A round part has no orientation: null, and the robot link sends yaw 0.
         {"yaw_deg", pose.round ? nlohmann::json(nullptr) : nlohmann::json(pose.yaw_deg)},
         {"points", pose.points},
         {"top_points", pose.top_points},
         {"yaw_moments_deg", pose.yaw_moments_deg},
         {"top_rectangle",
          {{"centre", {pose.top_rectangle.centre.x(), pose.top_rectangle.centre.y()}},
           {"length", pose.top_rectangle.length},
           {"width", pose.top_rectangle.width},
           {"yaw_deg", pose.top_rectangle.yaw_deg}}},
         {"round", pose.round},
         {"top_fill", pose.top_fill},
         {"merged", pose.merged},
         {"touching_points", pose.touching_points},
         {"points_above_top", pose.points_above_top},
         {"taller_touching_points", pose.taller_touching_points},
         {"at_image_border", pose.at_image_border},
         {"piece_left_out", pose.piece_left_out},
         {"image_edge_moved_mm", pose.image_edge_moved_mm},
         {"shadow_strip_mm", pose.shadow_strip_mm},
         {"unplaced_sides", pose.unplaced_sides}});
    if (pose.round) {
      objects.back()["top_circle"] = {
          {"centre", {pose.circle_centre.x(), pose.circle_centre.y()}},
          {"radius", pose.circle_radius}};
    }
  }
  const auto& t = report.triangulation;
  nlohmann::json json = {{"units", "mm"},
                         {"objects", objects},
                         {"clustering", ClusteringMethodName(options.clustering)},
                         {"yaw_method", YawMethodName(options.clustering == ClusteringMethod::kGrid
                                                          ? options.pose.yaw_method
                                                          : YawMethod::kCentralMoments)},
                         {"matches", report.match.matches.size()},
                         {"engine", report.match.solve.engine},
                         {"triangulation",
                          {{"accepted", t.accepted},
                           {"behind_camera", t.behind_camera},
                           {"large_residual", t.large_residual},
                           {"degenerate", t.degenerate},
                           {"edge_along_epipolar", t.edge_along_epipolar},
                           {"mean_residual_px", t.mean_residual_px},
                           {"max_residual_px", options.max_reprojection_error_px}}},
                         {"clustered_points",
                          {{"outside_height_window", report.clustering.n_outside_height_window},
                           {"in_small_clusters", report.clustering.n_in_small_clusters},
                           {"island_merges", report.island_merges},
                           {"top_level_splits", report.top_level_splits},
                           {"without_top_face", report.without_top_face},
                           {"narrow_top_face", report.narrow_top_face},
                           {"small_flagged", report.small_flagged},
                           {"merged", report.merged}}},
                         {"timing_ms",
                          {{"match", report.timing_ms.match},
                           {"refine", report.timing_ms.refine},
                           {"triangulate", report.timing_ms.triangulate},
                           {"cluster", report.timing_ms.cluster},
                           {"pose", report.timing_ms.pose},
                           {"total", report.timing_ms.total}}}};
  // Images wider than the reference: what the settings were scaled by (ScaledForImage).
  if (report.image_scale != 1.0) {
    json["image_scale"] = {{"scale", report.image_scale}, {"max_features", report.max_features}};
  }
  return json;
}

std::string ProbeOptions::Check() const {
  std::ostringstream out;
  if (zncc_window < 3 || zncc_window > 15 || zncc_window % 2 == 0) {
    out << "ProbeOptions.zncc_window must be odd in [3, 15] (is " << zncc_window << ")";
  } else if (!(z_range_mm.first < z_range_mm.second)) {
    out << "ProbeOptions.z_range_mm needs min < max (is " << z_range_mm.first << ", "
        << z_range_mm.second << ")";
  }
  return out.str();
}

ProbeReport ProbePoint(const cv::Mat& left_grey, const cv::Mat& right_grey,
                       const calib::StereoCalibration& calibration,
                       const Eigen::Vector2d& left_point, const ProbeOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (!(left_point.x() >= 0 && left_point.y() >= 0 && left_point.x() <= left_grey.cols - 1 &&
        left_point.y() <= left_grey.rows - 1)) {
    std::ostringstream out;
    out << "point (" << left_point.x() << ", " << left_point.y() << ") is outside the "
        << left_grey.cols << "x" << left_grey.rows << " left image";
    throw std::invalid_argument(out.str());
  }
  ProbeReport report;
  report.left_point = left_point;
  // The left ray X(t) = C1 + t d, cut to the height range, projected into the right image.
  const Eigen::Matrix3d M1 = calibration.P1.leftCols<3>();
  const Eigen::Vector3d direction = M1.inverse() * left_point.homogeneous();
  const Eigen::Vector3d C1 = calib::CameraCentre(calibration.P1);
  if (std::abs(direction.z()) < 1e-12) throw std::invalid_argument("the left ray is parallel to the table");
  auto at_height = [&](double z) {
    const Eigen::Vector3d X = C1 + ((z - C1.z()) / direction.z()) * direction;
    return Eigen::Vector2d((calibration.P2 * X.homogeneous()).hnormalized());
  };
  report.search_start = at_height(options.z_range_mm.first);
  report.search_end = at_height(options.z_range_mm.second);
  const ZnccMatcher zncc(left_grey, right_grey, options.zncc_window);
  const Eigen::Vector2d span = report.search_end - report.search_start;
  const int steps = std::max(1, static_cast<int>(std::ceil(span.norm())));
  std::vector<double> scores;
  std::vector<Eigen::Vector2d> positions;
  for (int k = 0; k <= steps; ++k) {
    const Eigen::Vector2d x = report.search_start + (static_cast<double>(k) / steps) * span;
    if (x.x() < 0 || x.y() < 0 || x.x() > right_grey.cols - 1 || x.y() > right_grey.rows - 1) continue;
    positions.push_back(x);
    scores.push_back(zncc(left_point.cast<float>(), x.cast<float>()));
  }
  report.positions_tested = static_cast<int>(positions.size());
  if (positions.empty()) return report;
  const auto best = static_cast<std::size_t>(
      std::max_element(scores.begin(), scores.end()) - scores.begin());
  report.zncc = scores[best];
  for (std::size_t k = 0; k < scores.size(); ++k) {
    const auto distance = static_cast<int>(k > best ? k - best : best - k);
    if (distance > options.zncc_window) report.second_zncc = std::max(report.second_zncc, scores[k]);
  }
  report.found = report.zncc > 0.0;
  if (!report.found) return report;
  // Sub-pixel: the vertex of the parabola through the peak and its neighbours.
  double offset = 0.0;
  if (best > 0 && best + 1 < scores.size()) {
    const double a = scores[best - 1], b = scores[best], c = scores[best + 1];
    const double curvature = a - 2 * b + c;
    if (curvature < 0) offset = std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
  }
  const Eigen::Vector2d step = span / steps;
  report.right_point = positions[best] + offset * step;
  report.epipolar_distance_px =
      calib::EpipolarDistancePx(calibration.F, left_point, report.right_point);
  if (const auto point = TriangulateLinear(calibration.P1, calibration.P2, left_point,
                                           report.right_point)) {
    report.point_in_world = point->point_in_world;
    report.reprojection_error_px = point->reprojection_error_px;
  }
  return report;
}

}  // namespace hnnstereo::vision
