#pragma once
// Edge and interest-point features (thesis 6.2): Canny (default), SUSAN edges, SUSAN corners,
// Moravec, Sobel, with a cap on the count that keeps features spread over the image.

#include <Eigen/Core>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hnnstereo::vision {

enum class FeatureDetector { kCanny, kSusanEdge, kSusanCorner, kMoravec, kSobel };

/// "canny", "susan-edge", "susan-corner", "moravec", "sobel".
std::string_view FeatureDetectorName(FeatureDetector detector);
std::optional<FeatureDetector> ParseFeatureDetector(std::string_view name);

struct FeatureOptions {
  FeatureDetector detector = FeatureDetector::kCanny;  ///< thesis: Canny is the best on a dusty table
  double canny_low = 50.0;          ///< Canny hysteresis low threshold (grey levels of gradient)
  double canny_high = 150.0;        ///< Canny hysteresis high threshold
  int canny_aperture = 3;           ///< Sobel aperture used by Canny (3, 5 or 7)
  int susan_brightness_threshold = 27;  ///< SUSAN t (grey levels), Smith & Brady 1997
  int moravec_window = 5;           ///< Moravec window side (pixels, odd)
  double moravec_threshold = 500.0; ///< Moravec minimum of directional SSDs
  double sobel_threshold = 100.0;   ///< Sobel gradient magnitude threshold
  int border_px = 4;                ///< features closer than this to the border are dropped
  int max_features = 0;             ///< cap on the count, 0 = no cap; spread kept by grid bucketing
  /// When set, moves the kept points of image `grey` (in place) to the pixels the matcher's
  /// geometry works in: the point route of lens distortion undistorts them (LensRoute::kPoints,
  /// vision/stereo/lens_distortion.h). Border and cap act on the image's own pixels first.
  std::function<void(const cv::Mat& grey, std::vector<Eigen::Vector2f>* points)> map_points;
  /// Empty when valid; otherwise a readable reason naming the field.
  std::string Check() const;
};

struct FeatureReport {
  std::vector<Eigen::Vector2f> points;  ///< pixel coordinates (x right, y down), 0-based
  std::vector<float> strength;          ///< detector response per kept point (for ranking)
  int n_detected = 0;                   ///< before the cap
  double time_ms = 0.0;
};

/// Detects features on a CV_8U grey image. Throws std::invalid_argument on bad options/image.
FeatureReport DetectFeatures(const cv::Mat& grey, const FeatureOptions& options);

}  // namespace hnnstereo::vision
