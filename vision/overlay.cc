#include "vision/overlay.h"

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "calib/atomic_file.h"

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


cv::Mat DrawMatchOverlay(const cv::Mat& left, const cv::Mat& right, const MatchReport& report,
                         int line_every) {
  const cv::Mat l = ToColour8(left), r = ToColour8(right);
  cv::Mat canvas(std::max(l.rows, r.rows), l.cols + r.cols, CV_8UC3, cv::Scalar::all(0));
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
    const cv::Scalar colour(255.0 * (1.0 - t), 255.0 * (1.0 - std::abs(2.0 * t - 1.0)), 255.0 * t);
    const cv::Point2f pl(m.left.x(), m.left.y());
    const cv::Point2f pr = cv::Point2f(m.right.x(), m.right.y()) + offset;
    cv::circle(canvas, pl, 2, colour, cv::FILLED);
    cv::circle(canvas, pr, 2, colour, cv::FILLED);
    if (line_every > 0 && index++ % line_every == 0) cv::line(canvas, pl, pr, colour, 1, cv::LINE_AA);
  }
  return canvas;
}

void WritePngAtomically(const std::string& path, const cv::Mat& image) {
  calib::WriteAtomically(path, [&](const std::string& temporary) {
    bool written = false;
    try {
      written = cv::imwrite(temporary, image);
    } catch (const cv::Exception& e) {
      throw std::runtime_error("cannot write image '" + path + "': " + e.err);
    }
    if (!written) throw std::runtime_error("cannot write image '" + path + "'");
  });
}

}  // namespace hnnstereo::vision
