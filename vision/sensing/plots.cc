#include "vision/sensing/plots.h"

#include "vision/stereo/overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

constexpr int kPlotWidth = 900;
constexpr int kPlotHeight = 450;
constexpr int kMarginLeft = 80, kMarginRight = 25, kMarginTop = 36, kMarginBottom = 50;

std::string Format(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

// A round tick step (1, 2 or 5 times a power of ten) giving about `target` ticks over `range`.
double NiceStep(double range, int target) {
  const double raw = range / std::max(1, target);
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  for (double nice : {1.0, 2.0, 5.0, 10.0}) {
    if (nice * power >= raw) return nice * power;
  }
  return 10.0 * power;
}

// Axes with a title and labels and round tick values; returns the plotting rectangle. With
// `log_x` the x axis shows log10(1 + x), ticks at 0, 1, 10, 100...
cv::Rect DrawAxes(cv::Mat& canvas, const std::string& title, const std::string& x_label,
                  const std::string& y_label, double x_min, double x_max, double y_min,
                  double y_max, bool log_x = false) {
  const cv::Rect area(kMarginLeft, kMarginTop, kPlotWidth - kMarginLeft - kMarginRight,
                      kPlotHeight - kMarginTop - kMarginBottom);
  const cv::Scalar ink(40, 40, 40), grid(225, 225, 225);
  cv::putText(canvas, title, {kMarginLeft, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.6, ink, 1, cv::LINE_AA);
  cv::putText(canvas, x_label, {area.x + area.width / 2 - 60, kPlotHeight - 10},
              cv::FONT_HERSHEY_SIMPLEX, 0.5, ink, 1, cv::LINE_AA);
  cv::putText(canvas, y_label, {6, kMarginTop - 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45, ink, 1,
              cv::LINE_AA);
  auto x_of = [&](double x) {
    const double f = log_x ? std::log10(1.0 + x - x_min) / std::log10(1.0 + x_max - x_min)
                           : (x - x_min) / (x_max - x_min);
    return area.x + static_cast<int>(std::lround(f * area.width));
  };
  std::vector<double> x_ticks;
  if (log_x) {
    x_ticks.push_back(x_min);
    for (double decade = 1.0; decade <= x_max - x_min; decade *= 10.0) x_ticks.push_back(x_min + decade);
  } else {
    const double step = NiceStep(x_max - x_min, 6);
    for (double x = std::ceil(x_min / step) * step; x <= x_max + 1e-9 * step; x += step) {
      x_ticks.push_back(x);
    }
  }
  for (double x : x_ticks) {
    const int px = x_of(x);
    cv::line(canvas, {px, area.y}, {px, area.y + area.height}, grid);
    cv::line(canvas, {px, area.y + area.height}, {px, area.y + area.height + 5}, ink);
    const std::string label = Format("%g", std::abs(x) < 1e-9 ? 0.0 : x);
    cv::putText(canvas, label, {px - 4 * static_cast<int>(label.size()), area.y + area.height + 20},
                cv::FONT_HERSHEY_SIMPLEX, 0.45, ink, 1, cv::LINE_AA);
  }
  const double y_step = NiceStep(y_max - y_min, 5);
  for (double y = std::ceil(y_min / y_step) * y_step; y <= y_max + 1e-9 * y_step; y += y_step) {
    const int py = area.y + area.height -
                   static_cast<int>(std::lround((y - y_min) / (y_max - y_min) * area.height));
    cv::line(canvas, {area.x, py}, {area.x + area.width, py}, grid);
    cv::line(canvas, {area.x - 5, py}, {area.x, py}, ink);
    cv::putText(canvas, Format("%g", std::abs(y) < 1e-9 * y_step ? 0.0 : y), {6, py + 5},
                cv::FONT_HERSHEY_SIMPLEX, 0.45, ink, 1, cv::LINE_AA);
  }
  cv::rectangle(canvas, area, ink, 1);
  return area;
}

// Text with a dark outline: legible on any background, the part's own colour included.
void OutlinedText(cv::Mat& canvas, const std::string& text, cv::Point at, const cv::Scalar& colour,
                  double scale = 0.55) {
  cv::putText(canvas, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar::all(0), 4, cv::LINE_AA);
  cv::putText(canvas, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

}  // namespace

cv::Scalar LabelColour(int label) {
  if (label < 0) return {150, 150, 150};
  static const cv::Scalar kPalette[] = {{60, 60, 255},  {60, 220, 60},  {255, 120, 40},
                                        {0, 220, 255},  {255, 60, 220}, {255, 255, 60},
                                        {120, 60, 200}, {60, 160, 255}, {180, 255, 140},
                                        {200, 200, 255}};
  return kPalette[label % 10];
}

cv::Mat DrawObjectOverlay(const cv::Mat& left_image, const PositionSensingReport& report,
                          const calib::ProjectionMatrix& P1, double line_length_mm) {
  cv::Mat canvas = ToColour8(left_image) * 0.6;
  for (const auto& p : report.match.left_features) {
    cv::circle(canvas, cv::Point2f(p.x(), p.y()), 1, cv::Scalar(110, 110, 110), cv::FILLED);
  }
  for (std::size_t k = 0; k < report.points_in_world.size(); ++k) {
    const StereoMatch& match =
        report.match.matches[static_cast<std::size_t>(report.match_of_point[k])];
    const int label = k < report.clustering.labels.size() ? report.clustering.labels[k] : -1;
    // Colour by part: the clustering's labels are renumbered tallest first below.
    cv::Scalar colour(255, 255, 255);
    if (label >= 0) {
      for (std::size_t o = 0; o < report.objects.size(); ++o) {
        const auto& indices = report.objects[o].point_indices;
        if (std::find(indices.begin(), indices.end(), static_cast<int>(k)) != indices.end()) {
          colour = LabelColour(static_cast<int>(o));
          break;
        }
      }
    }
    cv::circle(canvas, cv::Point2f(match.left.x(), match.left.y()), 1, colour, cv::FILLED);
  }
  auto project = [&](const Eigen::Vector3d& point) {
    const Eigen::Vector2d x = (P1 * point.homogeneous()).hnormalized();
    return cv::Point2d(x.x(), x.y());
  };
  for (std::size_t o = 0; o < report.objects.size(); ++o) {
    const ObjectPose& pose = report.objects[o];
    const double yaw = pose.yaw_deg * std::numbers::pi / 180.0;
    // yaw in (-90, 90]: the line points towards world +x, so negative angles turn it the other
    // way round the centroid, as seen on the table.
    const Eigen::Vector3d tip =
        pose.centroid + line_length_mm * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0.0);
    const cv::Point2d centre = project(pose.centroid);
    const cv::Scalar colour = LabelColour(static_cast<int>(o));
    cv::drawMarker(canvas, centre, cv::Scalar::all(0), cv::MARKER_CROSS, 14, 4, cv::LINE_AA);
    cv::drawMarker(canvas, centre, colour, cv::MARKER_CROSS, 14, 2, cv::LINE_AA);
    // A round part has no orientation: no yaw arrow (its yaw is sent as 0).
    if (!pose.round) {
      cv::arrowedLine(canvas, centre, project(tip), cv::Scalar::all(0), 4, cv::LINE_AA, 0, 0.2);
      cv::arrowedLine(canvas, centre, project(tip), colour, 2, cv::LINE_AA, 0, 0.2);
    }
    OutlinedText(canvas,
                 std::to_string(o + 1) + ": " + Format("%.0f mm", pose.height_mm) +
                     (pose.round ? " (round)" : ""),
                 cv::Point(static_cast<int>(centre.x) + 8, static_cast<int>(centre.y) - 8), colour);
  }
  return canvas;
}

cv::Mat PlotHeightHistogram(const PositionSensingReport& report, double bin_mm) {
  cv::Mat canvas(kPlotHeight, kPlotWidth, CV_8UC3, cv::Scalar::all(255));
  double z_min = -5.0, z_max = 50.0;
  for (const auto& p : report.points_in_world) {
    z_min = std::min(z_min, p.z());
    z_max = std::max(z_max, p.z());
  }
  z_min = bin_mm * std::floor(std::max(z_min, -50.0) / bin_mm);
  z_max = bin_mm * std::ceil(std::min(z_max, 300.0) / bin_mm);
  const int bins = std::max(1, static_cast<int>(std::lround((z_max - z_min) / bin_mm)));
  std::vector<int> counts(static_cast<std::size_t>(bins), 0);
  for (const auto& p : report.points_in_world) {
    const int bin = static_cast<int>(std::floor((p.z() - z_min) / bin_mm));
    if (bin >= 0 && bin < bins) ++counts[static_cast<std::size_t>(bin)];
  }
  const int peak = std::max(1, *std::max_element(counts.begin(), counts.end()));
  const cv::Rect area = DrawAxes(canvas, "heights of the triangulated points (z above the table)",
                                 "height z (mm)", "points", z_min, z_max, 0, peak);
  for (int b = 0; b < bins; ++b) {
    const int x0 = area.x + b * area.width / bins, x1 = area.x + (b + 1) * area.width / bins;
    const int h = static_cast<int>(
        std::lround(static_cast<double>(counts[static_cast<std::size_t>(b)]) / peak * area.height));
    cv::rectangle(canvas, cv::Rect(x0, area.y + area.height - h, std::max(1, x1 - x0 - 1), h),
                  cv::Scalar(180, 120, 60), cv::FILLED);
  }
  for (std::size_t o = 0; o < report.objects.size(); ++o) {
    const double z = report.objects[o].height_mm;
    const int x = area.x + static_cast<int>((z - z_min) / (z_max - z_min) * area.width);
    cv::line(canvas, {x, area.y}, {x, area.y + area.height}, LabelColour(static_cast<int>(o)), 1);
    cv::line(canvas, {x, area.y}, {x, area.y + area.height}, LabelColour(static_cast<int>(o)), 2);
    OutlinedText(canvas, "part " + std::to_string(o + 1),
                 {x + 3, area.y + 16 + 16 * static_cast<int>(o % 4)},
                 LabelColour(static_cast<int>(o)), 0.45);
  }
  return canvas;
}

cv::Mat PlotEnergyTrace(const hnn::SolveReport& solve) {
  cv::Mat canvas(kPlotHeight, kPlotWidth, CV_8UC3, cv::Scalar::all(255));
  std::vector<double> energy = solve.energy_trace;
  std::vector<double> iteration;
  for (std::size_t k = 0; k < energy.size(); ++k) {
    iteration.push_back(k < solve.energy_trace_iterations.size()
                            ? solve.energy_trace_iterations[k]
                            : static_cast<double>(k));
  }
  if (energy.empty()) {
    energy = {solve.energy_initial, solve.energy_final};
    iteration = {0.0, static_cast<double>(std::max(1, solve.iterations))};
  }
  const auto [e_lo, e_hi] = std::minmax_element(energy.begin(), energy.end());
  double e_min = *e_lo, e_max = *e_hi;
  if (e_max - e_min < 1e-9) {
    e_min -= 1.0;
    e_max += 1.0;
  }
  const double i_max = std::max(1.0, iteration.back());
  // Log iteration axis: the energy falls in the first steps, then creeps; both stay visible.
  const cv::Rect area =
      DrawAxes(canvas, "Hopfield energy (eq. 6.10), " + solve.engine + ", " + solve.termination,
               "iteration (log scale)", "energy", 0.0, i_max, e_min, e_max, true);
  std::vector<cv::Point> polyline;
  for (std::size_t k = 0; k < energy.size(); ++k) {
    polyline.emplace_back(
        area.x + static_cast<int>(std::log10(1.0 + iteration[k]) / std::log10(1.0 + i_max) *
                                  area.width),
        area.y + area.height - static_cast<int>((energy[k] - e_min) / (e_max - e_min) * area.height));
  }
  cv::polylines(canvas, polyline, false, cv::Scalar(200, 80, 30), 2, cv::LINE_AA);
  return canvas;
}

}  // namespace hnnstereo::vision
