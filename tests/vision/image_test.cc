#include "common/image.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

namespace fs = std::filesystem;

/// A fresh temporary directory per test, removed afterwards.
class LoadImageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = fs::temp_directory_path() /
                 ("hnnstereo_image_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(directory_, ignored);
  }
  std::string PathOf(const std::string& name) const { return (directory_ / name).string(); }
  std::string Write(const std::string& name, const cv::Mat& image) const {
    const std::string path = PathOf(name);
    EXPECT_TRUE(cv::imwrite(path, image)) << path;
    return path;
  }

  fs::path directory_;
};

/// Expects `call` to throw std::runtime_error whose message contains `fragment`.
template <typename Call>
void ExpectRuntimeError(Call call, const std::string& fragment) {
  try {
    call();
    ADD_FAILURE() << "no exception; expected one mentioning '" << fragment << "'";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
    EXPECT_EQ(std::string(error.what()).find('\n'), std::string::npos) << "one line expected";
  }
}

cv::Mat Ramp8(int rows, int cols) {
  cv::Mat image(rows, cols, CV_8UC1);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x)
      image.at<unsigned char>(y, x) = cv::saturate_cast<uchar>(x + 2 * y);
  }
  return image;
}

TEST_F(LoadImageTest, Grey8BitKeptAsIs) {
  const cv::Mat ramp = Ramp8(30, 40);
  const std::string path = Write("grey.png", ramp);
  const LoadedImage image = LoadImage(path);
  EXPECT_EQ(image.path, path);
  EXPECT_EQ(image.bit_depth, 8);
  EXPECT_EQ(image.channels, 1);
  ASSERT_EQ(image.grey.type(), CV_8UC1);
  EXPECT_EQ(cv::norm(image.grey, ramp, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(image.original, ramp, cv::NORM_INF), 0.0);
  // The grey copy does not alias the original.
  EXPECT_NE(image.grey.data, image.original.data);
}

TEST_F(LoadImageTest, SixteenBitScaledByItsRange) {
  cv::Mat deep(20, 50, CV_16UC1);
  for (int y = 0; y < deep.rows; ++y) {
    for (int x = 0; x < deep.cols; ++x)
      deep.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(1000 + 80 * x);
  }
  const LoadedImage image = LoadImage(Write("deep.png", deep));
  EXPECT_EQ(image.bit_depth, 16);
  EXPECT_EQ(image.channels, 1);
  EXPECT_EQ(image.original.type(), CV_16UC1);
  ASSERT_EQ(image.grey.type(), CV_8UC1);
  double min_value = 0.0, max_value = 0.0;
  cv::minMaxLoc(image.grey, &min_value, &max_value);
  EXPECT_EQ(min_value, 0.0);    // 1000 -> 0
  EXPECT_EQ(max_value, 255.0);  // 1000 + 80 * 49 -> 255
  for (int x = 1; x < deep.cols; ++x) {
    EXPECT_GT(image.grey.at<unsigned char>(0, x), image.grey.at<unsigned char>(0, x - 1));
  }
  EXPECT_NEAR(image.grey.at<unsigned char>(5, 25), 255.0 * 25 / 49, 0.51);
}

TEST_F(LoadImageTest, ColourConvertedToGrey) {
  cv::Mat colour(16, 24, CV_8UC3, cv::Scalar(200, 100, 50));  // B, G, R
  const LoadedImage image = LoadImage(Write("colour.png", colour));
  EXPECT_EQ(image.bit_depth, 8);
  EXPECT_EQ(image.channels, 3);
  EXPECT_EQ(image.original.type(), CV_8UC3);
  ASSERT_EQ(image.grey.type(), CV_8UC1);
  EXPECT_EQ(image.grey.size(), colour.size());
  // ITU-R BT.601 luma: 0.299 R + 0.587 G + 0.114 B.
  EXPECT_NEAR(image.grey.at<unsigned char>(3, 3), 0.299 * 50 + 0.587 * 100 + 0.114 * 200, 1.0);
}

TEST_F(LoadImageTest, SixteenBitColour) {
  // 16 x 16: the smallest image LoadImage takes (ImageLimits::min_side_px).
  cv::Mat colour(16, 16, CV_16UC3, cv::Scalar(1000, 2000, 3000));
  colour(cv::Rect(0, 0, 5, 16)).setTo(cv::Scalar(40000, 40000, 40000));
  const LoadedImage image = LoadImage(Write("deep_colour.png", colour));
  EXPECT_EQ(image.bit_depth, 16);
  EXPECT_EQ(image.channels, 3);
  ASSERT_EQ(image.grey.type(), CV_8UC1);
  EXPECT_EQ(image.grey.at<unsigned char>(0, 0), 255);
  EXPECT_EQ(image.grey.at<unsigned char>(0, 9), 0);
}

TEST_F(LoadImageTest, LimitsAreCheckedOnTheHeaderBeforeDecoding) {
  const std::string path = Write("ramp.png", Ramp8(40, 60));
  ImageLimits limits;
  limits.max_side_px = 50;
  ExpectRuntimeError([&] { LoadImage(path, limits); }, "is 60x40 pixels by its header, beyond");
  limits = ImageLimits{};
  limits.max_pixels = 60 * 40 - 1;
  ExpectRuntimeError([&] { LoadImage(path, limits); }, "beyond the limits");
  limits = ImageLimits{};
  limits.min_side_px = 41;
  ExpectRuntimeError([&] { LoadImage(path, limits); }, "smaller than the minimum of 41");
  limits = ImageLimits{};
  limits.max_file_bytes = 10;
  ExpectRuntimeError([&] { LoadImage(path, limits); }, "more than the limit of 10");
  EXPECT_EQ(LoadImage(path).grey.size(), cv::Size(60, 40));
}

TEST(ImageHeaderSize, ReadsEachFormatsHeaderWithoutDecoding) {
  const cv::Mat image = Ramp8(21, 34);
  for (const std::string extension : {".png", ".jpg", ".bmp", ".pgm", ".tif"}) {
    std::vector<unsigned char> encoded;
    ASSERT_TRUE(cv::imencode(extension, image, encoded)) << extension;
    int width = 0, height = 0;
    ASSERT_TRUE(calib::ReadImageHeaderSize(encoded, &width, &height)) << extension;
    EXPECT_EQ(width, 34) << extension;
    EXPECT_EQ(height, 21) << extension;
    // Cut anywhere in the header: no crash, no read past the end (ASan checks that).
    for (std::size_t cut = 0; cut < std::min<std::size_t>(encoded.size(), 64); ++cut) {
      const std::vector<unsigned char> head(encoded.begin(), encoded.begin() + static_cast<long>(cut));
      calib::ReadImageHeaderSize(head, &width, &height);
    }
  }
}

TEST_F(LoadImageTest, MissingFileSaysSo) {
  const std::string path = PathOf("no_such_image.png");
  ExpectRuntimeError([&] { LoadImage(path); }, "image '" + path + "' does not exist");
}

TEST_F(LoadImageTest, NonImageFileCannotBeRead) {
  const std::string path = PathOf("notes.png");
  std::ofstream(path) << "this is not a PNG file\n";
  ExpectRuntimeError([&] { LoadImage(path); },
                     "image '" + path + "' cannot be read (not an image or unsupported format)");
}

TEST_F(LoadImageTest, EmptyFileSaysEmpty) {
  const std::string path = PathOf("empty.png");
  std::ofstream{path};
  ExpectRuntimeError([&] { LoadImage(path); }, "empty");
}

TEST_F(LoadImageTest, DirectoryIsNotAnImage) {
  ExpectRuntimeError([&] { LoadImage(directory_.string()); }, "directory");
}

TEST_F(LoadImageTest, LoadsTeddyFromSharedData) {
  const std::string path =
      std::string(HNNSTEREO_SHARED_DIR) + "/datasets/middlebury2003_teddy/im2.png";
  if (!fs::exists(path)) GTEST_SKIP() << "shared data not found: " << path;
  const LoadedImage image = LoadImage(path);
  EXPECT_EQ(image.grey.cols, 450);
  EXPECT_EQ(image.grey.rows, 375);
  EXPECT_EQ(image.grey.type(), CV_8UC1);
  EXPECT_EQ(image.channels, 3);
}

TEST_F(LoadImageTest, CheckSameSizeNamesBothSizes) {
  const LoadedImage left = LoadImage(Write("left.png", Ramp8(48, 64)));
  const LoadedImage right = LoadImage(Write("right.png", Ramp8(24, 32)));
  const LoadedImage left_again = LoadImage(Write("left_again.png", Ramp8(48, 64)));
  EXPECT_NO_THROW(CheckSameSize(left, left_again));
  try {
    CheckSameSize(left, right);
    ADD_FAILURE() << "size mismatch not detected";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("64x48"), std::string::npos) << message;
    EXPECT_NE(message.find("32x24"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace hnnstereo::vision
