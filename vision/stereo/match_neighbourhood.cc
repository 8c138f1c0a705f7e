// The neighbourhood features of the per-match confidence (ConfidenceOptions in
// vision/stereo_matcher.h; docs/accuracy.md, "Confidence"). A file of its own: it is compiled
// with float reassociation (vision/CMakeLists.txt) so that its sums vectorise.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <opencv2/core/utility.hpp>

#include "common/cpu_clones.h"
#include "common/point_grid.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

namespace {

// The matches' points and displacements copied in the order of a uniform grid of their left
// points, so that a scan reads contiguous memory.
struct GridCopy {
  hnn::PointGrid grid;
  std::vector<float> px, py, sx, sy;
};

GridCopy CopyInGridOrder(const std::vector<StereoMatch>& matches,
                         const std::vector<Eigen::Vector2f>& points, float cell) {
  GridCopy c{hnn::PointGrid(points, cell), {}, {}, {}, {}};
  const std::size_t n = c.grid.items.size();
  c.px.resize(n), c.py.resize(n), c.sx.resize(n), c.sy.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const StereoMatch& m = matches[static_cast<std::size_t>(c.grid.items[k])];
    c.px[k] = m.left.x(), c.py[k] = m.left.y();
    c.sx[k] = m.right.x() - m.left.x(), c.sy[k] = m.right.y() - m.left.y();
  }
  return c;
}

// Inner rings (3, 6, 12 px; agreement within 1 px) and the surface within 12 px, for the grid
// items [first, last). Cloned for AVX-512 and AVX2 (host/cpu_clones.h): the default x86-64
// build has 16 vector registers of 4 floats, and the 21 running sums spilled to the stack.
HNNSTEREO_TARGET_CLONES("avx512f", "avx2", "default")
void InnerRings(const GridCopy& copy, int first, int last, std::vector<StereoMatch>& matches) {
  constexpr float kInner = kAgreementRadiiPx[2];
  const hnn::PointGrid& grid = copy.grid;
  const float *px = copy.px.data(), *py = copy.py.data(), *sx = copy.sx.data(),
              *sy = copy.sy.data();
  constexpr float r0 = kAgreementRadiiPx[0] * kAgreementRadiiPx[0];
  constexpr float r1 = kAgreementRadiiPx[1] * kAgreementRadiiPx[1];
  constexpr float r2 = kInner * kInner;
  for (int self = first; self < last; ++self) {
    const auto s = static_cast<std::size_t>(self);
    const float x = px[s], y = py[s], shift_x = sx[s], shift_y = sy[s];
    std::int32_t w0 = 0, w1 = 0, w2 = 0, a0 = 0, a1 = 0, a2 = 0;
    // Plane sums (the match itself included here, removed below).
    float n1 = 0, su = 0, sv = 0, suu = 0, suv = 0, svv = 0;
    float sx0 = 0, sxu = 0, sxv = 0, sy0 = 0, syu = 0, syv = 0;
    const int cx0 = grid.CellX(x - kInner), cx1 = grid.CellX(x + kInner);
    const int cy0 = grid.CellY(y - kInner), cy1 = grid.CellY(y + kInner);
    for (int cy = cy0; cy <= cy1; ++cy) {
      const std::size_t end = grid.RowEnd(cy, cx1);
      for (std::size_t k = grid.RowBegin(cy, cx0); k < end; ++k) {
        const float ex = px[k] - x, ey = py[k] - y;
        const float d2 = ex * ex + ey * ey;
        const float fx = sx[k] - shift_x, fy = sy[k] - shift_y;
        const std::int32_t agrees = fx * fx + fy * fy <= 1.0f ? 1 : 0;
        const std::int32_t in0 = d2 <= r0 ? 1 : 0, in1 = d2 <= r1 ? 1 : 0, in2 = d2 <= r2 ? 1 : 0;
        w0 += in0, w1 += in1, w2 += in2;
        a0 += in0 & agrees, a1 += in1 & agrees, a2 += in2 & agrees;
        const float w = static_cast<float>(in2);
        const float wx = w * ex, wy = w * ey;
        n1 += w, su += wx, sv += wy;
        suu += wx * ex, suv += wx * ey, svv += wy * ey;
        sx0 += w * sx[k], sxu += wx * sx[k], sxv += wy * sx[k];
        sy0 += w * sy[k], syu += wx * sy[k], syv += wy * sy[k];
      }
    }
    StereoMatch& m = matches[static_cast<std::size_t>(grid.items[s])];
    // The scan counted the match itself (d2 = 0, agrees), at (u, v) = (0, 0).
    m.neighbours[0] = w0 - 1, m.neighbours[1] = w1 - 1, m.neighbours[2] = w2 - 1;
    m.agreeing[0] = a0 - 1, m.agreeing[1] = a1 - 1, m.agreeing[2] = a2 - 1;
    n1 -= 1.0f, sx0 -= shift_x, sy0 -= shift_y;
    m.surface_residual = kSurfaceResidualCapPx;
    if (n1 >= 4.0f) {
      Eigen::Matrix3d normal;
      normal << n1, su, sv, su, suu, suv, sv, suv, svv;
      const double ridge = 1e-3 * (static_cast<double>(suu) + svv) / n1 + 1e-6;
      normal(1, 1) += ridge, normal(2, 2) += ridge;
      const Eigen::LDLT<Eigen::Matrix3d> solver(normal);
      const double ax = solver.solve(Eigen::Vector3d(sx0, sxu, sxv))(0);
      const double ay = solver.solve(Eigen::Vector3d(sy0, syu, syv))(0);
      const double residual = std::hypot(shift_x - ax, shift_y - ay);
      if (std::isfinite(residual)) {
        m.surface_residual = static_cast<float>(std::min<double>(residual, kSurfaceResidualCapPx));
      }
    }
  }
}

// The outer ring (24 px; agreement within 1 px + slope * distance), for the grid items
// [first, last). Cloned as InnerRings.
HNNSTEREO_TARGET_CLONES("avx512f", "avx2", "default")
void OuterRing(const GridCopy& copy, int first, int last, std::vector<StereoMatch>& matches) {
  constexpr float kOuter = kAgreementRadiiPx[3];
  const hnn::PointGrid& grid = copy.grid;
  const float *px = copy.px.data(), *py = copy.py.data(), *sx = copy.sx.data(),
              *sy = copy.sy.data();
  constexpr float r3 = kOuter * kOuter, slope = kAgreementSlope[3];
  for (int self = first; self < last; ++self) {
    const auto s = static_cast<std::size_t>(self);
    const float x = px[s], y = py[s], shift_x = sx[s], shift_y = sy[s];
    std::int32_t w3 = 0, a3 = 0;
    const int cx0 = grid.CellX(x - kOuter), cx1 = grid.CellX(x + kOuter);
    const int cy0 = grid.CellY(y - kOuter), cy1 = grid.CellY(y + kOuter);
    for (int cy = cy0; cy <= cy1; ++cy) {
      const std::size_t end = grid.RowEnd(cy, cx1);
      for (std::size_t k = grid.RowBegin(cy, cx0); k < end; ++k) {
        const float ex = px[k] - x, ey = py[k] - y;
        const float d2 = ex * ex + ey * ey;
        const float fx = sx[k] - shift_x, fy = sy[k] - shift_y;
        // |f| <= 1 + slope |e| without a square root: with L = |f|^2 - 1 - slope^2 |e|^2 it
        // reads L <= 2 slope |e|, i.e. L <= 0 or L^2 <= 4 slope^2 |e|^2.
        const float excess = fx * fx + fy * fy - 1.0f - slope * slope * d2;
        const std::int32_t agrees =
            (excess <= 0.0f ? 1 : 0) | (excess * excess <= 4.0f * slope * slope * d2 ? 1 : 0);
        const std::int32_t in = d2 <= r3 ? 1 : 0;
        w3 += in;
        a3 += in & agrees;
      }
    }
    StereoMatch& m = matches[static_cast<std::size_t>(grid.items[s])];
    m.neighbours[3] = w3 - 1, m.agreeing[3] = a3 - 1;
  }
}

}  // namespace

// Fills StereoMatch::neighbours / agreeing / surface_residual (ConfidenceOptions) for all
// decoded matches, in two passes over one uniform grid of the left points (cells of 12 px):
// each match scans the 3 x 3 cells around it for the inner rings and the surface, the 5 x 5
// for the outer ring (a 24 px grid's 3 x 3 cells read twice the area; a scan cut to the disk's
// chord over finer cells was measured too: its short rows made it slower). The points are
// copied in grid order, so a scan reads contiguous memory, and the counts are branch-free. The
// surface is the least-squares plane s(u, v) = a + b u + c v through the neighbours'
// displacements s within kSurfaceRadiusPx, in coordinates (u, v) centred on the match, so its
// value at the match is a: normal equations from the sums of 1, u, v, uu, uv, vv and s, us, vs
// (per displacement component), solved with a small ridge on the slopes so that neighbours on
// one line (an edge) still give a.
void CountAgreeingNeighbours(std::vector<StereoMatch>& matches, float scale) {
  if (matches.empty()) return;
  if (scale != 1.0f) {
    std::vector<StereoMatch> scaled = matches;
    for (StereoMatch& m : scaled) {
      m.left *= scale;
      m.right *= scale;
    }
    CountAgreeingNeighbours(scaled);
    for (std::size_t i = 0; i < matches.size(); ++i) {
      matches[i].neighbours = scaled[i].neighbours;
      matches[i].agreeing = scaled[i].agreeing;
      matches[i].surface_residual = scaled[i].surface_residual;
    }
    return;
  }
  static_assert(kAgreementRadiiPx.size() == 4 && kAgreementRadiiPx[2] == kSurfaceRadiusPx &&
                kAgreementSlope[0] == 0.0f && kAgreementSlope[1] == 0.0f && kAgreementSlope[2] == 0.0f);
  std::vector<Eigen::Vector2f> points(matches.size());
  for (std::size_t i = 0; i < matches.size(); ++i) points[i] = matches[i].left;
  const auto stripes = static_cast<double>(std::max<std::size_t>(1, matches.size() / 1024));
  const cv::Range all(0, static_cast<int>(matches.size()));
  const GridCopy copy = CopyInGridOrder(matches, points, kAgreementRadiiPx[2]);
  cv::parallel_for_(
      all, [&](const cv::Range& range) { InnerRings(copy, range.start, range.end, matches); },
      stripes);
  cv::parallel_for_(
      all, [&](const cv::Range& range) { OuterRing(copy, range.start, range.end, matches); },
      stripes);
}

}  // namespace hnnstereo::vision
