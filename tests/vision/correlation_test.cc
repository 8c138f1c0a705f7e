#include "vision/stereo/correlation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

constexpr unsigned kSeed = 20240611;

cv::Mat RandomImage(int rows, int cols, std::mt19937* random, int low = 0, int high = 255) {
  std::uniform_int_distribution<int> grey_level(low, high);
  cv::Mat image(rows, cols, CV_8UC1);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x)
      image.at<unsigned char>(y, x) = static_cast<uchar>(grey_level(*random));
  }
  return image;
}

/// Straightforward ZNCC in double: means, then the zero-mean products and norms.
double ReferenceZncc(const cv::Mat& left, const cv::Mat& right, const Eigen::Vector2f& left_point,
                     const Eigen::Vector2f& right_point, int window) {
  const int radius = window / 2;
  const int lx = static_cast<int>(std::floor(left_point.x() + 0.5f));
  const int ly = static_cast<int>(std::floor(left_point.y() + 0.5f));
  const int rx = static_cast<int>(std::floor(right_point.x() + 0.5f));
  const int ry = static_cast<int>(std::floor(right_point.y() + 0.5f));
  if (lx < radius || ly < radius || lx >= left.cols - radius || ly >= left.rows - radius ||
      rx < radius || ry < radius || rx >= right.cols - radius || ry >= right.rows - radius) {
    return 0.0;
  }
  double left_mean = 0.0, right_mean = 0.0;
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      left_mean += left.at<unsigned char>(ly + dy, lx + dx);
      right_mean += right.at<unsigned char>(ry + dy, rx + dx);
    }
  }
  left_mean /= window * window;
  right_mean /= window * window;
  double product = 0.0, left_square = 0.0, right_square = 0.0;
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      const double l = left.at<unsigned char>(ly + dy, lx + dx) - left_mean;
      const double r = right.at<unsigned char>(ry + dy, rx + dx) - right_mean;
      product += l * r;
      left_square += l * l;
      right_square += r * r;
    }
  }
  if (left_square == 0.0 || right_square == 0.0) return 0.0;
  return product / std::sqrt(left_square * right_square);
}

TEST(ZnccMatcher, OneForIdenticalWindows) {
  std::mt19937 random(kSeed);
  const cv::Mat image = RandomImage(40, 50, &random);
  for (const int window : {3, 5, 7, 15}) {
    const ZnccMatcher zncc(image, image, window);
    EXPECT_EQ(zncc.window(), window);
    EXPECT_NEAR(zncc({20.0f, 20.0f}, {20.0f, 20.0f}), 1.0f, 1e-6f) << "window " << window;
  }
  // The same content at different positions of two different images.
  cv::Mat shifted = cv::Mat::zeros(40, 50, CV_8UC1);
  image(cv::Rect(0, 0, 43, 40)).copyTo(shifted(cv::Rect(7, 0, 43, 40)));
  const ZnccMatcher zncc(image, shifted, 5);
  EXPECT_NEAR(zncc({12.0f, 15.0f}, {19.0f, 15.0f}), 1.0f, 1e-6f);
}

TEST(ZnccMatcher, MinusOneForInvertedWindows) {
  std::mt19937 random(kSeed);
  const cv::Mat image = RandomImage(30, 30, &random);
  const cv::Mat inverted = 255 - image;
  const ZnccMatcher zncc(image, inverted, 7);
  EXPECT_NEAR(zncc({15.0f, 15.0f}, {15.0f, 15.0f}), -1.0f, 1e-6f);
}

TEST(ZnccMatcher, InvariantToGainAndOffset) {
  std::mt19937 random(kSeed);
  const cv::Mat image = RandomImage(30, 30, &random, 0, 100);
  cv::Mat brighter;
  image.convertTo(brighter, CV_8U, 2.0, 17.0);  // exact: 2 * 100 + 17 <= 255
  const ZnccMatcher zncc(image, brighter, 5);
  EXPECT_NEAR(zncc({10.0f, 12.0f}, {10.0f, 12.0f}), 1.0f, 1e-6f);
  const ZnccMatcher same(image, image, 5);
  EXPECT_NEAR(zncc({10.0f, 12.0f}, {20.0f, 8.0f}), same({10.0f, 12.0f}, {20.0f, 8.0f}), 1e-6f);
}

TEST(ZnccMatcher, ZeroForFlatWindow) {
  std::mt19937 random(kSeed);
  cv::Mat textured = RandomImage(30, 30, &random);
  cv::Mat flat(30, 30, CV_8UC1, cv::Scalar(200));
  const ZnccMatcher zncc(textured, flat, 5);
  EXPECT_EQ(zncc({15.0f, 15.0f}, {15.0f, 15.0f}), 0.0f);
  const ZnccMatcher both_flat(flat, flat, 5);
  EXPECT_EQ(both_flat({15.0f, 15.0f}, {15.0f, 15.0f}), 0.0f);
}

TEST(ZnccMatcher, ZeroWhenWindowLeavesImage) {
  std::mt19937 random(kSeed);
  const cv::Mat image = RandomImage(30, 40, &random);
  const ZnccMatcher zncc(image, image, 5);
  const Eigen::Vector2f inside(20.0f, 15.0f);
  EXPECT_NEAR(zncc({2.0f, 2.0f}, {2.0f, 2.0f}), 1.0f, 1e-6f);      // first full window
  EXPECT_NEAR(zncc({37.0f, 27.0f}, {37.0f, 27.0f}), 1.0f, 1e-6f);  // last full window
  EXPECT_EQ(zncc({1.0f, 15.0f}, inside), 0.0f);
  EXPECT_EQ(zncc({38.0f, 15.0f}, inside), 0.0f);
  EXPECT_EQ(zncc({20.0f, 1.4f}, inside), 0.0f);   // rounds to 1
  EXPECT_EQ(zncc({20.0f, 27.6f}, inside), 0.0f);  // rounds to 28
  EXPECT_EQ(zncc(inside, {-5.0f, 15.0f}), 0.0f);
  EXPECT_EQ(zncc(inside, {1e9f, 15.0f}), 0.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(zncc(inside, {nan, 15.0f}), 0.0f);
  EXPECT_EQ(zncc({20.0f, nan}, inside), 0.0f);
}

TEST(ZnccMatcher, MatchesDoubleReferenceOnRandomImages) {
  std::mt19937 random(kSeed);
  std::cout << "seed " << kSeed << "\n";
  // Different sizes on purpose, and some low-contrast content where cancellation would show.
  const cv::Mat left = RandomImage(60, 80, &random);
  cv::Mat right = RandomImage(50, 90, &random);
  right(cv::Rect(0, 0, 45, 50)) = right(cv::Rect(0, 0, 45, 50)) / 40 + 200;  // values 200..206
  std::uniform_real_distribution<float> left_x(-2.0f, 82.0f), left_y(-2.0f, 62.0f);
  std::uniform_real_distribution<float> right_x(-2.0f, 92.0f), right_y(-2.0f, 52.0f);
  for (const int window : {3, 5, 7, 9, 15}) {
    const ZnccMatcher zncc(left, right, window);
    for (int trial = 0; trial < 2000; ++trial) {
      const Eigen::Vector2f left_point(left_x(random), left_y(random));
      const Eigen::Vector2f right_point(right_x(random), right_y(random));
      const double expected = ReferenceZncc(left, right, left_point, right_point, window);
      const float actual = zncc(left_point, right_point);
      ASSERT_NEAR(actual, expected, 1e-4)
          << "window " << window << " left " << left_point.transpose() << " right "
          << right_point.transpose();
      ASSERT_LE(std::fabs(actual), 1.0f);
    }
  }
}

// The row profiles (all disparities at once) equal the pair-by-pair ZNCC bit for bit: every
// window size, points near every border, fractional and x.5 coordinates, flat patches (0),
// images of different sizes, ranges reaching outside the image, and NaN.
TEST(ZnccMatcher, RowProfilesEqualThePairByPairZnccBitForBit) {
  std::mt19937 random(kSeed + 7);
  for (const int window : {3, 5, 7, 9, 15}) {
    cv::Mat left = RandomImage(40, 90, &random), right = RandomImage(40, 83, &random);
    left(cv::Rect(30, 10, 20, 15)).setTo(77);   // flat patches: ZNCC 0
    right(cv::Rect(5, 20, 25, 12)).setTo(140);
    const ZnccMatcher zncc(left, right, window);
    std::uniform_real_distribution<float> x(-3.0f, 95.0f), y(-3.0f, 43.0f);
    std::vector<Eigen::Vector2f> points;
    for (int n = 0; n < 300; ++n) {
      Eigen::Vector2f p(x(random), y(random));
      if (n % 3 == 0) p = p.array().round();
      if (n % 7 == 0) p.x() = std::floor(p.x()) + 0.5f;
      if (n % 11 == 0) p.y() = std::floor(p.y()) + 0.5f;
      points.push_back(p);
    }
    points.emplace_back(std::numeric_limits<float>::quiet_NaN(), 10.0f);
    for (const auto& [d_min, d_max] : std::vector<std::pair<int, int>>{{0, 64}, {-20, 20}, {5, 5}, {-90, 120}}) {
      std::vector<float> profile(static_cast<std::size_t>(d_max - d_min + 1));
      for (const Eigen::Vector2f& p : points) {
        zncc.RowProfile(p, d_min, d_max, profile.data());
        for (int d = d_min; d <= d_max; ++d) {
          const float expected = zncc(p, Eigen::Vector2f(p.x() - static_cast<float>(d), p.y()));
          ASSERT_EQ(profile[static_cast<std::size_t>(d - d_min)], expected)
              << "window " << window << " point " << p.transpose() << " d " << d;
        }
        zncc.ReverseRowProfile(p, d_min, d_max, profile.data());
        for (int d = d_min; d <= d_max; ++d) {
          const Eigen::Vector2f left_point(std::round(p.x()) + static_cast<float>(d), std::round(p.y()));
          ASSERT_EQ(profile[static_cast<std::size_t>(d - d_min)], zncc(left_point, p))
              << "reverse: window " << window << " point " << p.transpose() << " d " << d;
        }
      }
    }
  }
}

/// The census similarity straight from its definition (docs/accuracy.md, "The data term"),
/// written apart from the library: codes with the image edge replicated (and a square reaching
/// past the edge sees the edge pixels' codes and grey levels), the weighted Hamming
/// sum over the square around each (rounded) point, weights round(255 exp(-|dI| / gamma)) of the
/// reference image (the left one unless `reference_right`), 0 for a point outside its image.
double ReferenceCensus(const cv::Mat& left, const cv::Mat& right, const Eigen::Vector2f& left_point,
                       const Eigen::Vector2f& right_point, const DataTermOptions& o,
                       bool reference_right = false) {
  const auto pixel = [](const cv::Mat& image, int x, int y) {
    return static_cast<int>(image.at<unsigned char>(std::clamp(y, 0, image.rows - 1),
                                                    std::clamp(x, 0, image.cols - 1)));
  };
  const int r = o.census_window / 2, h = o.aggregation_window / 2;
  const auto code = [&](const cv::Mat& image, int x, int y) {  // past the edge: the edge's code
    x = std::clamp(x, 0, image.cols - 1);
    y = std::clamp(y, 0, image.rows - 1);
    std::vector<int> bits;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        if (dx != 0 || dy != 0) bits.push_back(pixel(image, x + dx, y + dy) < pixel(image, x, y));
      }
    }
    return bits;
  };
  const auto inside = [](const cv::Mat& image, const Eigen::Vector2f& p) {
    return p.x() + 0.5f >= 0.0f && p.x() + 0.5f < image.cols && p.y() + 0.5f >= 0.0f &&
           p.y() + 0.5f < image.rows;
  };
  if (!inside(left, left_point) || !inside(right, right_point)) return 0.0;
  const int lx = static_cast<int>(left_point.x() + 0.5f),
            ly = static_cast<int>(left_point.y() + 0.5f);
  const int rx = static_cast<int>(right_point.x() + 0.5f),
            ry = static_cast<int>(right_point.y() + 0.5f);
  double cost = 0.0, weight_sum = 0.0;
  for (int qy = -h; qy <= h; ++qy) {
    for (int qx = -h; qx <= h; ++qx) {
      const int difference = reference_right
                                 ? std::abs(pixel(right, rx + qx, ry + qy) - pixel(right, rx, ry))
                                 : std::abs(pixel(left, lx + qx, ly + qy) - pixel(left, lx, ly));
      const double w =
          o.support_gamma > 0.0 ? std::round(255.0 * std::exp(-difference / o.support_gamma)) : 1.0;
      const std::vector<int> a = code(left, lx + qx, ly + qy), b = code(right, rx + qx, ry + qy);
      int hamming = 0;
      for (std::size_t k = 0; k < a.size(); ++k) hamming += a[k] != b[k];
      cost += w * hamming;
      weight_sum += w;
    }
  }
  return 1.0 - 2.0 * cost / (static_cast<double>((2 * r + 1) * (2 * r + 1) - 1) * weight_sum);
}

DataTermOptions Census(int census_window, int aggregation_window, double gamma) {
  DataTermOptions o;
  o.kind = DataTermOptions::Kind::kCensus;
  o.census_window = census_window;
  o.aggregation_window = aggregation_window;
  o.support_gamma = gamma;
  return o;
}

TEST(CensusDataTerm, MatchesTheDefinitionOnRandomImages) {
  std::mt19937 random(kSeed + 21);
  for (const DataTermOptions& o : {Census(5, 13, 30.0), Census(3, 5, 0.0), Census(5, 1, 10.0)}) {
    const cv::Mat left = RandomImage(30, 41, &random), right = RandomImage(30, 37, &random);
    const ZnccMatcher census(left, right, 7, o);
    std::uniform_real_distribution<float> x(-2.0f, 42.0f), y(-2.0f, 31.0f);
    for (int n = 0; n < 400; ++n) {
      const Eigen::Vector2f l(x(random), y(random)), r(x(random), y(random));
      ASSERT_NEAR(census(l, r), ReferenceCensus(left, right, l, r, o), 1e-6)
          << l.transpose() << " / " << r.transpose() << " window " << o.aggregation_window;
      ASSERT_NEAR(census.ReverseSimilarity(l, r), ReferenceCensus(left, right, l, r, o, true),
                  1e-6);
    }
  }
}

TEST(CensusDataTerm, OneForIdenticalImagesAndPeaksAtTheShift) {
  std::mt19937 random(kSeed + 22);
  const cv::Mat image = RandomImage(40, 80, &random);
  const ZnccMatcher same(image, image, 7, Census(5, 13, 30.0));
  EXPECT_FLOAT_EQ(same(Eigen::Vector2f(20.0f, 20.0f), Eigen::Vector2f(20.0f, 20.0f)), 1.0f);
  EXPECT_FLOAT_EQ(same(Eigen::Vector2f(0.0f, 39.0f), Eigen::Vector2f(0.0f, 39.0f)),
                  1.0f);  // corner
  // The right image is the left one shifted 9 px to the left: x_r = x_l - 9.
  const cv::Mat right = image(cv::Rect(9, 0, 71, 40)).clone();
  const ZnccMatcher census(image, right, 7, Census(5, 13, 30.0));
  std::vector<float> profile(31);
  for (const Eigen::Vector2f& p : {Eigen::Vector2f(40.0f, 20.0f), Eigen::Vector2f(30.0f, 8.0f)}) {
    census.RowProfile(p, 0, 30, profile.data());
    const auto best = std::max_element(profile.begin(), profile.end()) - profile.begin();
    EXPECT_EQ(best, 9) << p.transpose();
    EXPECT_FLOAT_EQ(profile[9], 1.0f);
  }
  EXPECT_EQ(census(Eigen::Vector2f(-1.0f, 5.0f), Eigen::Vector2f(3.0f, 5.0f)), 0.0f);  // outside
  EXPECT_EQ(census(Eigen::Vector2f(std::numeric_limits<float>::quiet_NaN(), 5.0f),
                   Eigen::Vector2f(3.0f, 5.0f)),
            0.0f);
}

TEST(CensusDataTerm, RowProfilesEqualThePairByPairSimilarityBitForBit) {
  std::mt19937 random(kSeed + 23);
  for (const DataTermOptions& o : {Census(5, 13, 30.0), Census(3, 7, 0.0)}) {
    cv::Mat left = RandomImage(40, 90, &random), right = RandomImage(40, 83, &random);
    left(cv::Rect(30, 10, 20, 15)).setTo(77);
    const ZnccMatcher census(left, right, 7, o);
    std::uniform_real_distribution<float> x(-3.0f, 95.0f), y(-3.0f, 43.0f);
    std::vector<Eigen::Vector2f> points;
    for (int n = 0; n < 200; ++n) {
      Eigen::Vector2f p(x(random), y(random));
      if (n % 3 == 0) p = p.array().round();
      if (n % 7 == 0) p.x() = std::floor(p.x()) + 0.5f;
      points.push_back(p);
    }
    points.emplace_back(std::numeric_limits<float>::quiet_NaN(), 10.0f);
    for (const auto& [d_min, d_max] :
         std::vector<std::pair<int, int>>{{0, 64}, {-20, 20}, {-90, 120}}) {
      std::vector<float> profile(static_cast<std::size_t>(d_max - d_min + 1));
      for (const Eigen::Vector2f& p : points) {
        census.RowProfile(p, d_min, d_max, profile.data());
        for (int d = d_min; d <= d_max; ++d) {
          ASSERT_EQ(profile[static_cast<std::size_t>(d - d_min)],
                    census(p, Eigen::Vector2f(p.x() - static_cast<float>(d), p.y())))
              << p.transpose() << " d " << d;
        }
        census.ReverseRowProfile(p, d_min, d_max, profile.data());
        for (int d = d_min; d <= d_max; ++d) {
          const Eigen::Vector2f left_point(std::round(p.x()) + static_cast<float>(d),
                                           std::round(p.y()));
          ASSERT_EQ(profile[static_cast<std::size_t>(d - d_min)],
                    census.ReverseSimilarity(left_point, p))
              << "reverse: " << p.transpose() << " d " << d;
        }
      }
    }
  }
}

TEST(CensusDataTerm, RejectsBadOptions) {
  const cv::Mat image(20, 20, CV_8UC1, cv::Scalar(10));
  for (const DataTermOptions& o :
       {Census(7, 13, 30.0), Census(5, 14, 30.0), Census(5, 33, 30.0), Census(5, 13, -1.0),
        Census(5, 13, std::numeric_limits<double>::quiet_NaN())}) {
    EXPECT_FALSE(o.Check().empty());
    EXPECT_THROW(ZnccMatcher(image, image, 7, o), std::invalid_argument);
  }
  EXPECT_TRUE(Census(3, 1, 0.0).Check().empty());
}

// The window statistics against brute-force integer sums of every window, bit for bit:
// random images (a grey-level range of 0..255 reaches the largest sums of squares), a flat
// patch (inverse norm 0), images a window wide and narrower, and every odd window 1..15.
TEST(ZnccWindowStatistics, EqualBruteForceSumsBitForBit) {
  std::mt19937 random(kSeed);
  for (const int window : {1, 3, 5, 7, 9, 15}) {
    for (const cv::Size size :
         {cv::Size(37, 23), cv::Size(window, window), cv::Size(window - 1, 40), cv::Size(64, 17)}) {
      if (size.width < 1) continue;
      cv::Mat image = RandomImage(size.height, size.width, &random);
      if (size.width > 20 && size.height > 12) image(cv::Rect(2, 1, 17, 11)).setTo(200);
      if (size.width == 64) {  // the largest sums: alternating 0 / 255 columns
        for (int x = 0; x < image.cols; x += 2) image.col(x).setTo(255);
        for (int x = 1; x < image.cols; x += 2) image.col(x).setTo(0);
      }
      const cv::Mat statistics = ZnccWindowStatistics(image, window);
      ASSERT_EQ(statistics.type(), CV_32FC2);
      ASSERT_EQ(statistics.size(), image.size());
      const int radius = window / 2;
      const double n = static_cast<double>(window) * window;
      for (int y = 0; y < image.rows; ++y) {
        for (int x = 0; x < image.cols; ++x) {
          float sum_expected = 0.0f, norm_expected = 0.0f;
          if (y >= radius && x >= radius && y < image.rows - radius && x < image.cols - radius) {
            long long sum = 0, square = 0;
            for (int dy = -radius; dy <= radius; ++dy) {
              for (int dx = -radius; dx <= radius; ++dx) {
                const long long v = image.at<unsigned char>(y + dy, x + dx);
                sum += v;
                square += v * v;
              }
            }
            const double scaled_variance = n * static_cast<double>(square) -
                                           static_cast<double>(sum) * static_cast<double>(sum);
            sum_expected = static_cast<float>(sum);
            norm_expected =
                scaled_variance > 0.5 ? static_cast<float>(std::sqrt(n / scaled_variance)) : 0.0f;
          }
          const cv::Vec2f got = statistics.at<cv::Vec2f>(y, x);
          ASSERT_EQ(got[0], sum_expected) << "window " << window << " at " << x << "," << y;
          ASSERT_EQ(got[1], norm_expected) << "window " << window << " at " << x << "," << y;
        }
      }
    }
  }
}

TEST(ZnccWindowStatistics, RejectsBadWindowAndImage) {
  const cv::Mat grey(8, 8, CV_8UC1, cv::Scalar(3));
  EXPECT_THROW(ZnccWindowStatistics(grey, 4), std::invalid_argument);
  EXPECT_THROW(ZnccWindowStatistics(grey, 17), std::invalid_argument);
  EXPECT_THROW(ZnccWindowStatistics(grey, -1), std::invalid_argument);
  EXPECT_THROW(ZnccWindowStatistics(cv::Mat(8, 8, CV_32FC1), 3), std::invalid_argument);
  EXPECT_THROW(ZnccWindowStatistics(cv::Mat(), 3), std::invalid_argument);
}

TEST(ZnccMatcher, RejectsBadWindow) {
  const cv::Mat image(20, 20, CV_8UC1, cv::Scalar(0));
  for (const int window : {-1, 0, 1, 2, 4, 6, 16, 17}) {
    EXPECT_THROW(ZnccMatcher(image, image, window), std::invalid_argument) << window;
  }
}

TEST(ZnccMatcher, RejectsWrongImageType) {
  const cv::Mat grey(20, 20, CV_8UC1, cv::Scalar(0));
  const cv::Mat colour(20, 20, CV_8UC3, cv::Scalar(0, 0, 0));
  const cv::Mat floating(20, 20, CV_32FC1, cv::Scalar(0));
  EXPECT_THROW(ZnccMatcher(colour, grey, 5), std::invalid_argument);
  EXPECT_THROW(ZnccMatcher(grey, floating, 5), std::invalid_argument);
  EXPECT_THROW(ZnccMatcher(cv::Mat(), grey, 5), std::invalid_argument);
}

// Reports the throughput (not asserted: the machine is shared). Teddy if present, else random.
TEST(ZnccMatcher, ThroughputReport) {
  const std::string directory =
      std::string(HNNSTEREO_SHARED_DIR) + "/datasets/middlebury2003_teddy";
  cv::Mat left = cv::imread(directory + "/im2.png", cv::IMREAD_GRAYSCALE);
  cv::Mat right = cv::imread(directory + "/im6.png", cv::IMREAD_GRAYSCALE);
  if (left.empty() || right.empty()) {
    std::mt19937 random(kSeed);
    left = RandomImage(375, 450, &random);
    right = RandomImage(375, 450, &random);
  }
  std::mt19937 random(kSeed);
  std::uniform_real_distribution<float> x(0.0f, static_cast<float>(left.cols - 1));
  std::uniform_real_distribution<float> y(0.0f, static_cast<float>(left.rows - 1));
  std::vector<Eigen::Vector2f> points(4096);
  for (auto& point : points) point = {x(random), y(random)};
  for (const int window : {5, 7}) {
    const auto build_start = std::chrono::steady_clock::now();
    const ZnccMatcher zncc(left, right, window);
    const double build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - build_start)
            .count();
    constexpr int kCalls = 2'000'000;
    double checksum = 0.0;
    const auto start = std::chrono::steady_clock::now();
    for (int call = 0; call < kCalls; ++call) {
      checksum += zncc(points[call & 4095], points[(call * 7 + 3) & 4095]);
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "ZNCC " << window << "x" << window << ": " << kCalls / seconds / 1e6
              << " M calls/s (" << 1e9 * seconds / kCalls << " ns/call), construction " << build_ms
              << " ms, checksum " << checksum << "\n";
    EXPECT_TRUE(std::isfinite(checksum));
  }
}

}  // namespace
}  // namespace hnnstereo::vision
