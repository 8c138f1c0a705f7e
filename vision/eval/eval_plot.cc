#include "vision/eval/eval_plot.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include <opencv2/imgproc.hpp>

#include "common/format.h"

namespace hnnstereo::vision {
namespace {

constexpr int kPanelWidth = 420;
constexpr int kPanelHeight = 320;
constexpr int kMargin = 44;

const cv::Scalar kColours[] = {{40, 40, 220},  {220, 120, 30},  {30, 160, 30}, {160, 40, 160},
                               {20, 160, 200}, {120, 120, 120}, {0, 90, 160},  {200, 60, 120}};

cv::Scalar ColourOf(std::size_t index) {
  return kColours[index % (sizeof kColours / sizeof kColours[0])];
}

void DrawPanel(cv::Mat panel, const PairEvaluation& pair, const std::vector<std::string>& methods,
               bool legend) {
  panel.setTo(cv::Scalar(255, 255, 255));
  const int left = kMargin, right = kPanelWidth - 12, top = 24, bottom = kPanelHeight - kMargin;
  auto to_pixel = [&](double density, double precision) {
    const double x = left + std::clamp(density, 0.0, 1.0) * (right - left);
    const double y = bottom - std::clamp(precision, 0.0, 1.0) * (bottom - top);
    return cv::Point(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)));
  };
  for (int tick = 0; tick <= 10; tick += 2) {
    const double share = tick / 10.0;
    cv::line(panel, to_pixel(share, 0.0), to_pixel(share, 1.0), cv::Scalar(225, 225, 225), 1);
    cv::line(panel, to_pixel(0.0, share), to_pixel(1.0, share), cv::Scalar(225, 225, 225), 1);
    const std::string label = std::to_string(tick * 10);
    cv::putText(panel, label, to_pixel(share, 0.0) + cv::Point(-8, 16), cv::FONT_HERSHEY_SIMPLEX,
                0.35, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
    cv::putText(panel, label, to_pixel(0.0, share) + cv::Point(-28, 4), cv::FONT_HERSHEY_SIMPLEX,
                0.35, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  }
  cv::rectangle(panel, to_pixel(0.0, 1.0), to_pixel(1.0, 0.0), cv::Scalar(0, 0, 0), 1);
  cv::putText(panel, pair.name, cv::Point(left + 60, 16), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(panel, "density % of Canny edges", cv::Point(left + 100, kPanelHeight - 8),
              cv::FONT_HERSHEY_SIMPLEX, 0.38, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(panel, "prec. 1px %", cv::Point(2, top - 6), cv::FONT_HERSHEY_SIMPLEX, 0.35,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  for (const auto& [method, curve] : pair.curves) {
    const auto it = std::find(methods.begin(), methods.end(), method);
    const cv::Scalar colour = ColourOf(static_cast<std::size_t>(it - methods.begin()));
    for (std::size_t i = 0; i < curve.size(); ++i) {
      const cv::Point p = to_pixel(curve[i].density, curve[i].precision_1px);
      if (i > 0) {
        cv::line(panel, to_pixel(curve[i - 1].density, curve[i - 1].precision_1px), p, colour, 2,
                 cv::LINE_AA);
      }
      if (curve.size() == 1 || i + 1 == curve.size())
        cv::circle(panel, p, 4, colour, cv::FILLED, cv::LINE_AA);
    }
  }
  if (legend) {
    int y = bottom - 12 * static_cast<int>(methods.size());
    for (std::size_t m = 0; m < methods.size(); ++m, y += 12) {
      cv::line(panel, cv::Point(left + 8, y - 3), cv::Point(left + 24, y - 3), ColourOf(m), 2);
      cv::putText(panel, methods[m], cv::Point(left + 28, y), cv::FONT_HERSHEY_SIMPLEX, 0.33,
                  cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    }
  }
}

}  // namespace

cv::Mat DrawPrecisionDensityPlot(const EvaluationReport& report) {
  std::vector<std::string> methods;
  for (const PairEvaluation& pair : report.pairs) {
    for (const auto& curve : pair.curves) {
      if (std::find(methods.begin(), methods.end(), curve.first) == methods.end()) {
        methods.push_back(curve.first);
      }
    }
  }
  const int n = std::max<int>(1, static_cast<int>(report.pairs.size()));
  const int columns = std::min(n, 3);
  const int rows = (n + columns - 1) / columns;
  cv::Mat plot(rows * kPanelHeight, columns * kPanelWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  for (int i = 0; i < static_cast<int>(report.pairs.size()); ++i) {
    const cv::Rect cell((i % columns) * kPanelWidth, (i / columns) * kPanelHeight, kPanelWidth,
                        kPanelHeight);
    DrawPanel(plot(cell), report.pairs[static_cast<std::size_t>(i)], methods, i == 0);
  }
  return plot;
}

}  // namespace hnnstereo::vision

namespace hnnstereo::vision {
namespace {

constexpr int kRankedWidth = 1000;
constexpr int kRankedHeight = 680;

void DashedLine(cv::Mat& image, cv::Point a, cv::Point b, const cv::Scalar& colour, int dash = 6) {
  const double length = std::hypot(b.x - a.x, b.y - a.y);
  const int pieces = std::max(1, static_cast<int>(length / dash));
  for (int i = 0; i < pieces; i += 2) {
    const double t0 = double(i) / pieces, t1 = std::min(1.0, double(i + 1) / pieces);
    cv::line(image, a + (b - a) * t0, a + (b - a) * t1, colour, 1, cv::LINE_AA);
  }
}

void Text(cv::Mat& image, const std::string& text, cv::Point at, double scale = 0.5,
          const cv::Scalar& colour = cv::Scalar(0, 0, 0), int thickness = 1) {
  cv::putText(image, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv::LINE_AA);
}

void Marker(cv::Mat& image, cv::Point p, const cv::Scalar& colour, bool square) {
  if (square) {
    cv::rectangle(image, p - cv::Point(5, 5), p + cv::Point(5, 5), colour, cv::FILLED);
    cv::rectangle(image, p - cv::Point(5, 5), p + cv::Point(5, 5), cv::Scalar(0, 0, 0), 1);
  } else {
    cv::circle(image, p, 6, colour, cv::FILLED, cv::LINE_AA);
    cv::circle(image, p, 6, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
}

}  // namespace

namespace {

// The ranked plot's axes: density 0-1 across [left, right] px, precision y_min-1 up
// [bottom, top] px, y ticks every y_step from first_tick (round values, 100 %).
struct RankedAxes {
  int left = 80, right = kRankedWidth - 30, top = 60, bottom = kRankedHeight - 70;
  double y_min = 0.0, y_span = 1.0, y_step = 0.1, first_tick = 0.0;

  cv::Point ToPixel(double density, double precision) const {
    const double x = left + std::clamp(density, 0.0, 1.0) * (right - left);
    const double y = bottom - std::clamp((precision - y_min) / y_span, 0.0, 1.0) * (bottom - top);
    return cv::Point(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)));
  }
};

// Y range: from the lowest precision shown (rounded down to 5 %) to 100 %.
RankedAxes RankedAxesFor(const std::vector<std::vector<CurvePoint>>& curves) {
  double lowest = 1.0;
  for (const std::vector<CurvePoint>& curve : curves) {
    for (const CurvePoint& c : curve) lowest = std::min(lowest, c.precision_1px);
  }
  RankedAxes axes;
  axes.y_min = std::clamp(std::floor((lowest - 0.01) * 20.0) / 20.0, 0.0, 0.95);
  axes.y_span = 1.0 - axes.y_min;
  const double y_span = axes.y_span;
  axes.y_step = y_span > 0.5 ? 0.1 : y_span > 0.2 ? 0.05 : y_span > 0.1 ? 0.02 : 0.01;
  axes.first_tick = std::ceil(axes.y_min / axes.y_step - 1e-9) * axes.y_step;
  return axes;
}

// The grid, tick labels, the table's density guides (dashed) and the frame.
void DrawRankedGrid(cv::Mat& plot, const RankedAxes& axes) {
  const cv::Scalar grid(228, 228, 228), ink(40, 40, 40);
  for (int tick = 0; tick <= 10; ++tick) {
    const double share = tick / 10.0;
    cv::line(plot, axes.ToPixel(share, axes.y_min), axes.ToPixel(share, 1.0), grid, 1);
    Text(plot, std::to_string(tick * 10),
         axes.ToPixel(share, axes.y_min) + cv::Point(tick == 10 ? -14 : -8, 22), 0.5, ink);
  }
  for (int k = 0;; ++k) {
    const double precision = axes.first_tick + k * axes.y_step;
    if (precision > 1.0 + 1e-9) break;
    cv::line(plot, axes.ToPixel(0.0, precision), axes.ToPixel(1.0, precision), grid, 1);
    char label[16];
    std::snprintf(label, sizeof label, "%.0f", 100.0 * precision);
    Text(plot, label, axes.ToPixel(0.0, precision) + cv::Point(-38, 5), 0.5, ink);
  }
  for (const double guide : kTableDensities) {
    DashedLine(plot, axes.ToPixel(guide, axes.y_min), axes.ToPixel(guide, 1.0),
               cv::Scalar(150, 150, 150));
  }
  cv::rectangle(plot, axes.ToPixel(0.0, 1.0), axes.ToPixel(1.0, axes.y_min), cv::Scalar(0, 0, 0),
                1);
}

// The title (shrunk to fit), the x label and the rotated y label.
void DrawRankedLabels(cv::Mat& plot, const PairEvaluation& pair, const RankedAxes& axes) {
  const int left = axes.left;
  {
    const std::string title =
        pair.name + ": precision vs density, each method ranked by its own confidence";
    double scale = 0.65;
    int baseline = 0;
    while (scale > 0.4 &&
           cv::getTextSize(title, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline).width >
               kRankedWidth - 20 - left / 2) {
      scale -= 0.05;
    }
    Text(plot, title, cv::Point(left / 2, 30), scale, cv::Scalar(0, 0, 0), 1);
  }
  Text(plot, "density: % of left Canny edge pixels with ground truth that get a kept match",
       cv::Point(left + 150, kRankedHeight - 20), 0.55);
  const std::string label = "precision within 1 px (% of kept non-occluded matches)";
  int baseline = 0;
  const cv::Size size = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, 0.55, 1, &baseline);
  cv::Mat strip(size.height + baseline + 4, size.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
  Text(strip, label, cv::Point(2, size.height + 1), 0.55);
  cv::Mat rotated;
  cv::rotate(strip, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int y0 = std::max(0, (axes.top + axes.bottom) / 2 - rotated.rows / 2);
  if (y0 + rotated.rows <= plot.rows && rotated.cols + 8 < left) {
    rotated.copyTo(plot(cv::Rect(8, y0, rotated.cols, rotated.rows)));
  }
}

// One legend row: its text, colour and symbol (0 thick line, 1 line, 2 circles, 3 squares).
struct LegendEntry {
  std::string label;
  cv::Scalar colour;
  int kind = 0;
};

// A swept baseline's curve: thin line, a marker per setting (circles SGBM, squares BM), each
// labelled with its uniqueness ratio above-right or below-left of its marker, wherever it
// overlaps no label in `placed_labels` (crowded settings stay unlabelled rather than
// unreadable).
void DrawSweptCurve(cv::Mat& plot, const RankedAxes& axes, const RankedMethod& method,
                    const std::vector<CurvePoint>& curve, const cv::Scalar& colour, bool sgbm,
                    std::vector<cv::Rect>* placed_labels) {
  for (std::size_t i = 1; i < curve.size(); ++i) {
    cv::line(plot, axes.ToPixel(curve[i - 1].density, curve[i - 1].precision_1px),
             axes.ToPixel(curve[i].density, curve[i].precision_1px), colour, 1, cv::LINE_AA);
  }
  for (std::size_t i = 0; i < curve.size(); ++i) {
    const cv::Point p = axes.ToPixel(curve[i].density, curve[i].precision_1px);
    Marker(plot, p, colour, !sgbm);
    const std::string label = std::to_string(method.sweep[i].uniqueness_ratio);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &baseline);
    for (const cv::Point offset : {cv::Point(8, -8), cv::Point(-8 - size.width, 18)}) {
      const cv::Rect box(p + offset - cv::Point(1, size.height + 1), size + cv::Size(2, 3));
      const bool free = std::none_of(placed_labels->begin(), placed_labels->end(),
                                     [&](const cv::Rect& r) { return (r & box).area() > 0; });
      if (!free) continue;
      placed_labels->push_back(box);
      Text(plot, label, p + offset, 0.45, cv::Scalar(255, 255, 255), 4);  // a halo over lines
      Text(plot, label, p + offset, 0.45, colour);
      break;
    }
  }
}

// A ranked curve (thickness 3 for the presets, 2 for WTA) with a dot at its densest end.
void DrawRankedCurve(cv::Mat& plot, const RankedAxes& axes, const std::vector<CurvePoint>& curve,
                     const cv::Scalar& colour, int thickness) {
  for (std::size_t i = 1; i < curve.size(); ++i) {
    cv::line(plot, axes.ToPixel(curve[i - 1].density, curve[i - 1].precision_1px),
             axes.ToPixel(curve[i].density, curve[i].precision_1px), colour, thickness,
             cv::LINE_AA);
  }
  if (!curve.empty()) {
    cv::circle(plot, axes.ToPixel(curve.back().density, curve.back().precision_1px), 5, colour,
               cv::FILLED, cv::LINE_AA);
  }
}

// Every method's curve; returns the legend. Colours (BGR): HNN presets red, orange, purple,
// grey; WTA green; SGBM blue; BM brown.
std::vector<LegendEntry> DrawRankedCurves(cv::Mat& plot, const RankedAxes& axes,
                                          const PairEvaluation& pair,
                                          const std::vector<std::vector<CurvePoint>>& curves) {
  const cv::Scalar hnn_colours[] = {{30, 30, 215}, {0, 140, 255}, {160, 40, 160}, {120, 120, 120}};
  std::size_t hnn_index = 0;
  std::vector<LegendEntry> legend;
  std::vector<cv::Rect> placed_labels;
  for (std::size_t m = 0; m < pair.ranked.size(); ++m) {
    const RankedMethod& method = pair.ranked[m];
    const bool wta = method.method.rfind("wta", 0) == 0;
    const bool sgbm = method.method.find("sgbm") != std::string::npos;
    LegendEntry entry;
    entry.label = method.method;
    if (method.swept) {
      entry.colour = sgbm ? cv::Scalar(200, 110, 20) : cv::Scalar(40, 90, 140);
      entry.kind = sgbm ? 2 : 3;
      DrawSweptCurve(plot, axes, method, curves[m], entry.colour, sgbm, &placed_labels);
      entry.label += " (number = uniqueness ratio)";
    } else {
      entry.colour = wta ? cv::Scalar(40, 150, 40) : hnn_colours[hnn_index++ % 4];
      entry.kind = wta ? 1 : 0;
      DrawRankedCurve(plot, axes, curves[m], entry.colour, wta ? 2 : 3);
      if (!wta) entry.label += " (by confidence)";
    }
    legend.push_back(std::move(entry));
  }
  return legend;
}

// The legend: a boxed list in the lower-left corner of the axes.
void DrawRankedLegend(cv::Mat& plot, const RankedAxes& axes,
                      const std::vector<LegendEntry>& legend) {
  const int row_height = 24;
  int legend_width = 0;
  for (const LegendEntry& entry : legend) {
    int baseline = 0;
    legend_width =
        std::max(legend_width,
                 cv::getTextSize(entry.label, cv::FONT_HERSHEY_SIMPLEX, 0.5, 1, &baseline).width);
  }
  const cv::Rect box(axes.left + 12,
                     axes.bottom - 12 - row_height * static_cast<int>(legend.size()) - 8,
                     legend_width + 60, row_height * static_cast<int>(legend.size()) + 8);
  cv::rectangle(plot, box, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(plot, box, cv::Scalar(120, 120, 120), 1);
  for (std::size_t i = 0; i < legend.size(); ++i) {
    const int y = box.y + 4 + row_height * static_cast<int>(i) + row_height / 2;
    const cv::Point a(box.x + 8, y), b(box.x + 40, y);
    switch (legend[i].kind) {
      case 0:
        cv::line(plot, a, b, legend[i].colour, 3, cv::LINE_AA);
        break;
      case 1:
        cv::line(plot, a, b, legend[i].colour, 2, cv::LINE_AA);
        break;
      default:
        cv::line(plot, a, b, legend[i].colour, 1, cv::LINE_AA);
        Marker(plot, (a + b) / 2, legend[i].colour, legend[i].kind == 3);
    }
    Text(plot, legend[i].label, cv::Point(box.x + 50, y + 6), 0.5);
  }
}

}  // namespace

cv::Mat DrawRankedPlot(const PairEvaluation& pair) {
  if (pair.ranked.empty()) return {};
  cv::Mat plot(kRankedHeight, kRankedWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  std::vector<std::vector<CurvePoint>> curves;
  for (const RankedMethod& m : pair.ranked) curves.push_back(m.Curve());
  const RankedAxes axes = RankedAxesFor(curves);
  DrawRankedGrid(plot, axes);
  DrawRankedLabels(plot, pair, axes);
  DrawRankedLegend(plot, axes, DrawRankedCurves(plot, axes, pair, curves));
  return plot;
}

cv::Mat DrawCalibrationPlot(const EvaluationReport& report) {
  const RankedSummary summary = SummarizeRanked(report);
  if (summary.calibration.empty()) return {};
  const std::string method = summary.calibration.front().method;
  std::vector<const ConfidenceCalibration*> tables;
  for (const ConfidenceCalibration& c : summary.calibration) {
    if (c.method == method) tables.push_back(&c);
  }
  constexpr std::size_t kBins = ConfidenceCalibration::kBins;
  double y_max = 0.1;
  for (const ConfidenceCalibration* c : tables) {
    for (std::size_t b = 0; b < kBins; ++b) {
      if (c->matches[b] > 0.0) y_max = std::max(y_max, c->Error(b));
    }
  }
  y_max = std::ceil(y_max * 10.0) / 10.0;
  const int width = 900, height = 560, left = 80, right = width - 200, top = 50,
            bottom = height - 70;
  cv::Mat plot(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  auto to_pixel = [&](double slot, double error) {
    const double x = left + (slot + 0.5) / kBins * (right - left);
    const double y = bottom - std::clamp(error / y_max, 0.0, 1.0) * (bottom - top);
    return cv::Point(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)));
  };
  for (int tick = 0; tick <= 10; ++tick) {
    const double error = y_max * tick / 10.0;
    const cv::Point a(left, to_pixel(0, error).y), b(right, to_pixel(0, error).y);
    cv::line(plot, a, b, cv::Scalar(225, 225, 225), 1);
    Text(plot, std::to_string(static_cast<int>(std::lround(error * 100.0))), a + cv::Point(-30, 4),
         0.4);
  }
  for (std::size_t b = 0; b < kBins; ++b) {
    const std::string label = common::Fixed(kConfidenceBinEdges[b], 2) + "-" +
                              common::Fixed(kConfidenceBinEdges[b + 1], 2);
    Text(plot, label, cv::Point(to_pixel(static_cast<double>(b), 0).x - 34, bottom + 20), 0.4);
  }
  cv::rectangle(plot, cv::Point(left, top), cv::Point(right, bottom), cv::Scalar(0, 0, 0), 1);
  Text(plot, method + ": error rate against confidence", cv::Point(left, 30), 0.6);
  Text(plot, "confidence bin", cv::Point((left + right) / 2 - 50, height - 20), 0.5);
  Text(plot, "error %", cv::Point(10, top - 12), 0.45);
  auto draw = [&](const ConfidenceCalibration& c, const cv::Scalar& colour, int thickness,
                  bool ideal) {
    std::optional<cv::Point> previous;
    for (std::size_t b = 0; b < kBins; ++b) {
      if (c.matches[b] <= 0.0) continue;
      const double error = ideal ? 1.0 - c.MeanConfidence(b) : c.Error(b);
      const cv::Point p = to_pixel(static_cast<double>(b), error);
      if (previous) {
        if (ideal) {
          DashedLine(plot, *previous, p, colour);
        } else {
          cv::line(plot, *previous, p, colour, thickness, cv::LINE_AA);
        }
      }
      if (!ideal && thickness > 1) cv::circle(plot, p, 4, colour, cv::FILLED, cv::LINE_AA);
      previous = p;
    }
  };
  for (const ConfidenceCalibration* c : tables) {
    if (c->n_pairs == 1 && c->group != "overall") draw(*c, cv::Scalar(200, 200, 200), 1, false);
  }
  int legend_y = top + 10;
  std::size_t colour = 0;
  for (const ConfidenceCalibration* c : tables) {
    const bool pooled = c->group == "overall" || c->group == "indoor" || c->group == "outdoor";
    if (!pooled) continue;
    const cv::Scalar line_colour = c->group == "overall" ? cv::Scalar(0, 0, 0) : ColourOf(colour++);
    draw(*c, line_colour, 2, false);
    if (c->group == "overall") draw(*c, cv::Scalar(0, 0, 0), 1, true);
    cv::line(plot, cv::Point(right + 15, legend_y - 4), cv::Point(right + 40, legend_y - 4),
             line_colour, 2);
    Text(plot, c->group + " (" + std::to_string(c->n_pairs) + ")", cv::Point(right + 46, legend_y),
         0.45);
    legend_y += 20;
  }
  DashedLine(plot, cv::Point(right + 15, legend_y - 4), cv::Point(right + 40, legend_y - 4),
             cv::Scalar(0, 0, 0));
  Text(plot, "1 - confidence", cv::Point(right + 46, legend_y), 0.45);
  legend_y += 20;
  cv::line(plot, cv::Point(right + 15, legend_y - 4), cv::Point(right + 40, legend_y - 4),
           cv::Scalar(200, 200, 200), 1);
  Text(plot, "each pair", cv::Point(right + 46, legend_y), 0.45);
  return plot;
}

}  // namespace hnnstereo::vision
