#include "vision/stereo/overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "common/format.h"


namespace hnnstereo::vision {

cv::Mat ToColour8(const cv::Mat& image) {
  cv::Mat eight;
  if (image.depth() == CV_16U) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(image.reshape(1), &lo, &hi);
    image.convertTo(eight, CV_8U, hi > lo ? 255.0 / (hi - lo) : 1.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);
  } else {
    eight = image;
  }
  cv::Mat colour;
  if (eight.channels() == 1) {
    cv::cvtColor(eight, colour, cv::COLOR_GRAY2BGR);
  } else if (eight.channels() == 4) {
    cv::cvtColor(eight, colour, cv::COLOR_BGRA2BGR);
  } else {
    colour = eight.clone();
  }
  return colour;
}


namespace {

// Blue (small) -> green -> red (large), t in [0, 1].
cv::Scalar DisparityColour(float t) {
  return {255.0 * (1.0 - t), 255.0 * (1.0 - std::abs(2.0 * t - 1.0)), 255.0 * t};
}

void Text(cv::Mat& canvas, const std::string& text, cv::Point at, double scale = 0.45) {
  cv::putText(canvas, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar::all(235), 1,
              cv::LINE_AA);
}

using common::Fixed;

}  // namespace

cv::Mat DrawMatchOverlay(const cv::Mat& left, const cv::Mat& right, const MatchReport& report,
                         int line_every) {
  const cv::Mat l = ToColour8(left), r = ToColour8(right);
  // The images side by side, and below them a legend: what the colours mean, how many matches,
  // the engine and the time - the picture is read without the source.
  constexpr int kLegendHeight = 56;
  const int image_rows = std::max(l.rows, r.rows);
  cv::Mat canvas(image_rows + kLegendHeight, l.cols + r.cols, CV_8UC3, cv::Scalar::all(0));
  // Dim the images so that the marks stand out.
  cv::Mat(l * 0.6).copyTo(canvas(cv::Rect(0, 0, l.cols, l.rows)));
  cv::Mat(r * 0.6).copyTo(canvas(cv::Rect(l.cols, 0, r.cols, r.rows)));
  const cv::Point2f offset(static_cast<float>(l.cols), 0.0f);
  for (const auto& p : report.left_features) {
    cv::circle(canvas, cv::Point2f(p.x(), p.y()), 1, cv::Scalar(120, 120, 120), cv::FILLED);
  }
  for (const auto& p : report.right_features) {
    cv::circle(canvas, cv::Point2f(p.x(), p.y()) + offset, 1, cv::Scalar(120, 120, 120), cv::FILLED);
  }
  float max_disparity = 1.0f;
  for (const auto& m : report.matches) max_disparity = std::max(max_disparity, (m.left - m.right).norm());
  int index = 0;
  for (const auto& m : report.matches) {
    const float t = std::clamp((m.left - m.right).norm() / max_disparity, 0.0f, 1.0f);
    const cv::Scalar colour = DisparityColour(t);
    const cv::Point2f pl(m.left.x(), m.left.y());
    const cv::Point2f pr = cv::Point2f(m.right.x(), m.right.y()) + offset;
    cv::circle(canvas, pl, 2, colour, cv::FILLED);
    cv::circle(canvas, pr, 2, colour, cv::FILLED);
    if (line_every > 0 && index++ % line_every == 0) cv::line(canvas, pl, pr, colour, 1, cv::LINE_AA);
  }

  // Legend: a colour bar of the match displacement with round ticks, then the figures.
  const int top = image_rows;
  const int bar_x = 10, bar_width = std::max(100, std::min(300, canvas.cols / 3)), bar_y = top + 8;
  for (int x = 0; x < bar_width; ++x) {
    cv::line(canvas, {bar_x + x, bar_y}, {bar_x + x, bar_y + 12},
             DisparityColour(static_cast<float>(x) / static_cast<float>(bar_width - 1)));
  }
  const double tick_step = max_disparity > 100 ? 50 : max_disparity > 40 ? 20 : max_disparity > 20 ? 10 : 5;
  for (double value = 0; value <= max_disparity + 1e-6; value += tick_step) {
    const int x = bar_x + static_cast<int>(value / max_disparity * (bar_width - 1));
    cv::line(canvas, {x, bar_y + 12}, {x, bar_y + 16}, cv::Scalar::all(235));
    Text(canvas, Fixed(value, 0), {x - 6, bar_y + 30}, 0.38);
  }
  Text(canvas, "colour = match displacement |left - right| (px); grey dots = unmatched features",
       {bar_x, top + kLegendHeight - 6}, 0.4);
  const int text_x = bar_x + bar_width + 20;
  Text(canvas,
       std::to_string(report.matches.size()) + " matches of " + std::to_string(report.n_left) +
           " left / " + std::to_string(report.n_right) + " right features",
       {text_x, top + 18});
  Text(canvas,
       "engine " + report.solve.engine + ", " + Fixed(report.timing_ms.total, 0) + " ms, on " +
           report.solve.device,
       {text_x, top + 38}, 0.4);
  return canvas;
}

}  // namespace hnnstereo::vision
