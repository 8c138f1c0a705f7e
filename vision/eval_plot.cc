#include "vision/eval_plot.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

constexpr int kPanelWidth = 420;
constexpr int kPanelHeight = 320;
constexpr int kMargin = 44;

const cv::Scalar kColours[] = {{40, 40, 220},  {220, 120, 30}, {30, 160, 30},  {160, 40, 160},
                               {20, 160, 200}, {120, 120, 120}, {0, 90, 160}, {200, 60, 120}};

cv::Scalar ColourOf(std::size_t index) { return kColours[index % (sizeof kColours / sizeof kColours[0])]; }

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
    cv::putText(panel, label, to_pixel(share, 0.0) + cv::Point(-8, 16), cv::FONT_HERSHEY_SIMPLEX, 0.35,
                cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
    cv::putText(panel, label, to_pixel(0.0, share) + cv::Point(-28, 4), cv::FONT_HERSHEY_SIMPLEX, 0.35,
                cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  }
  cv::rectangle(panel, to_pixel(0.0, 1.0), to_pixel(1.0, 0.0), cv::Scalar(0, 0, 0), 1);
  cv::putText(panel, pair.name, cv::Point(left + 60, 16), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0),
              1, cv::LINE_AA);
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
      if (curve.size() == 1 || i + 1 == curve.size()) cv::circle(panel, p, 4, colour, cv::FILLED, cv::LINE_AA);
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
