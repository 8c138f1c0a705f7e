#include "vision/features/features.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

constexpr unsigned kSeed = 4242;

// A bright rectangle on a dark background. Its pixels are x in [30, 90), y in [25, 75), so its
// outline (between pixel centres) is the box [29.5, 89.5] x [24.5, 74.5].
constexpr int kRows = 100, kCols = 120;
constexpr float kLeft = 29.5f, kRight = 89.5f, kTop = 24.5f, kBottom = 74.5f;

cv::Mat RectangleImage() {
  cv::Mat image(kRows, kCols, CV_8UC1, cv::Scalar(40));
  image(cv::Rect(30, 25, 60, 50)).setTo(cv::Scalar(200));
  return image;
}

float DistanceToOutline(const Eigen::Vector2f& point) {
  const float x = std::clamp(point.x(), kLeft, kRight);
  const float y = std::clamp(point.y(), kTop, kBottom);
  const bool inside =
      point.x() > kLeft && point.x() < kRight && point.y() > kTop && point.y() < kBottom;
  if (!inside) return std::hypot(point.x() - x, point.y() - y);
  return std::min({point.x() - kLeft, kRight - point.x(), point.y() - kTop, kBottom - point.y()});
}

const std::array<Eigen::Vector2f, 4> kCorners = {
    Eigen::Vector2f(kLeft, kTop), Eigen::Vector2f(kRight, kTop), Eigen::Vector2f(kLeft, kBottom),
    Eigen::Vector2f(kRight, kBottom)};

/// Report invariants: sorted row-major, strengths positive and aligned, inside the border.
void ExpectWellFormed(const FeatureReport& report, const cv::Size& size, int border_px) {
  ASSERT_EQ(report.points.size(), report.strength.size());
  EXPECT_GE(report.n_detected, static_cast<int>(report.points.size()));
  EXPECT_GE(report.time_ms, 0.0);
  for (std::size_t i = 0; i < report.points.size(); ++i) {
    const Eigen::Vector2f& point = report.points[i];
    EXPECT_GT(report.strength[i], 0.0f);
    EXPECT_GE(point.x(), static_cast<float>(border_px));
    EXPECT_GE(point.y(), static_cast<float>(border_px));
    EXPECT_LE(point.x(), static_cast<float>(size.width - 1 - border_px));
    EXPECT_LE(point.y(), static_cast<float>(size.height - 1 - border_px));
    if (i > 0) {
      const Eigen::Vector2f& previous = report.points[i - 1];
      EXPECT_TRUE(previous.y() < point.y() ||
                  (previous.y() == point.y() && previous.x() < point.x()))
          << "not row-major at " << i;
    }
  }
}

FeatureReport Detect(FeatureDetector detector, const cv::Mat& image) {
  FeatureOptions options;
  options.detector = detector;
  return DetectFeatures(image, options);
}

void ExpectEdgesOnOutline(FeatureDetector detector, float tolerance_px) {
  const cv::Mat image = RectangleImage();
  const FeatureReport report = Detect(detector, image);
  SCOPED_TRACE(std::string(FeatureDetectorName(detector)));
  ExpectWellFormed(report, image.size(), FeatureOptions().border_px);
  // The outline is 2 * (60 + 50) = 220 pixels long; expect most of it covered.
  EXPECT_GE(report.points.size(), 200u);
  for (const Eigen::Vector2f& point : report.points) {
    EXPECT_LE(DistanceToOutline(point), tolerance_px) << point.transpose();
  }
  // Every side is found: points near the middle of each side.
  for (const Eigen::Vector2f& middle :
       {Eigen::Vector2f(kLeft, 50.0f), Eigen::Vector2f(kRight, 50.0f), Eigen::Vector2f(60.0f, kTop),
        Eigen::Vector2f(60.0f, kBottom)}) {
    const bool found =
        std::any_of(report.points.begin(), report.points.end(),
                    [&](const Eigen::Vector2f& p) { return (p - middle).norm() <= 1.5f; });
    EXPECT_TRUE(found) << "nothing near " << middle.transpose();
  }
}

void ExpectCornersAtRectangleCorners(FeatureDetector detector, float tolerance_px,
                                     FeatureOptions options = {}) {
  const cv::Mat image = RectangleImage();
  options.detector = detector;
  const FeatureReport report = DetectFeatures(image, options);
  SCOPED_TRACE(std::string(FeatureDetectorName(detector)));
  ExpectWellFormed(report, image.size(), FeatureOptions().border_px);
  EXPECT_EQ(report.points.size(), 4u);
  for (const Eigen::Vector2f& corner : kCorners) {
    const bool found =
        std::any_of(report.points.begin(), report.points.end(),
                    [&](const Eigen::Vector2f& p) { return (p - corner).norm() <= tolerance_px; });
    EXPECT_TRUE(found) << "no feature near corner " << corner.transpose();
  }
  for (const Eigen::Vector2f& point : report.points) {
    float nearest = std::numeric_limits<float>::max();
    for (const Eigen::Vector2f& corner : kCorners)
      nearest = std::min(nearest, (point - corner).norm());
    EXPECT_LE(nearest, tolerance_px) << "stray feature at " << point.transpose();
  }
}

TEST(DetectFeatures, CannyEdgesLieOnTheRectangleOutline) {
  ExpectEdgesOnOutline(FeatureDetector::kCanny, 1.5f);
}

TEST(DetectFeatures, SusanEdgesLieOnTheRectangleOutline) {
  ExpectEdgesOnOutline(FeatureDetector::kSusanEdge, 1.5f);
}

TEST(DetectFeatures, SobelEdgesLieOnTheRectangleOutline) {
  ExpectEdgesOnOutline(FeatureDetector::kSobel, 1.5f);
}

TEST(DetectFeatures, SusanCornersAtTheRectangleCorners) {
  ExpectCornersAtRectangleCorners(FeatureDetector::kSusanCorner, 2.0f);
}

// Moravec's minimum of directional SSDs peaks where the window still sees both edges of the
// corner but lies as far inside as possible: (radius - 1/2) * sqrt(2) from the corner on the
// diagonal, 2.12 px for the default 5 x 5 window and 0.71 px for 3 x 3.
TEST(DetectFeatures, MoravecCornersAtTheRectangleCorners) {
  ExpectCornersAtRectangleCorners(FeatureDetector::kMoravec, 2.2f);
  FeatureOptions options;
  options.moravec_window = 3;
  ExpectCornersAtRectangleCorners(FeatureDetector::kMoravec, 0.75f, options);
}

TEST(DetectFeatures, NothingOnAFlatImage) {
  const cv::Mat flat(60, 60, CV_8UC1, cv::Scalar(128));
  for (const FeatureDetector detector :
       {FeatureDetector::kCanny, FeatureDetector::kSusanEdge, FeatureDetector::kSusanCorner,
        FeatureDetector::kMoravec, FeatureDetector::kSobel}) {
    const FeatureReport report = Detect(detector, flat);
    EXPECT_TRUE(report.points.empty()) << FeatureDetectorName(detector);
    EXPECT_EQ(report.n_detected, 0);
  }
}

TEST(DetectFeatures, BorderDropsFeaturesNearTheEdge) {
  const cv::Mat image = RectangleImage();
  FeatureOptions options;
  // Keeps x in [27, 92], y in [27, 72]: the left and right sides stay, top and bottom go.
  options.border_px = 27;
  const FeatureReport report = DetectFeatures(image, options);
  ExpectWellFormed(report, image.size(), options.border_px);
  EXPECT_GE(report.points.size(), 2u * 40u);
  options.border_px = 60;  // nothing left of a 120 x 100 image
  EXPECT_TRUE(DetectFeatures(image, options).points.empty());
}

/// Texture everywhere, but four times stronger in the top-left quadrant: keeping the strongest
/// features would empty the other three quadrants.
cv::Mat UnevenTexture() {
  std::mt19937 random(kSeed);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  cv::Mat texture(200, 240, CV_32F);
  for (int y = 0; y < texture.rows; ++y) {
    for (int x = 0; x < texture.cols; ++x) texture.at<float>(y, x) = noise(random);
  }
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 1.5);
  cv::Mat image(texture.size(), CV_8UC1);
  for (int y = 0; y < texture.rows; ++y) {
    for (int x = 0; x < texture.cols; ++x) {
      const float gain = (x < 120 && y < 100) ? 240.0f : 60.0f;
      image.at<unsigned char>(y, x) =
          cv::saturate_cast<uchar>(128.0f + gain * texture.at<float>(y, x));
    }
  }
  return image;
}

TEST(DetectFeatures, CapKeepsCountAndSpread) {
  const cv::Mat image = UnevenTexture();
  for (const FeatureDetector detector :
       {FeatureDetector::kCanny, FeatureDetector::kSobel, FeatureDetector::kSusanEdge}) {
    SCOPED_TRACE(std::string(FeatureDetectorName(detector)));
    FeatureOptions options;
    options.detector = detector;
    options.canny_low = 20.0;
    options.canny_high = 60.0;
    options.sobel_threshold = 40.0;
    options.max_features = 300;
    const FeatureReport report = DetectFeatures(image, options);
    ExpectWellFormed(report, image.size(), options.border_px);
    ASSERT_GT(report.n_detected, 3 * options.max_features) << "test image not textured enough";
    EXPECT_EQ(static_cast<int>(report.points.size()), options.max_features);
    std::array<int, 4> per_quadrant{};
    for (const Eigen::Vector2f& point : report.points) {
      ++per_quadrant[(point.x() >= 120.0f ? 1 : 0) + (point.y() >= 100.0f ? 2 : 0)];
    }
    for (int quadrant = 0; quadrant < 4; ++quadrant) {
      EXPECT_GE(per_quadrant[quadrant], options.max_features / 8)
          << "quadrant " << quadrant << " starved: " << per_quadrant[quadrant];
    }
    // Deterministic.
    const FeatureReport again = DetectFeatures(image, options);
    ASSERT_EQ(again.points.size(), report.points.size());
    for (std::size_t i = 0; i < report.points.size(); ++i) {
      EXPECT_EQ(again.points[i], report.points[i]);
    }
  }
}

TEST(DetectFeatures, CapKeepsEverythingWhenBelowIt) {
  const cv::Mat image = RectangleImage();
  FeatureOptions options;
  const FeatureReport uncapped = DetectFeatures(image, options);
  options.max_features = static_cast<int>(uncapped.points.size());
  const FeatureReport capped = DetectFeatures(image, options);
  EXPECT_EQ(capped.points, uncapped.points);
  options.max_features = 10;
  const FeatureReport few = DetectFeatures(image, options);
  EXPECT_EQ(few.points.size(), 10u);
  EXPECT_EQ(few.n_detected, uncapped.n_detected);
}

TEST(FeatureOptions, DefaultsAreValid) { EXPECT_EQ(FeatureOptions().Check(), ""); }

TEST(FeatureOptions, CheckNamesTheBadField) {
  const auto expect_reason = [](auto change, const std::string& field) {
    FeatureOptions options;
    change(options);
    const std::string reason = options.Check();
    EXPECT_NE(reason.find(field), std::string::npos) << "reason: '" << reason << "'";
  };
  expect_reason([](FeatureOptions& o) { o.canny_low = -1.0; }, "canny_low");
  expect_reason([](FeatureOptions& o) { o.canny_low = 200.0; }, "canny_low");
  expect_reason([](FeatureOptions& o) { o.canny_low = std::nan(""); }, "canny_low");
  expect_reason([](FeatureOptions& o) { o.canny_high = std::numeric_limits<double>::infinity(); },
                "canny_high");
  expect_reason([](FeatureOptions& o) { o.canny_aperture = 4; }, "canny_aperture");
  expect_reason([](FeatureOptions& o) { o.susan_brightness_threshold = 0; },
                "susan_brightness_threshold");
  expect_reason([](FeatureOptions& o) { o.susan_brightness_threshold = 300; },
                "susan_brightness_threshold");
  expect_reason([](FeatureOptions& o) { o.moravec_window = 4; }, "moravec_window");
  expect_reason([](FeatureOptions& o) { o.moravec_window = 1; }, "moravec_window");
  expect_reason([](FeatureOptions& o) { o.moravec_threshold = -5.0; }, "moravec_threshold");
  expect_reason([](FeatureOptions& o) { o.sobel_threshold = -1.0; }, "sobel_threshold");
  expect_reason([](FeatureOptions& o) { o.border_px = -1; }, "border_px");
  expect_reason([](FeatureOptions& o) { o.max_features = -3; }, "max_features");
}

TEST(DetectFeatures, ThrowsOnBadInput) {
  const FeatureOptions options;
  EXPECT_THROW(DetectFeatures(cv::Mat(), options), std::invalid_argument);
  EXPECT_THROW(DetectFeatures(cv::Mat(20, 20, CV_8UC3, cv::Scalar(0, 0, 0)), options),
               std::invalid_argument);
  EXPECT_THROW(DetectFeatures(cv::Mat(20, 20, CV_16UC1, cv::Scalar(0)), options),
               std::invalid_argument);
  FeatureOptions bad;
  bad.canny_aperture = 9;
  try {
    DetectFeatures(RectangleImage(), bad);
    ADD_FAILURE() << "invalid options accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("canny_aperture"), std::string::npos) << error.what();
  }
}

TEST(FeatureDetectorName, RoundTripsThroughParse) {
  for (const FeatureDetector detector :
       {FeatureDetector::kCanny, FeatureDetector::kSusanEdge, FeatureDetector::kSusanCorner,
        FeatureDetector::kMoravec, FeatureDetector::kSobel}) {
    EXPECT_EQ(ParseFeatureDetector(FeatureDetectorName(detector)), detector);
  }
  EXPECT_EQ(FeatureDetectorName(FeatureDetector::kSusanCorner), "susan-corner");
  EXPECT_FALSE(ParseFeatureDetector("harris").has_value());
  EXPECT_FALSE(ParseFeatureDetector("").has_value());
}

// Real data: counts on Middlebury Teddy; timing is printed only (speed targets live in
// `hnnstereo bench`, not in unit tests).
TEST(DetectFeatures, TeddyCountsAndTiming) {
  const std::string path =
      std::string(HNNSTEREO_SHARED_DIR) + "/datasets/middlebury2003_teddy/im2.png";
  const cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (grey.empty()) GTEST_SKIP() << "shared data not found: " << path;
  for (const FeatureDetector detector :
       {FeatureDetector::kCanny, FeatureDetector::kSusanEdge, FeatureDetector::kSusanCorner,
        FeatureDetector::kMoravec, FeatureDetector::kSobel}) {
    FeatureOptions options;
    options.detector = detector;
    options.max_features = 5000;
    DetectFeatures(grey, options);  // warm-up (OpenCV thread pool, caches)
    double best_ms = std::numeric_limits<double>::max();
    FeatureReport report;
    for (int repeat = 0; repeat < 5; ++repeat) {
      report = DetectFeatures(grey, options);
      best_ms = std::min(best_ms, report.time_ms);
    }
    ExpectWellFormed(report, grey.size(), options.border_px);
    EXPECT_LE(report.points.size(), 5000u);
    EXPECT_GT(report.points.size(), 0u);
    std::cout << FeatureDetectorName(detector) << " on Teddy im2 (cap 5000): detected "
              << report.n_detected << ", kept " << report.points.size() << ", best of 5 " << best_ms
              << " ms\n";
  }
}

}  // namespace
}  // namespace hnnstereo::vision
