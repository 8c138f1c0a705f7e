// Setup checks: one image given twice (identical, noisy, blurred, re-saved copies) is refused,
// real pairs (Teddy, rendered cells) pass, a swapped rectified pair is seen, disparity ranges.
#include "vision/stereo/setup_checks.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "common/image.h"
#include "vision/sensing/swapped_cameras.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::vision {
namespace {

const std::string kTeddy = std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy/";

cv::Mat Teddy(const std::string& name) { return LoadImage(kTeddy + name).grey; }

cv::Mat WithNoise(const cv::Mat& grey, double sigma, int seed) {
  cv::Mat noise(grey.size(), CV_32F), out;
  cv::theRNG().state = static_cast<std::uint64_t>(seed);
  cv::randn(noise, 0.0, sigma);
  grey.convertTo(out, CV_32F);
  out += noise;
  out.convertTo(out, CV_8U);
  return out;
}

void Print(const char* name, const PairComparison& c) {
  std::printf("%-28s MAD %6.2f identical %.3f textured %4d zero %.3f positive %.3f negative %.3f "
              "(%.1f ms) -> %s%s\n",
              name, c.mean_abs_difference_grey, c.identical_pixel_fraction, c.textured_blocks,
              c.zero_shift_fraction, c.positive_shift_fraction, c.negative_shift_fraction, c.time_ms,
              c.near_identical ? "near-identical" : "two views", c.looks_swapped ? ", swapped" : "");
}

TEST(SetupChecks, TeddyPairIsTwoViews) {
  const PairComparison c = ComparePair(Teddy("im2.png"), Teddy("im6.png"));
  Print("teddy im2/im6", c);
  EXPECT_FALSE(c.near_identical);
  EXPECT_FALSE(c.looks_swapped);
  EXPECT_LT(c.zero_shift_fraction, 0.5);
  EXPECT_NO_THROW(CheckDistinctViews(Teddy("im2.png"), Teddy("im6.png")));
}

// A wall-time bound: in the extended suite only (tests/vision/CMakeLists.txt), as a loaded
// machine can fail it.
TEST(SetupChecksTiming, TeddyPairIsComparedWithin200Ms) {
  const cv::Mat left = Teddy("im2.png"), right = Teddy("im6.png");
  const PairComparison c = ComparePair(left, right);
  EXPECT_LT(c.time_ms, 200.0);
}

TEST(SetupChecks, TeddySwappedLooksSwapped) {
  const PairComparison c = ComparePair(Teddy("im6.png"), Teddy("im2.png"));
  Print("teddy im6/im2 (swapped)", c);
  EXPECT_FALSE(c.near_identical);
  EXPECT_TRUE(c.looks_swapped);
}

TEST(SetupChecks, IdenticalImagesAreRefused) {
  const cv::Mat left = Teddy("im2.png");
  const PairComparison c = ComparePair(left, left.clone());
  Print("teddy im2/im2", c);
  EXPECT_TRUE(c.near_identical);
  EXPECT_DOUBLE_EQ(c.mean_abs_difference_grey, 0.0);
  try {
    CheckDistinctViews(left, left, "--left/--right");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--left/--right are identical"), std::string::npos)
        << e.what();
  }
}

TEST(SetupChecks, NoisyBlurredAndRecompressedCopiesAreRefused) {
  const cv::Mat left = Teddy("im2.png");
  for (double sigma : {1.0, 3.0, 8.0}) {
    const PairComparison c = ComparePair(left, WithNoise(left, sigma, 7));
    Print(("teddy im2 + noise " + std::to_string(sigma).substr(0, 3)).c_str(), c);
    EXPECT_TRUE(c.near_identical) << sigma;
    EXPECT_THROW(CheckDistinctViews(left, WithNoise(left, sigma, 7)), std::invalid_argument);
  }
  cv::Mat blurred;
  cv::GaussianBlur(left, blurred, cv::Size(0, 0), 1.0);
  const PairComparison b = ComparePair(left, blurred);
  Print("teddy im2 + blur 1 px", b);
  EXPECT_TRUE(b.near_identical);
  std::vector<unsigned char> jpeg;
  cv::imencode(".jpg", left, jpeg, {cv::IMWRITE_JPEG_QUALITY, 50});
  const PairComparison j = ComparePair(left, cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE));
  Print("teddy im2 as JPEG q50", j);
  EXPECT_TRUE(j.near_identical);
}

TEST(SetupChecks, RenderedCellPairsAreTwoViewsAndTheirCopiesAreNot) {
  // (Seeds 1-5 measured in setup_checks.h; two here: rendering is the slow part.)
  for (std::uint64_t seed : {3u, 5u}) {
    SceneRenderOptions options;
    options.seed = seed;
    const RenderedScene scene = RenderScene(options);
    const PairComparison c = ComparePair(scene.left, scene.right);
    Print(("render seed " + std::to_string(seed)).c_str(), c);
    EXPECT_FALSE(c.near_identical) << seed;
    const PairComparison copy = ComparePair(scene.left, WithNoise(scene.left, 2.0, 3));
    Print(("render seed " + std::to_string(seed) + " left + noise 2").c_str(), copy);
    EXPECT_TRUE(copy.near_identical) << seed;
  }
}

// A calibrated cell pair correlates along its epipolar segments as given, not swapped.
TEST(SetupChecks, SwappedCellPairCorrelatesTheOtherWayRound) {
  SceneRenderOptions options;
  options.seed = 7;
  const RenderedScene scene = RenderScene(options);
  const SwapComparison given = CompareWithSwappedCameras(scene.left, scene.right, scene.cameras, {-5, 200});
  std::printf("cell seed 7 as given: %d points, ZNCC %.2f as given, %.2f swapped\n", given.points,
              given.as_given_zncc, given.swapped_zncc);
  EXPECT_FALSE(given.looks_swapped);
  const SwapComparison swapped = CompareWithSwappedCameras(scene.right, scene.left, scene.cameras, {-5, 200});
  std::printf("cell seed 7 swapped: %d points, ZNCC %.2f as given, %.2f swapped\n", swapped.points,
              swapped.as_given_zncc, swapped.swapped_zncc);
  EXPECT_TRUE(swapped.looks_swapped);
}

TEST(SetupChecks, FlatImagesAbstainUnlessIdentical) {
  const cv::Mat flat(100, 120, CV_8U, cv::Scalar(90));
  EXPECT_TRUE(ComparePair(flat, flat).near_identical);  // the same pixels
  const cv::Mat other(100, 120, CV_8U, cv::Scalar(95));
  const PairComparison c = ComparePair(flat, other);
  EXPECT_EQ(c.textured_blocks, 0);
  EXPECT_FALSE(c.near_identical);  // no texture, no verdict
}

TEST(SetupChecks, BadInputThrows) {
  const cv::Mat a(50, 60, CV_8U, cv::Scalar(1)), b(50, 61, CV_8U, cv::Scalar(1));
  EXPECT_THROW(ComparePair(a, b), std::invalid_argument);
  EXPECT_THROW(ComparePair(cv::Mat(), a), std::invalid_argument);
  DistinctPairOptions bad;
  bad.block_px = 2;
  EXPECT_NE(bad.Check().find("block_px"), std::string::npos);
  EXPECT_THROW(ComparePair(a, a, bad), std::invalid_argument);
}

TEST(SetupChecks, DisparityRangeBeyondTheWidthIsNamed) {
  EXPECT_EQ(DisparityRangeProblem(0, 64, 450), "");
  EXPECT_EQ(DisparityRangeProblem(-449, 449, 450), "");
  EXPECT_NE(DisparityRangeProblem(0, 1e9, 450).find("--max-disparity"), std::string::npos);
  EXPECT_NE(DisparityRangeProblem(0, 450, 450).find("image width (450 px"), std::string::npos);
  EXPECT_NE(DisparityRangeProblem(-1e6, 0, 450).find("--min-disparity"), std::string::npos);
  EXPECT_NE(DisparityRangeProblem(10, 5, 450).find("must be above --min-disparity"),
            std::string::npos);
  // A range of one disparity is no search (issue 41: --max-disparity 0 gave nonsense matches).
  EXPECT_NE(DisparityRangeProblem(0, 0, 450).find("--max-disparity 0.0 must be above"),
            std::string::npos);
  EXPECT_NE(DisparityRangeProblem(0, std::numeric_limits<double>::infinity(), 450).find("finite"),
            std::string::npos);
}

}  // namespace
}  // namespace hnnstereo::vision
