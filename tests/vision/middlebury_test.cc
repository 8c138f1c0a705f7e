// Middlebury loading: PFM, layouts, scale factors, occlusion masks, and the disparity convention
// checked photometrically on the real sets in ../shared/datasets (skipped when absent).
#include "vision/eval/middlebury.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include <opencv2/imgcodecs.hpp>

namespace hnnstereo::vision {
namespace {

namespace fs = std::filesystem;

const std::string kDatasets = std::string(HNNSTEREO_SHARED_DIR) + "/datasets";

class TempDir {
 public:
  explicit TempDir(const std::string& tag)
      : path_(fs::temp_directory_path() / ("hnnstereo_middlebury_" + tag + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
};

TEST(Pfm, RoundTripKeepsRowOrderAndInfinity) {
  TempDir dir("pfm");
  cv::Mat image(3, 4, CV_32F);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 4; ++x) image.at<float>(y, x) = static_cast<float>(10 * y + x) + 0.25f;
  image.at<float>(1, 2) = std::numeric_limits<float>::infinity();
  WritePfm(dir / "a.pfm", image);
  const cv::Mat read = ReadPfm(dir / "a.pfm");
  ASSERT_EQ(read.type(), CV_32F);
  ASSERT_EQ(read.size(), image.size());
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 4; ++x) EXPECT_EQ(read.at<float>(y, x), image.at<float>(y, x)) << x << "," << y;
}

TEST(Pfm, StoredBottomToTopAndBigEndian) {
  // A hand-written big-endian file: the first stored row is the image's LAST row.
  TempDir dir("pfm_be");
  std::string bytes = "Pf\n1 2\n1.0\n";
  auto append_big_endian = [&](float value) {
    unsigned char raw[4];
    std::memcpy(raw, &value, 4);
    for (int i = 3; i >= 0; --i) bytes.push_back(static_cast<char>(raw[i]));
  };
  append_big_endian(7.5f);   // bottom row
  append_big_endian(-2.0f);  // top row
  std::ofstream(dir / "b.pfm", std::ios::binary) << bytes;
  const cv::Mat read = ReadPfm(dir / "b.pfm");
  ASSERT_EQ(read.rows, 2);
  EXPECT_EQ(read.at<float>(0, 0), -2.0f);
  EXPECT_EQ(read.at<float>(1, 0), 7.5f);
}

TEST(Pfm, MalformedFilesThrow) {
  TempDir dir("pfm_bad");
  std::ofstream(dir / "magic.pfm") << "P5\n2 2\n-1\n";
  EXPECT_THROW(ReadPfm(dir / "magic.pfm"), std::runtime_error);
  std::ofstream(dir / "short.pfm") << "Pf\n2 2\n-1\nabc";
  EXPECT_THROW(ReadPfm(dir / "short.pfm"), std::runtime_error);
  EXPECT_THROW(ReadPfm(dir / "missing.pfm"), std::runtime_error);
}

TEST(LeftRightConsistentMask, MarksPixelsWhoseRightDisparityDisagrees) {
  cv::Mat left(1, 8, CV_32F, cv::Scalar(2.0f)), right(1, 8, CV_32F, cv::Scalar(2.0f));
  right.at<float>(0, 3) = 5.0f;  // left x = 5 maps to right x = 3: inconsistent
  const cv::Mat mask = LeftRightConsistentMask(left, right, 1.0);
  EXPECT_EQ(mask.at<std::uint8_t>(0, 0), 0);  // x - d leaves the image
  EXPECT_EQ(mask.at<std::uint8_t>(0, 1), 0);
  EXPECT_EQ(mask.at<std::uint8_t>(0, 2), 255);
  EXPECT_EQ(mask.at<std::uint8_t>(0, 5), 0);
  EXPECT_EQ(mask.at<std::uint8_t>(0, 6), 255);
}

TEST(MiddleburyLayout, UnknownFolderIsNotASet) {
  TempDir dir("empty");
  EXPECT_FALSE(DetectMiddleburyLayout(dir.str()));
  EXPECT_TRUE(FindMiddleburyDatasets(dir.str()).empty());
  EXPECT_THROW(LoadMiddlebury(dir.str()), std::runtime_error);
  EXPECT_FALSE(DetectMiddleburyLayout(dir / "does-not-exist"));
}

TEST(MiddleburyLayout, Synthetic2003SetScalesByFourAndChecksSizes) {
  TempDir dir("synthetic");
  std::mt19937 random(7);
  cv::Mat left(40, 60, CV_8U), disparity(40, 60, CV_8U, cv::Scalar(12));  // 12 / 4 = 3 px
  cv::randu(left, 0, 255);
  disparity.at<std::uint8_t>(5, 5) = 0;  // unknown
  cv::imwrite(dir / "im2.png", left);
  cv::imwrite(dir / "im6.png", left);
  cv::imwrite(dir / "disp2.png", disparity);
  ASSERT_EQ(DetectMiddleburyLayout(dir.str()), MiddleburyLayout::k2003);
  const MiddleburyPair pair = LoadMiddlebury(dir.str());
  EXPECT_EQ(pair.scale_factor, 4.0);
  EXPECT_FLOAT_EQ(pair.disparity.at<float>(0, 0), 3.0f);
  EXPECT_TRUE(std::isnan(pair.disparity.at<float>(5, 5)));
  EXPECT_EQ(pair.nonoccluded.at<std::uint8_t>(5, 5), 0);
  EXPECT_EQ(pair.occlusion_source, "none");
  EXPECT_EQ(pair.max_disparity, 16.0);
  cv::imwrite(dir / "disp2.png", cv::Mat(20, 60, CV_8U, cv::Scalar(12)));
  EXPECT_THROW(LoadMiddlebury(dir.str()), std::runtime_error);
}

TEST(UpsampledMiddlebury, ScalesTheImagesTheTruthAndTheRange) {
  TempDir dir("upsampled");
  std::mt19937 random(9);
  cv::Mat left(40, 60, CV_8U), disparity(40, 60, CV_8U, cv::Scalar(12));  // 12 / 4 = 3 px
  cv::randu(left, 0, 255);
  disparity.at<std::uint8_t>(5, 5) = 0;  // unknown
  cv::imwrite(dir / "im2.png", left);
  cv::imwrite(dir / "im6.png", left);
  cv::imwrite(dir / "disp2.png", disparity);
  const MiddleburyPair pair = LoadMiddlebury(dir.str());
  const MiddleburyPair up = UpsampledMiddlebury(pair, 2.0);
  EXPECT_EQ(up.name, pair.name + "_x2");
  EXPECT_EQ(up.left_grey.size(), cv::Size(120, 80));
  EXPECT_EQ(up.disparity.size(), cv::Size(120, 80));
  EXPECT_FLOAT_EQ(up.disparity.at<float>(0, 0), 6.0f);
  EXPECT_TRUE(std::isnan(up.disparity.at<float>(10, 10)));  // pixel (5, 5) covers 10..11
  EXPECT_EQ(up.max_disparity, 2.0 * pair.max_disparity);
  EXPECT_EQ(UpsampledMiddlebury(pair, 1.0).left_grey.size(), pair.left_grey.size());
  EXPECT_THROW(UpsampledMiddlebury(pair, 0.5), std::invalid_argument);
}

// Mean |I_left(x, y) - I_right(x - d, y)| over non-occluded pixels, with the truth or shifted.
double PhotometricError(const MiddleburyPair& pair, double extra_shift) {
  double sum = 0.0;
  int n = 0;
  for (int y = 0; y < pair.disparity.rows; y += 2) {
    for (int x = 0; x < pair.disparity.cols; x += 2) {
      if (!pair.nonoccluded.at<std::uint8_t>(y, x)) continue;
      const long xr = std::lround(static_cast<double>(x) - pair.disparity.at<float>(y, x) - extra_shift);
      if (xr < 0 || xr >= pair.disparity.cols) continue;
      sum += std::abs(pair.left_grey.at<std::uint8_t>(y, x) - pair.right_grey.at<std::uint8_t>(y, static_cast<int>(xr)));
      ++n;
    }
  }
  return n ? sum / n : 1e9;
}

struct RealSet {
  const char* folder;
  MiddleburyLayout layout;
  double scale;
  double min_truth, max_truth;  // px
  const char* occlusion_source;
};

class RealSets : public ::testing::TestWithParam<RealSet> {};

TEST_P(RealSets, LoadWithTheRightScaleAndConvention) {
  const RealSet& set = GetParam();
  const std::string dir = kDatasets + "/" + set.folder;
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " is absent";
  const MiddleburyPair pair = LoadMiddlebury(dir);
  EXPECT_EQ(pair.layout, set.layout);
  EXPECT_EQ(pair.scale_factor, set.scale);
  EXPECT_EQ(pair.occlusion_source, set.occlusion_source);
  EXPECT_EQ(pair.disparity.size(), pair.left_grey.size());
  double low = 0, high = 0;
  cv::Mat known = pair.disparity.clone();
  known.setTo(1000.0f, pair.disparity != pair.disparity);
  cv::minMaxLoc(known, &low, nullptr);
  known.setTo(-1.0f, pair.disparity != pair.disparity);
  cv::minMaxLoc(known, nullptr, &high);
  EXPECT_NEAR(low, set.min_truth, 1.0);
  EXPECT_NEAR(high, set.max_truth, 1.0);
  EXPECT_GE(pair.max_disparity, high);
  // Most pixels with truth are visible; the occluded share is a few to ~15 %.
  const double visible = cv::countNonZero(pair.nonoccluded);
  const double with_truth = cv::countNonZero(pair.disparity == pair.disparity);
  EXPECT_GT(visible / with_truth, 0.8);
  EXPECT_LE(visible, with_truth);
  // The convention (x - d) and the scale make the views agree; one pixel off is clearly worse.
  const double at_truth = PhotometricError(pair, 0.0);
  // (Adirondack's two exposures differ: its ratio is about 0.75, the others' below 0.6.)
  EXPECT_LT(at_truth, 0.85 * PhotometricError(pair, 2.0)) << at_truth;
  EXPECT_LT(at_truth, 0.85 * PhotometricError(pair, -2.0)) << at_truth;
}

INSTANTIATE_TEST_SUITE_P(
    SharedDatasets, RealSets,
    ::testing::Values(
        RealSet{"middlebury2001_tsukuba", MiddleburyLayout::k2001Tsukuba, 16.0, 5.0, 14.0, "mask"},
        RealSet{"middlebury2001_venus", MiddleburyLayout::k2001, 8.0, 3.0, 19.75, "left-right check"},
        RealSet{"middlebury2003_teddy", MiddleburyLayout::k2003, 4.0, 12.0, 52.75, "left-right check"},
        RealSet{"middlebury2005_2006_third_Aloe", MiddleburyLayout::k2005, 3.0, 14.33, 70.33,
                "left-right check"},
        RealSet{"middlebury2014_Q_Adirondack", MiddleburyLayout::k2014, 1.0, 9.46, 63.04, "mask"}));

TEST(UpsampledMiddlebury, TheTruthStillMapsLeftPixelsOntoTheirRightPixels) {
  const MiddleburyPair up = UpsampledMiddlebury(
      LoadMiddlebury(std::string(HNNSTEREO_SOURCE_DIR) + "/tests/data/middlebury2003_teddy"), 2.0);
  // The scaled truth lands each left pixel on its own right pixel: 4 px (2 of the pair as
  // stored) either way is clearly worse.
  const double at_truth = PhotometricError(up, 0.0);
  EXPECT_LT(at_truth, 0.85 * PhotometricError(up, 4.0)) << at_truth;
  EXPECT_LT(at_truth, 0.85 * PhotometricError(up, -4.0)) << at_truth;
  const std::string folder = kDatasets + "/middlebury2014_Q_Adirondack";
  if (!fs::exists(folder)) GTEST_SKIP() << folder << " not present";
  const MiddleburyPair calibrated = UpsampledMiddlebury(LoadMiddlebury(folder), 2.0);
  EXPECT_EQ(calibrated.calibration->ImageSizeProblem(calibrated.left_grey.cols,
                                                     calibrated.left_grey.rows), "");
}

TEST(MiddleburyDatasets, ParentFolderListsEverySetSorted) {
  if (!fs::exists(kDatasets)) GTEST_SKIP() << kDatasets << " is absent";
  const std::vector<std::string> sets = FindMiddleburyDatasets(kDatasets);
  ASSERT_GE(sets.size(), 5u);
  EXPECT_TRUE(std::is_sorted(sets.begin(), sets.end()));
  const std::vector<std::string> one = FindMiddleburyDatasets(sets.front());
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one.front(), sets.front());
}

TEST(MiddleburyCalibration, The2014SetCarriesItsCalibTxt) {
  const std::string dir = kDatasets + "/middlebury2014_Q_Adirondack";
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " is absent";
  const MiddleburyPair pair = LoadMiddlebury(dir);
  ASSERT_TRUE(pair.calibration.has_value());
  EXPECT_NEAR(pair.calibration->P1(0, 0), 1038.018, 1e-3);
}

}  // namespace
}  // namespace hnnstereo::vision
