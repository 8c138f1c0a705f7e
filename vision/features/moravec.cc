// Moravec interest operator, written by hand (OpenCV has no Moravec operator).

#include "vision/features/moravec.h"

#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {

cv::Mat MoravecResponse(const cv::Mat& grey, int window, double threshold) {
  if (grey.empty() || grey.type() != CV_8UC1) {
    throw std::invalid_argument("Moravec needs a non-empty CV_8UC1 image");
  }
  if (window < 3 || window % 2 == 0) {
    throw std::invalid_argument("Moravec window must be odd and >= 3 (got " +
                                std::to_string(window) + ")");
  }
  const int radius = window / 2;
  // A window and its one-step shift must both lie inside the image.
  const int margin = radius + 1;
  cv::Mat response = cv::Mat::zeros(grey.size(), CV_32F);
  if (grey.rows <= 2 * margin || grey.cols <= 2 * margin) return response;

  cv::Mat image;
  grey.convertTo(image, CV_32F);

  // V_theta for theta = pi, pi/4, pi/2, 3pi/4 as one-step shifts d = (dx, dy), eq. 6.3. The
  // squared difference image of each shift is summed over the window with an unnormalised box
  // filter (S_d), so the cost does not depend on the window size. Each direction is taken in
  // both senses: the shift by -d gives S_d(p - d), and min(S_d(p), S_d(p - d)) makes the
  // response symmetric, so that all four corners of a rectangle are found at the same offset.
  // (With one sense only, corners facing -d are found half a window further inside.)
  constexpr std::array<std::array<int, 2>, 4> kShifts = {{{1, 0}, {1, 1}, {0, 1}, {1, -1}}};
  cv::Mat minimum(grey.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::max()));
  cv::Mat squared_difference(grey.size(), CV_32F);
  cv::Mat directional_ssd;
  for (const auto& [dx, dy] : kShifts) {
    // (I(q) - I(q + d))^2 wherever q + d is inside the image, 0 elsewhere.
    squared_difference.setTo(0.0f);
    for (int y = std::max(0, -dy); y < grey.rows - std::max(0, dy); ++y) {
      const float* row = image.ptr<float>(y);
      const float* shifted_row = image.ptr<float>(y + dy);
      float* out = squared_difference.ptr<float>(y);
      for (int x = 0; x < grey.cols - dx; ++x) {
        const float difference = row[x] - shifted_row[x + dx];
        out[x] = difference * difference;
      }
    }
    cv::boxFilter(squared_difference, directional_ssd, CV_32F, cv::Size(window, window),
                  cv::Point(-1, -1), /*normalize=*/false, cv::BORDER_CONSTANT);
    for (int y = 1; y < grey.rows - 1; ++y) {
      const float* ssd = directional_ssd.ptr<float>(y);
      const float* ssd_back = directional_ssd.ptr<float>(y - dy);  // S_d at p - d
      float* out = minimum.ptr<float>(y);
      for (int x = 1; x < grey.cols - 1; ++x) {
        out[x] = std::min({out[x], ssd[x], ssd_back[x - dx]});
      }
    }
  }

  // Keep V where it exceeds the threshold and is the maximum of its window x window
  // neighbourhood (Moravec's local-maximum suppression).
  const auto threshold_f = static_cast<float>(threshold);
  for (int y = margin; y < grey.rows - margin; ++y) {
    const float* row = minimum.ptr<float>(y);
    for (int x = margin; x < grey.cols - margin; ++x) {
      const float strength = row[x];
      if (!(strength > threshold_f)) continue;
      bool is_maximum = true;
      for (int ny = std::max(margin, y - radius);
           ny <= std::min(grey.rows - margin - 1, y + radius) && is_maximum; ++ny) {
        const float* neighbour_row = minimum.ptr<float>(ny);
        for (int nx = std::max(margin, x - radius);
             nx <= std::min(grey.cols - margin - 1, x + radius); ++nx) {
          if (nx == x && ny == y) continue;
          const bool earlier = ny < y || (ny == y && nx < x);
          if (earlier ? neighbour_row[nx] >= strength : neighbour_row[nx] > strength) {
            is_maximum = false;
            break;
          }
        }
      }
      if (is_maximum) response.at<float>(y, x) = strength;
    }
  }
  return response;
}

}  // namespace hnnstereo::vision
