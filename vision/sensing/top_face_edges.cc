#include "vision/sensing/top_face_edges.h"

#include "calib/epipolar.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
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
  // Fraction of samples every `step` mm on the segment a-b (world, at the height) where the
  // image gradient across the segment's image reaches the threshold within 1 px across it.
  double Support(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double step) const {
    const std::vector<Across> samples = Sample(a, b, step);
    if (samples.empty()) return 0.0;
    int supported = 0;
    for (const Across& sample : samples) supported += sample.within_1px >= min_gradient_ ? 1 : 0;
    return static_cast<double>(supported) / static_cast<double>(samples.size());
  }

  // Fraction of samples every `step` mm on the segment a-b (world, at the height) where the
  // image gradient across it reaches the threshold within 1 px across it with the given
  // polarity: `polarity` > 0 counts samples brighter on the side of `outward` (a world
  // direction in the plane), < 0 darker.
  double PolarSupport(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                      const Eigen::Vector2d& outward, double polarity, double step) const {
    const std::vector<Across> samples = Sample(a, b, step);
    const double orientation = OutwardOrientation(a, b, outward);
    if (samples.empty() || orientation == 0.0) return 0.0;
    int supported = 0;
    for (const Across& sample : samples) {
      const double signed_gradient = orientation * sample.signed_within_1px;
      supported += polarity * signed_gradient >= min_gradient_ ? 1 : 0;
    }
    return static_cast<double>(supported) / static_cast<double>(samples.size());
  }

  // Mean gradient across the segment a-b towards `outward` (a world direction in the plane):
  // > 0 when the image is brighter on that side.
  double MeanOutwardGradient(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                             const Eigen::Vector2d& outward, double step) const {
    const std::vector<Across> samples = Sample(a, b, step);
    const double orientation = OutwardOrientation(a, b, outward);
    if (samples.empty()) return 0.0;
    double sum = 0.0;
    for (const Across& sample : samples) sum += orientation * sample.signed_within_1px;
    return sum / static_cast<double>(samples.size());
  }

  // Mean image gradient across the segment a-b at its samples, on the line itself: peaks on the
  // edge's line.
  double Strength(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double step) const {
    const std::vector<Across> samples = Sample(a, b, step);
    if (samples.empty()) return 0.0;
    double sum = 0.0;
    for (const Across& sample : samples) sum += sample.on_line;
    return sum / static_cast<double>(samples.size());
  }

 private:
  // The gradient across a segment's image at one sample: on its pixel, and the largest within
  // 1 px across (0 outside the image).
  struct Across {
    double on_line = 0.0, within_1px = 0.0;
    /// The gradient of largest magnitude within 1 px, signed along the image normal of the
    /// segment (t rotated by +90 degrees, t from a's image to b's).
    double signed_within_1px = 0.0;
  };

  // +1 when `outward` (world, in the plane, from the segment a-b's middle) points along the
  // image normal of Sample, -1 against it, 0 when undefined.
  double OutwardOrientation(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                            const Eigen::Vector2d& outward) const {
    Eigen::Vector2d ua, ub, um, uo;
    const Eigen::Vector2d mid = 0.5 * (a + b);
    if (!Project(a, &ua) || !Project(b, &ub) || !Project(mid, &um) || !Project(mid + outward, &uo)) {
      return 0.0;
    }
    const Eigen::Vector2d t = ub - ua;
    const double side = Eigen::Vector2d(-t.y(), t.x()).dot(uo - um);
    return side > 0.0 ? 1.0 : (side < 0.0 ? -1.0 : 0.0);
  }

  std::vector<Across> Sample(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double step) const {
    Eigen::Vector2d ua, ub;
    if (!((b - a).norm() > 0.0) || !Project(a, &ua) || !Project(b, &ub) || !((ub - ua).norm() > 0.0)) {
      return {};
    }
    const int n = static_cast<int>(std::floor((b - a).norm() / step)) + 1;
    const Eigen::Vector2d t = (ub - ua).normalized();
    const Eigen::Vector2d normal(-t.y(), t.x());
    const auto signed_across = [&](const Eigen::Vector2d& uv) {
      const int u = static_cast<int>(std::lround(uv.x()));
      const int v = static_cast<int>(std::lround(uv.y()));
      if (u < 0 || v < 0 || u >= gx_.cols || v >= gx_.rows) return 0.0;
      return static_cast<double>(gx_.at<float>(v, u) * normal.x() + gy_.at<float>(v, u) * normal.y());
    };
    const auto across = [&](const Eigen::Vector2d& uv) { return std::abs(signed_across(uv)); };
    std::vector<Across> samples(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d xy = a + (b - a) * (n == 1 ? 0.5 : static_cast<double>(i) / (n - 1));
      Eigen::Vector2d uv;
      if (!Project(xy, &uv)) continue;
      Across& sample = samples[static_cast<std::size_t>(i)];
      sample.on_line = across(uv);
      sample.within_1px = std::max({sample.on_line, across(uv + normal), across(uv - normal)});
      for (const Eigen::Vector2d& at : {uv, Eigen::Vector2d(uv + normal), Eigen::Vector2d(uv - normal)}) {
        const double g = signed_across(at);
        if (std::abs(g) > std::abs(sample.signed_within_1px)) sample.signed_within_1px = g;
      }
    }
    return samples;
  }

  const Eigen::Matrix<double, 3, 4>& P_;
  const cv::Mat& gx_;
  const cv::Mat& gy_;
  double height_;
  double min_gradient_;
};

// Side k of frame f without the corner margins, as a segment a-b; false when nothing is left.
bool SideSegment(const Frame& f, int k, const TopFaceEdgeOptions& o, Eigen::Vector2d* a,
                 Eigen::Vector2d* b) {
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  const double reach = f.half[other] - o.corner_margin_mm;
  if (reach <= 0.0) return false;
  const Eigen::Vector2d mid = f.centre + s.sign * f.half[s.axis] * f.axis[s.axis];
  *a = mid - reach * f.axis[other];
  *b = mid + reach * f.axis[other];
  return true;
}

// Edge support of side k of frame f.
double SideSupport(const EdgeProbe& probe, const Frame& f, int k, const TopFaceEdgeOptions& o) {
  Eigen::Vector2d a, b;
  return SideSegment(f, k, o, &a, &b) ? probe.Support(a, b, o.step_mm) : 0.0;
}

// Mean gradient across side k of frame f.
double SideStrength(const EdgeProbe& probe, const Frame& f, int k, const TopFaceEdgeOptions& o) {
  Eigen::Vector2d a, b;
  return SideSegment(f, k, o, &a, &b) ? probe.Strength(a, b, o.step_mm) : 0.0;
}

// The most that `measure` (of a frame) gives with side k of frame f moved up to `slack` mm
// either way in `step` steps: a side the points placed a little off its edge still counts.
template <typename Measure>
double BestNearSide(const Frame& f, int k, double slack, double step, const Measure& measure) {
  const Side s = SideOf(k);
  double best = 0.0;
  for (double e = -slack; e <= slack + 1e-9; e += step) {
    if (f.half[s.axis] + 0.5 * e > 0.0) best = std::max(best, measure(Extended(f, k, e)));
  }
  return best;
}

// The polarity the neighbouring side of side k at `across` (-1 or +1 along the other axis)
// shows along the face from `from` to `to` (mm from f's centre along side k's outward axis):
// +1 when the image is brighter outside the face, -1 darker, 0 when it shows none.
double NeighbourSidePolarity(const EdgeProbe& probe, const Frame& f, int k, double across,
                             double from, double to, double step) {
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  const Eigen::Vector2d base = f.centre + across * f.half[other] * f.axis[other];
  const double mean = probe.MeanOutwardGradient(base + s.sign * from * f.axis[s.axis],
                                                base + s.sign * to * f.axis[s.axis],
                                                across * f.axis[other], step);
  return mean > 0.0 ? 1.0 : (mean < 0.0 ? -1.0 : 0.0);
}

// Edge support (the lower of the two) of the sides beside side k of frame f, along the stretch
// from `near` to `far` (mm from f's centre along side k's outward axis); nullopt when that is
// under two samples long. With `face_corner_margin`, only samples whose gradient has the
// polarity the same side shows along the face itself count (sampled from the corner margin to
// `near` less the corner margin): a face brighter than the ground around it stays brighter past
// a shadow's edge across it (ambient light), while the ground in the face's own shadow beyond
// its end is darker than the ground beside it; 0 when a side shows no polarity along the face.
// `wall_mm` (for the side at -half and at +half across): each side's line past the edge may lie
// up to that far outward (the best line counts): in a shadow the face and the wall the camera
// sees beside it can be equally dark, and the side's edge is then the wall's base
// (InAShadowASidesEdgeMayBeItsWallsBase).
std::optional<double> NeighbourSidesSupport(const EdgeProbe& probe, const Frame& f, int k,
                                            double near, double far, double step,
                                            std::optional<double> face_corner_margin = std::nullopt,
                                            std::array<double, 2> wall_mm = {0.0, 0.0}) {
  if (far - near < 2.0 * step) return std::nullopt;
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  double lowest = 1.0;
  for (double across : {-1.0, 1.0}) {
    const Eigen::Vector2d outward = across * f.axis[other];
    const Eigen::Vector2d base = f.centre + across * f.half[other] * f.axis[other];
    double polarity = 0.0;
    if (face_corner_margin) {
      const double margin = *face_corner_margin;
      polarity = NeighbourSidePolarity(probe, f, k, across, -(f.half[s.axis] - margin),
                                       near - 2.0 * margin, step);
      if (polarity == 0.0) return 0.0;
    }
    double best = 0.0;
    const double reach = std::max(0.0, wall_mm[across > 0.0 ? 1 : 0]);
    for (double offset = 0.0; offset <= reach + 1e-9; offset += step) {
      const Eigen::Vector2d line = base + offset * outward;
      const Eigen::Vector2d a = line + s.sign * near * f.axis[s.axis];
      const Eigen::Vector2d b = line + s.sign * far * f.axis[s.axis];
      best = std::max(best, face_corner_margin ? probe.PolarSupport(a, b, outward, polarity, step)
                                               : probe.Support(a, b, step));
    }
    lowest = std::min(lowest, best);
  }
  return lowest;
}

// The polarity the face's outline shows across side k's two neighbouring sides, along the face
// (from the corner margin at either end): +1 when the image is brighter outside the face on
// both, -1 when darker on both, 0 when they disagree or show none.
double NeighbourSidesPolarity(const EdgeProbe& probe, const Frame& f, int k, double margin,
                              double step) {
  const Side s = SideOf(k);
  const double reach = f.half[s.axis] - margin;  // from one corner margin to the other
  if (reach <= margin) return 0.0;
  double polarity = 0.0;
  for (double across : {-1.0, 1.0}) {
    const double sign =
        NeighbourSidePolarity(probe, f, k, across, -s.sign * reach, s.sign * reach, step);
    if (sign == 0.0 || (polarity != 0.0 && sign != polarity)) return 0.0;
    polarity = sign;
  }
  return polarity;
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

// Strong points (not `weak`) lower than `max_z`, seen by any camera of `camera_centres` (above
// the plane) through a strip of the plane z = `height`: along side k of frame f from `near` to
// `far` (mm from f's centre along the side's outward axis), across within f's half width less
// `inset`.
int LowerPointsSeenThroughStrip(const Frame& f, int k, double near, double far, double inset,
                                double height, double max_z,
                                const std::vector<Eigen::Vector3d>& points,
                                const std::vector<bool>& weak,
                                const std::vector<Eigen::Vector3d>& camera_centres) {
  const Side s = SideOf(k);
  const int other = 1 - s.axis;
  int count = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (weak[i] || !(points[i].z() < max_z)) continue;
    for (const Eigen::Vector3d& C : camera_centres) {
      if (!(C.z() > height) || points[i].z() == C.z()) continue;
      const double t = (height - C.z()) / (points[i].z() - C.z());
      const Eigen::Vector2d q = (C + t * (points[i] - C)).head<2>() - f.centre;
      const double along = s.sign * q.dot(f.axis[s.axis]);
      const double across = std::abs(q.dot(f.axis[other]));
      if (along > near && along < far && across < f.half[other] - inset) {
        ++count;
        break;
      }
    }
  }
  return count;
}

// How far past an edge (mm) a face's sides are sampled to tell the face's end from a line
// across the face.
constexpr double kSidesPastMm = 4.0;
// A face's end found past a line across it lies at least this far (mm) past the base edge of
// a wall that would stand on that line.
constexpr double kPastWallMm = 3.0;

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
  if (!(max_yaw_turn_deg >= 0.0 && max_yaw_turn_deg <= 45.0)) {
    return "top edges: max_yaw_turn_deg must be in [0, 45]";
  }
  if (!(yaw_step_deg > 0.0)) return "top edges: yaw_step_deg must be > 0";
  if (!(min_yaw_turn_gain >= 0.0)) return "top edges: min_yaw_turn_gain must be >= 0";
  return {};
}

namespace {

// Where side k's outward search starts (mm past the side) and whether the side lies at a line
// across the face (an image edge the face's two sides go on past), whose end lies further out.
struct OutwardSearch {
  double from = 1.0;
  bool line_at_side = false;
};

// One top's fit to the image's edges (ExtendTopToImageEdges): the top's frame as its sides
// move, the report of the moves, and the tests the fit makes on that frame. Each public step
// reads top-down: FitPasses runs FitSide on every side, once or twice; FitSide tests the side
// where it lies, may move it in to an edge inside, and else searches outward.
class TopFit {
 public:
  TopFit(const ObjectPose& pose, const TopFaceEdgeInputs& in, const TopFaceEdgeOptions& options)
      : pose_(pose),
        in_(in),
        options_(options),
        probe_(in.P, in.gradient_x, in.gradient_y, pose.height_mm, options.min_edge_gradient),
        f_(FrameOf(pose.top_rectangle)),
        step_(options.step_mm),
        camera_(in.camera_centres.at(0)) {}

  const Frame& frame() const { return f_; }
  int lines_unplaced() const { return lines_unplaced_; }

  // Two passes when the first moves a side (second_pass): a side's test reads its neighbouring
  // sides' lines, which may move after it. The moves add up; the second pass's findings are
  // counted afresh and merged with the first's (the support before any move, the larger count).
  TopFaceEdgeReport FitPasses() {
    TopFaceEdgeReport first;  // the first pass's findings, when there is a second
    for (int pass = 0; pass < (options_.second_pass ? 2 : 1); ++pass) {
      if (pass == 1) {
        if (report_.moved_mm() == 0.0) break;
        first = report_;
        report_ = TopFaceEdgeReport{};
        for (int k = 0; k < 4; ++k) report_.extension_mm[k] = first.extension_mm[k];
        lines_unplaced_ = 0;
      }
      for (int k = 0; k < 4; ++k) FitSide(k);
    }
    for (int k = 0; k < 4; ++k) {
      if (report_.end_support_before[k] < options_.min_end_support && report_.extension_mm[k] == 0.0) {
        ++report_.unplaced_sides;
      }
    }
    report_.unplaced_sides += lines_unplaced_;
    if (first.moved_mm() != 0.0) {
      for (int k = 0; k < 4; ++k) report_.end_support_before[k] = first.end_support_before[k];
      report_.refused_by_points = std::max(report_.refused_by_points, first.refused_by_points);
      report_.edge_inside = std::max(report_.edge_inside, first.edge_inside);
      report_.line_on_face = std::max(report_.line_on_face, first.line_on_face);
      report_.end_edge_reversed = std::max(report_.end_edge_reversed, first.end_edge_reversed);
    }
    return report_;
  }

 private:
  // One side: its support where it lies; at an image edge it stays unless that edge is a line
  // across the face; with none under it, it moves in to an edge inside when there is one;
  // else the first edge outward that passes the tests, unless matched points contradict it.
  void FitSide(int k) {
    double face_polarity = 0.0;
    const double before = SupportBefore(k, &face_polarity);
    const bool at_edge = before >= options_.min_end_support;
    OutwardSearch search;
    if (at_edge ? !LineAcrossFaceAtSide(k, &search) : SettledInside(k, face_polarity, &search)) {
      return;
    }
    const double found = SearchOutward(k, &search);
    if (found <= 0.0) {
      if (search.line_at_side && at_edge && !EndAtOwnWall(k)) ++lines_unplaced_;  // else counted later
      return;
    }
    const double best = StrongestLine(k, found);
    const Frame g = Extended(f_, k, best);
    if (ContradictedByPoints(g, k)) {
      ++report_.refused_by_points;
      if (search.line_at_side && at_edge) ++lines_unplaced_;  // else counted later
      return;
    }
    report_.extension_mm[k] += best;
    f_ = g;
  }

  // Side k's image-edge support where it lies (within 1 mm), recorded in end_support_before.
  // An edge under the side with the polarity opposite to the face's outline along its two
  // neighbouring sides is no end of this face (a shadow's outer edge on the ground, matched at
  // the top's height; end_edge_polarity): the support is then taken with the face's polarity,
  // which `face_polarity` keeps for the search inward (0: any polarity).
  double SupportBefore(int k, double* face_polarity) {
    double before = BestNearSide(f_, k, 1.0, options_.step_mm, [&](const Frame& g) {
      return SideSupport(probe_, g, k, options_);
    });
    report_.end_support_before[k] = before;
    if (options_.end_edge_polarity && before >= options_.min_end_support) {
      if (const double polarity = NeighbourSidesPolarity(probe_, f_, k, options_.corner_margin_mm, step_);
          polarity != 0.0) {
        *face_polarity = polarity;
        const double polar = BestNearSide(f_, k, 1.0, options_.step_mm, [&](const Frame& g) {
          return SupportWithPolarity(g, k, *face_polarity);
        });
        if (polar < options_.min_end_support) {
          ++report_.end_edge_reversed;
          before = polar;
        } else {
          *face_polarity = 0.0;
        }
      }
    }
    return before;
  }

  // Side k's image-edge support on frame g: any polarity when `face_polarity` is 0, else the
  // face's (PolarSupport).
  double SupportWithPolarity(const Frame& g, int k, double face_polarity) const {
    if (face_polarity == 0.0) return SideSupport(probe_, g, k, options_);
    const Side s = SideOf(k);
    Eigen::Vector2d a, b;
    return SideSegment(g, k, options_, &a, &b)
               ? probe_.PolarSupport(a, b, s.sign * g.axis[s.axis], face_polarity, step_)
               : 0.0;
  }

  // A side at an image edge ends the face unless the face's two sides go on past that edge in
  // the image (look_past_lines_on_face): then the edge is a line across the face (a taller
  // neighbour's shadow's edge, a mark) and the search goes on past the base edge of a wall that
  // would stand on it. Returns whether to search outward.
  bool LineAcrossFaceAtSide(int k, OutwardSearch* search) {
    if (!options_.look_past_lines_on_face) return false;
    const double past_from = f_.half[SideOf(k).axis] + 1.0 + options_.corner_margin_mm;
    if (SidesPast(f_, k, past_from) < options_.min_side_support) return false;
    ++report_.line_on_face;
    search->line_at_side = true;
    search->from = std::max(1.0 + options_.corner_margin_mm, WallSeenMm(k) + kPastWallMm);
    return true;
  }

  // A side with no image edge under it may lie beyond the face's edge (points at the top
  // height past it): it moves in to the first edge within max_inward_mm, when at most
  // max_cut_fraction of the top's points lie beyond that edge and the face's sides do not go
  // on past it (else it is a line on the face). Returns whether the side is settled: moved in,
  // or kept; false (search outward) when there is no edge inside, or when that edge is a line
  // across the face whose end may lie further out.
  bool SettledInside(int k, double face_polarity, OutwardSearch* search) {
    const Side s = SideOf(k);
    double inside = 0.0;
    for (double e = -1.0 - step_; e >= -options_.max_inward_mm - 1e-9 && Admissible(k, e); e -= step_) {
      if (SupportWithPolarity(Extended(f_, k, e), k, face_polarity) >= options_.min_end_support) {
        inside = e;
        break;
      }
    }
    if (!(inside < 0.0)) return false;
    ++report_.edge_inside;
    const double best = StrongestLine(k, inside);
    const Frame g = Extended(f_, k, best);
    // The face's sides sampled from the corner margin past the edge to the side as it was, and
    // at least kSidesPastMm: a face that goes on past the edge goes on past the side as well.
    const double past_from = f_.half[s.axis] + best + options_.corner_margin_mm;
    const std::optional<double> sides_past_edge = NeighbourSidesSupport(
        probe_, f_, k, past_from, std::max(f_.half[s.axis], past_from + kSidesPastMm), step_,
        std::nullopt, NeighbourWalls(k));
    if (FractionBeyondSide(g, k, pose_.height_mm, in_.top_layer_mm, in_.points,
                           pose_.point_indices) <= options_.max_cut_fraction &&
        sides_past_edge.value_or(0.0) < options_.min_side_support) {
      report_.extension_mm[k] += best;
      f_ = g;
      return true;
    }
    // A line across the face just inside the side, the face's sides going on past it with the
    // face's polarity: the face's end may lie further out. Search out from the side.
    if (!options_.look_past_lines_on_face || SidesPast(f_, k, past_from) < options_.min_side_support) {
      return true;
    }
    ++report_.line_on_face;
    search->line_at_side = true;
    search->from = std::max(search->from, best + WallSeenMm(k) + kPastWallMm);
    return false;
  }

  // The first move outward (mm, from search->from up to max_extension_mm, admissible, into no
  // other part's rectangle) where side k is at an image edge and its neighbouring sides reach
  // it; an edge found that is itself a line across the face is looked past. 0: none found.
  double SearchOutward(int k, OutwardSearch* search) {
    const Side s = SideOf(k);
    const double from = f_.half[s.axis];
    for (double e = search->from; e <= options_.max_extension_mm + 1e-9 && Admissible(k, e);
         e += step_) {
      const Frame g = Extended(f_, k, e);
      bool blocked = false;
      for (const Rectangle2D& other : in_.others) blocked = blocked || Overlaps(g, other, 1.0);
      if (blocked) break;
      // The neighbouring sides from the old side (2 from - g.half from g's centre, which moved
      // by half the extension) to the corner margin before the new one.
      if (SideSupport(probe_, g, k, options_) >= options_.min_end_support &&
          NeighbourSidesSupport(
              probe_, g, k, 2.0 * from - g.half[s.axis], g.half[s.axis] - options_.corner_margin_mm,
              step_, std::nullopt,
              search->line_at_side ? NeighbourWalls(k) : std::array<double, 2>{0.0, 0.0})
                  .value_or(1.0) >= options_.min_side_support) {
        const double past = g.half[s.axis] + 1.0 + options_.corner_margin_mm;
        if (options_.look_past_lines_on_face && SidesPast(g, k, past) >= options_.min_side_support) {
          if (!search->line_at_side) ++report_.line_on_face;
          search->line_at_side = true;
          e += WallSeenMm(k) + kPastWallMm;
          continue;
        }
        return e;
      }
    }
    return 0.0;
  }

  // Whether a side at a line across the face, whose end was not found, is the face's end after
  // all (end_at_own_wall): the face's sides stop past the wall the camera sees beyond it, so
  // what went on in line with them was that wall.
  bool EndAtOwnWall(int k) const {
    const double past_wall = f_.half[SideOf(k).axis] + WallSeenMm(k) + kPastWallMm;
    return options_.end_at_own_wall && !(SidesPast(f_, k, past_wall) >= options_.min_side_support);
  }

  // Whether more than max_contradicting_points strong points lower than the top (by 2 top
  // layers) are seen through the strip that moving side k to frame g adds (1.5 mm inside its
  // sides): the table or a lower part where the face would hide them.
  bool ContradictedByPoints(const Frame& g, int k) const {
    const Side s = SideOf(k);
    const double from = f_.half[s.axis];
    constexpr double kInsideMm = 1.5;
    const double low = pose_.height_mm - 2.0 * in_.top_layer_mm;
    return LowerPointsSeenThroughStrip(g, k, 2.0 * from - g.half[s.axis] + kInsideMm,
                                       g.half[s.axis] - kInsideMm, kInsideMm, pose_.height_mm, low,
                                       in_.points, in_.weak,
                                       in_.camera_centres) > options_.max_contradicting_points;
  }

  // Whether side k may move by e (mm, outward positive): the top keeps some width and stays
  // within max_length_mm.
  bool Admissible(int k, double e) const {
    const Frame g = Extended(f_, k, e);
    return g.half[SideOf(k).axis] > 2.0 * options_.corner_margin_mm &&
           2.0 * std::max(g.half[0], g.half[1]) <= in_.max_length_mm;
  }

  // The support test passes a few pixels before an edge (the Sobel response is a few pixels
  // wide, the test allows 1 px): the edge's line is where the gradient across the side peaks,
  // within the next 3 mm of a move that first passes it at `first`.
  double StrongestLine(int k, double first) const {
    const double direction = first > 0.0 ? step_ : -step_;
    double best = first, best_strength = SideStrength(probe_, Extended(f_, k, first), k, options_);
    for (double e = first + direction; std::abs(e - first) <= 3.0 + 1e-9 && Admissible(k, e);
         e += direction) {
      const double strength = SideStrength(probe_, Extended(f_, k, e), k, options_);
      if (strength > best_strength) {
        best = e;
        best_strength = strength;
      }
    }
    return best;
  }

  // How far (mm, in the plane of the top, outward) the wall under side k shows past it in the
  // image: 0 where the camera does not see that wall. The base point under the side's middle,
  // seen through the plane of the top, lies at mid + h / H (C - mid). A side looking past a
  // line across the face never stops at the base edge of a wall standing on that line.
  double WallSeenMm(int k) const {
    const Side s = SideOf(k);
    const Eigen::Vector2d outward = s.sign * f_.axis[s.axis];
    const Eigen::Vector2d mid = f_.centre + f_.half[s.axis] * outward;
    if (!(camera_.z() > pose_.height_mm)) return 0.0;
    return std::max(0.0, pose_.height_mm / camera_.z() * (camera_.head<2>() - mid).dot(outward));
  }

  // The walls seen beside side k's two neighbouring sides (at -half and +half across), plus
  // 1 mm of blur, where those sides' lines may lie past a line across the face.
  std::array<double, 2> NeighbourWalls(int k) const {
    const int other = 1 - SideOf(k).axis;
    return std::array<double, 2>{WallSeenMm(2 * other + 1) + 1.0, WallSeenMm(2 * other) + 1.0};
  }

  // The face's sides' support (with the face's polarity) over kSidesPastMm from `near` (mm
  // from frame g's centre) past side k: whether the face goes on past an edge there.
  double SidesPast(const Frame& g, int k, double near) const {
    return NeighbourSidesSupport(probe_, g, k, near, near + kSidesPastMm, step_,
                                 options_.corner_margin_mm, NeighbourWalls(k))
        .value_or(0.0);
  }

  const ObjectPose& pose_;
  const TopFaceEdgeInputs& in_;
  const TopFaceEdgeOptions& options_;
  const EdgeProbe probe_;
  Frame f_;
  const double step_;
  const Eigen::Vector3d camera_;  // the image's camera centre
  TopFaceEdgeReport report_;
  // Sides at an image edge that is a line across the face whose end was not placed (those
  // beyond an inner line count with the sides that have no edge under them).
  int lines_unplaced_ = 0;
};

}  // namespace

TopFaceEdgeReport ExtendTopToImageEdges(ObjectPose* pose, const TopFaceEdgeInputs& inputs,
                                        const TopFaceEdgeOptions& options) {
  if (pose->round || inputs.gradient_x.empty()) return TopFaceEdgeReport{};
  if (inputs.camera_centres.empty()) {
    throw std::invalid_argument("ExtendTopToImageEdges needs the camera centres (P's first)");
  }
  TopFit fit(*pose, inputs, options);
  const TopFaceEdgeReport report = fit.FitPasses();
  if (report.moved_mm() == 0.0) return report;
  const Frame& f = fit.frame();
  if (f.half[1] > f.half[0]) {
    // The moves made the short side the long one: the yaw (the long side's direction) would
    // turn 90 degrees on edges that do not settle which side is longer. Keep the points'
    // rectangle.
    TopFaceEdgeReport kept;
    kept.swapped_sides_refused = true;
    for (int k = 0; k < 4; ++k) {
      kept.end_support_before[k] = report.end_support_before[k];
      if (kept.end_support_before[k] < options.min_end_support) ++kept.unplaced_sides;
    }
    kept.unplaced_sides += fit.lines_unplaced();
    return kept;
  }
  Rectangle2D& r = pose->top_rectangle;
  r.centre = f.centre;
  r.length = 2.0 * f.half[0];
  r.width = 2.0 * f.half[1];
  if (inputs.centroid_from_rectangle) {
    pose->centroid.x() = r.centre.x();
    pose->centroid.y() = r.centre.y();
  }
  return report;
}

double TurnTopToImageEdges(ObjectPose* pose, const Eigen::Matrix<double, 3, 4>& P,
                           const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                           bool yaw_from_rectangle, const TopFaceEdgeOptions& options) {
  if (pose->round || gradient_x.empty() || !(options.max_yaw_turn_deg > 0.0)) return 0.0;
  const EdgeProbe probe(P, gradient_x, gradient_y, pose->height_mm, options.min_edge_gradient);
  // The gradient along the outline: each side's mean gradient on its line (at its best offset
  // within kSlackMm, so that a side the points placed a little off still counts), weighted by
  // the side's length.
  constexpr double kSlackMm = 1.5;
  const auto outline_strength = [&](double turn_deg) {
    Rectangle2D r = pose->top_rectangle;
    r.yaw_deg += turn_deg;
    const Frame f = FrameOf(r);
    double total = 0.0;
    for (int k = 0; k < 4; ++k) {
      const double best = BestNearSide(f, k, kSlackMm, options.step_mm, [&](const Frame& g) {
        return SideStrength(probe, g, k, options);
      });
      total += best * 2.0 * f.half[1 - SideOf(k).axis];
    }
    return total;
  };
  const double unturned = outline_strength(0.0);
  double best_turn = 0.0, best = unturned;
  // Coarse, then fine around the coarse best.
  const double coarse = 4.0 * options.yaw_step_deg;
  for (double t = -options.max_yaw_turn_deg; t <= options.max_yaw_turn_deg + 1e-9; t += coarse) {
    if (const double strength = outline_strength(t); strength > best) {
      best = strength;
      best_turn = t;
    }
  }
  const double around = best_turn;
  for (double t = around - coarse; t <= around + coarse + 1e-9; t += options.yaw_step_deg) {
    if (std::abs(t) > options.max_yaw_turn_deg) continue;
    if (const double strength = outline_strength(t); strength > best) {
      best = strength;
      best_turn = t;
    }
  }
  if (best_turn == 0.0 || !(best >= (1.0 + options.min_yaw_turn_gain) * unturned)) return 0.0;
  pose->top_rectangle.yaw_deg = NormaliseAxisAngle(pose->top_rectangle.yaw_deg + best_turn);
  if (yaw_from_rectangle) pose->yaw_deg = pose->top_rectangle.yaw_deg;
  return best_turn;
}

namespace {

// The sides across a gap are sought, and the facing ends, each at its best offset within this
// distance (mm) of the rectangle's side: the pieces' points scatter about the face's outline.
constexpr double kGapSearchMm = 2.0;

// A piece's extent [lo, hi] (mm) along axis `axis` of frame f, from f's centre.
std::pair<double, double> ExtentAlong(const Frame& f, const std::vector<Eigen::Vector2d>& piece,
                                      int axis) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Eigen::Vector2d& p : piece) {
    const double t = (p - f.centre).dot(f.axis[axis]);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  return {lo, hi};
}

// The axis of the joint frame f along which two pieces lie apart by the widest gap, and that
// gap [near, far] (mm from f's centre); -1 when they overlap along both axes.
int WidestGap(const Frame& f, const std::vector<Eigen::Vector2d>& piece_a,
              const std::vector<Eigen::Vector2d>& piece_b, double* near, double* far) {
  int along = -1;
  *near = 0.0;
  *far = 0.0;
  for (int axis = 0; axis < 2; ++axis) {
    const auto [a_lo, a_hi] = ExtentAlong(f, piece_a, axis);
    const auto [b_lo, b_hi] = ExtentAlong(f, piece_b, axis);
    const bool a_first = a_hi < b_lo;
    const double from = a_first ? a_hi : b_hi;
    const double to = a_first ? b_lo : a_lo;
    if (to - from > *far - *near) {
      along = axis;
      *near = from;
      *far = to;
    }
  }
  return along;
}

// GapBetweenPieces::sides_support: the joint frame's two sides across the gap [near, far]
// along axis `along`, each side with the polarity it shows over its whole length (the pieces'
// stretches included; a piece may be an edge strip too thin to show it alone).
double SidesAcrossGapSupport(const EdgeProbe& probe, const Frame& f, int along, double near,
                             double far, const TopFaceEdgeOptions& options) {
  const double margin = options.corner_margin_mm;
  const double step = options.step_mm;
  const int across_axis = 1 - along;
  const auto at = [&](double t_along, double t_across) {
    return Eigen::Vector2d(f.centre + t_along * f.axis[along] + t_across * f.axis[across_axis]);
  };
  double support = 0.0;
  const double end = f.half[along] - margin;
  for (double across : {-1.0, 1.0}) {
    const Eigen::Vector2d outward = across * f.axis[across_axis];
    for (double offset = -kGapSearchMm; offset <= kGapSearchMm + 1e-9; offset += step) {
      const double line = across * (f.half[across_axis] + offset);
      const double face = probe.MeanOutwardGradient(at(-end, line), at(end, line), outward, step);
      if (face == 0.0) continue;
      support = std::max(support, probe.PolarSupport(at(near + margin, line), at(far - margin, line),
                                                     outward, face > 0.0 ? 1.0 : -1.0, step));
    }
  }
  return support;
}

// The support, with `polarity`, of the side of a piece's own minimum-area rectangle that faces
// `towards` (two boxes in a row need not share a yaw); 0 for a piece too thin to have an end.
double FacingEndSupport(const EdgeProbe& probe, const std::vector<Eigen::Vector2d>& piece,
                        const Eigen::Vector2d& towards, double polarity,
                        const TopFaceEdgeOptions& options) {
  const double margin = options.corner_margin_mm;
  const double step = options.step_mm;
  const Frame own = FrameOf(MinAreaRectangle(piece));
  const Eigen::Vector2d to = towards - own.centre;
  // The side whose outward normal points most towards the other piece.
  int axis = 0;
  double best_cosine = -2.0, sign = 1.0;
  for (int k = 0; k < 2; ++k) {
    for (double side_sign : {-1.0, 1.0}) {
      const double cosine = side_sign * own.axis[k].dot(to.normalized());
      if (cosine > best_cosine) {
        best_cosine = cosine;
        axis = k;
        sign = side_sign;
      }
    }
  }
  const int other = 1 - axis;
  const double reach = own.half[other] - margin;
  if (reach < margin) return 0.0;
  const Eigen::Vector2d outward = sign * own.axis[axis];
  double support = 0.0;
  for (double offset = -kGapSearchMm; offset <= kGapSearchMm + 1e-9; offset += step) {
    const Eigen::Vector2d mid = own.centre + (own.half[axis] + offset) * outward;
    support = std::max(support, probe.PolarSupport(mid - reach * own.axis[other],
                                                   mid + reach * own.axis[other], outward,
                                                   polarity, step));
  }
  return support;
}

// The mean of a piece's points.
Eigen::Vector2d CentreOf(const std::vector<Eigen::Vector2d>& piece) {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : piece) centre += p / static_cast<double>(piece.size());
  return centre;
}

}  // namespace

std::optional<GapBetweenPieces> LookAcrossGap(const std::vector<Eigen::Vector2d>& piece_a,
                                              const std::vector<Eigen::Vector2d>& piece_b,
                                              double height_mm, const Eigen::Matrix<double, 3, 4>& P,
                                              const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                              const TopFaceEdgeOptions& options) {
  if (piece_a.empty() || piece_b.empty() || gradient_x.empty()) return std::nullopt;
  std::vector<Eigen::Vector2d> joint = piece_a;
  joint.insert(joint.end(), piece_b.begin(), piece_b.end());
  const Frame f = FrameOf(MinAreaRectangle(joint));
  double near = 0.0, far = 0.0;
  const int along = WidestGap(f, piece_a, piece_b, &near, &far);
  if (along < 0 || far - near - 2.0 * options.corner_margin_mm < 2.0 * options.step_mm) {
    return std::nullopt;
  }
  const EdgeProbe probe(P, gradient_x, gradient_y, height_mm, options.min_edge_gradient);
  GapBetweenPieces gap;
  gap.sides_support = SidesAcrossGapSupport(probe, f, along, near, far, options);
  // The facing ends, both faces brighter than the gap (or both darker).
  const Eigen::Vector2d centre_a = CentreOf(piece_a), centre_b = CentreOf(piece_b);
  for (double polarity : {-1.0, 1.0}) {
    gap.ends_support =
        std::max(gap.ends_support, std::min(FacingEndSupport(probe, piece_a, centre_b, polarity, options),
                                            FacingEndSupport(probe, piece_b, centre_a, polarity, options)));
  }
  return gap;
}

}  // namespace hnnstereo::vision


