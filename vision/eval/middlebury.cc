#include "vision/eval/middlebury.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/atomic_file.h"
#include "common/image.h"

namespace hnnstereo::vision {
namespace {

namespace fs = std::filesystem;

constexpr float kUnknown = std::numeric_limits<float>::quiet_NaN();

// The first existing file among `stem` + each extension, or "".
std::string FindFile(const fs::path& directory, const std::string& stem,
                     std::initializer_list<const char*> extensions) {
  for (const char* extension : extensions) {
    const fs::path path = directory / (stem + extension);
    std::error_code error;
    if (fs::is_regular_file(path, error)) return path.string();
  }
  return {};
}

struct LayoutFiles {
  std::string left, right, disparity, right_disparity, mask, calib;
};

std::optional<std::pair<MiddleburyLayout, LayoutFiles>> FindLayoutFiles(const fs::path& dir) {
  LayoutFiles f;
  // 2014: im0/im1 + disp0GT.pfm (or disp0.pfm) + calib.txt + mask0nocc.png.
  f.left = FindFile(dir, "im0", {".png"});
  f.right = FindFile(dir, "im1", {".png"});
  f.disparity = FindFile(dir, "disp0GT", {".pfm"});
  if (f.disparity.empty()) f.disparity = FindFile(dir, "disp0", {".pfm"});
  if (!f.left.empty() && !f.right.empty() && !f.disparity.empty()) {
    f.right_disparity = FindFile(dir, "disp1GT", {".pfm"});
    f.mask = FindFile(dir, "mask0nocc", {".png"});
    f.calib = FindFile(dir, "calib", {".txt"});
    return std::make_pair(MiddleburyLayout::k2014, f);
  }
  // 2001 Tsukuba: five views of row 3; left = col3, right = col4.
  f = {};
  f.left = FindFile(dir, "scene1.row3.col3", {".ppm", ".png"});
  f.right = FindFile(dir, "scene1.row3.col4", {".ppm", ".png"});
  f.disparity = FindFile(dir, "truedisp.row3.col3", {".pgm", ".png"});
  if (!f.left.empty() && !f.right.empty() && !f.disparity.empty()) {
    f.mask = FindFile(dir, "nonocc", {".png"});
    return std::make_pair(MiddleburyLayout::k2001Tsukuba, f);
  }
  // 2005/2006: view1/view5 + disp1.png (+ disp5.png).
  f = {};
  f.left = FindFile(dir, "view1", {".png"});
  f.right = FindFile(dir, "view5", {".png"});
  f.disparity = FindFile(dir, "disp1", {".png"});
  if (!f.left.empty() && !f.right.empty() && !f.disparity.empty()) {
    f.right_disparity = FindFile(dir, "disp5", {".png"});
    f.mask = FindFile(dir, "nonocc", {".png"});
    return std::make_pair(MiddleburyLayout::k2005, f);
  }
  // 2001 (Venus, Sawtooth...): im2/im6 + disp2.pgm; 2003 (Teddy, Cones): im2/im6 + disp2.png.
  f = {};
  f.left = FindFile(dir, "im2", {".png", ".ppm", ".pgm"});
  f.right = FindFile(dir, "im6", {".png", ".ppm", ".pgm"});
  if (f.left.empty() || f.right.empty()) return std::nullopt;
  f.mask = FindFile(dir, "nonocc", {".png"});
  f.disparity = FindFile(dir, "disp2", {".pgm"});
  if (!f.disparity.empty()) {
    f.right_disparity = FindFile(dir, "disp6", {".pgm"});
    return std::make_pair(MiddleburyLayout::k2001, f);
  }
  f.disparity = FindFile(dir, "disp2", {".png"});
  if (!f.disparity.empty()) {
    f.right_disparity = FindFile(dir, "disp6", {".png"});
    return std::make_pair(MiddleburyLayout::k2003, f);
  }
  return std::nullopt;
}

// 8-bit PGM/PNG ground truth: value / scale, 0 = unknown.
cv::Mat ReadScaledDisparity(const std::string& path, double scale) {
  const cv::Mat stored =
      calib::ReadImageFileWithin(path, cv::IMREAD_GRAYSCALE | cv::IMREAD_ANYDEPTH);
  cv::Mat values;
  stored.convertTo(values, CV_32F);
  cv::Mat disparity(values.size(), CV_32F);
  for (int y = 0; y < values.rows; ++y) {
    const float* in = values.ptr<float>(y);
    float* out = disparity.ptr<float>(y);
    for (int x = 0; x < values.cols; ++x) {
      out[x] = in[x] > 0.0f ? static_cast<float>(in[x] / scale) : kUnknown;
    }
  }
  return disparity;
}

// PFM ground truth: +inf (or any non-finite value) = unknown.
cv::Mat ReadPfmDisparity(const std::string& path) {
  cv::Mat disparity = ReadPfm(path);
  if (disparity.type() != CV_32F) throw std::runtime_error("ground truth " + path + " is not a grey PFM");
  // A finite disparity outside [0, width] cannot be meant; it would also set the search range
  // (max_disparity) of the whole evaluation.
  const float max_disparity = static_cast<float>(disparity.cols);
  for (int y = 0; y < disparity.rows; ++y) {
    float* row = disparity.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      if (!std::isfinite(row[x])) {
        row[x] = kUnknown;
      } else if (row[x] < 0.0f || row[x] > max_disparity) {
        throw std::runtime_error("ground truth " + path + " has a disparity of " +
                                 std::to_string(row[x]) + " at (" + std::to_string(x) + ", " +
                                 std::to_string(y) + "), outside [0, " +
                                 std::to_string(disparity.cols) + "] (the image width)");
      }
    }
  }
  return disparity;
}

// Scale factor of the 2005/2006 sets: third size stores 3 d (README, verified on Aloe); half
// and full size are assumed to store 2 d and d. The width tells the size (full ~1300 px).
double Scale2005(int width) {
  if (width < 500) return 3.0;
  if (width < 900) return 2.0;
  return 1.0;
}

// Scale factor of the 2003 sets: quarter size (450 px wide) stores 4 d, half size 2 d.
double Scale2003(int width) { return width < 600 ? 4.0 : 2.0; }

}  // namespace

std::string_view MiddleburyLayoutName(MiddleburyLayout layout) {
  switch (layout) {
    case MiddleburyLayout::k2001Tsukuba: return "middlebury2001-tsukuba";
    case MiddleburyLayout::k2001: return "middlebury2001";
    case MiddleburyLayout::k2003: return "middlebury2003";
    case MiddleburyLayout::k2005: return "middlebury2005";
    case MiddleburyLayout::k2014: return "middlebury2014";
  }
  return "unknown";
}

std::optional<MiddleburyLayout> DetectMiddleburyLayout(const std::string& directory) {
  std::error_code error;
  if (!fs::is_directory(directory, error)) return std::nullopt;
  const auto found = FindLayoutFiles(directory);
  if (!found) return std::nullopt;
  return found->first;
}

std::vector<std::string> FindMiddleburyDatasets(const std::string& directory) {
  if (DetectMiddleburyLayout(directory)) return {directory};
  std::vector<std::string> sets;
  std::error_code error;
  if (!fs::is_directory(directory, error)) return sets;
  for (const auto& entry : fs::directory_iterator(directory, error)) {
    if (entry.is_directory(error) && DetectMiddleburyLayout(entry.path().string())) {
      sets.push_back(entry.path().string());
    }
  }
  std::sort(sets.begin(), sets.end());
  return sets;
}

cv::Mat LeftRightConsistentMask(const cv::Mat& left_disparity, const cv::Mat& right_disparity,
                                double tolerance_px) {
  if (left_disparity.type() != CV_32F || right_disparity.type() != CV_32F ||
      left_disparity.size() != right_disparity.size()) {
    throw std::invalid_argument("left-right check needs two CV_32F maps of the same size");
  }
  cv::Mat mask(left_disparity.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < left_disparity.rows; ++y) {
    const float* left = left_disparity.ptr<float>(y);
    const float* right = right_disparity.ptr<float>(y);
    for (int x = 0; x < left_disparity.cols; ++x) {
      const float d = left[x];
      if (!std::isfinite(d)) continue;
      const long xr = std::lround(static_cast<double>(x) - d);
      if (xr < 0 || xr >= left_disparity.cols) continue;
      const float dr = right[xr];
      if (std::isfinite(dr) && std::abs(dr - d) <= tolerance_px) mask.at<std::uint8_t>(y, x) = 255;
    }
  }
  return mask;
}

MiddleburyPair UpsampledMiddlebury(const MiddleburyPair& pair, double factor) {
  if (!(factor >= 1.0) || !(factor <= 16.0)) {
    throw std::invalid_argument("an upsampling factor must be in [1, 16]");
  }
  if (factor == 1.0) return pair;
  MiddleburyPair up = pair;
  std::ostringstream name;
  name << pair.name << "_x" << factor;
  up.name = name.str();
  const cv::Size size(static_cast<int>(std::lround(pair.left_grey.cols * factor)),
                      static_cast<int>(std::lround(pair.left_grey.rows * factor)));
  auto images = [&](const cv::Mat& in, int interpolation) {
    cv::Mat out;
    if (!in.empty()) cv::resize(in, out, size, 0, 0, interpolation);
    return out;
  };
  up.left_original = images(pair.left_original, cv::INTER_CUBIC);
  up.right_original = images(pair.right_original, cv::INTER_CUBIC);
  up.left_grey = images(pair.left_grey, cv::INTER_CUBIC);
  up.right_grey = images(pair.right_grey, cv::INTER_CUBIC);
  auto disparities = [&](const cv::Mat& in) {
    cv::Mat out = images(in, cv::INTER_NEAREST);
    if (!out.empty()) out *= factor;
    return out;
  };
  up.disparity = disparities(pair.disparity);
  up.right_disparity = disparities(pair.right_disparity);
  up.nonoccluded = images(pair.nonoccluded, cv::INTER_NEAREST);
  up.min_disparity = pair.min_disparity * factor;
  up.max_disparity = pair.max_disparity * factor;
  if (pair.calibration) {
    // x' = S x with S = [f 0 (f-1)/2; 0 f (f-1)/2; 0 0 1]: P' = S P.
    Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
    S(0, 0) = S(1, 1) = factor;
    S(0, 2) = S(1, 2) = (factor - 1.0) / 2.0;
    up.calibration->P1 = S * pair.calibration->P1;
    up.calibration->P2 = S * pair.calibration->P2;
    up.calibration->image_width = size.width;
    up.calibration->image_height = size.height;
    up.calibration->DeriveFromProjections();
  }
  return up;
}

MiddleburyPair LoadMiddlebury(const std::string& directory) {
  const fs::path dir(directory);
  const auto found = FindLayoutFiles(dir);
  if (!found) {
    throw std::runtime_error(directory + " is not a recognised Middlebury set (see --help for layouts)");
  }
  const auto& [layout, files] = *found;
  MiddleburyPair pair;
  pair.directory = directory;
  pair.name = fs::path(directory).lexically_normal().filename().string();
  if (pair.name.empty()) pair.name = fs::path(directory).lexically_normal().parent_path().filename().string();
  pair.layout = layout;
  pair.left_path = files.left;
  pair.right_path = files.right;
  const LoadedImage left = LoadImage(files.left);
  const LoadedImage right = LoadImage(files.right);
  CheckSameSize(left, right);
  pair.left_original = left.original;
  pair.right_original = right.original;
  pair.left_grey = left.grey;
  pair.right_grey = right.grey;
  const int width = left.grey.cols;

  switch (layout) {
    case MiddleburyLayout::k2001Tsukuba: pair.scale_factor = 16.0; break;
    case MiddleburyLayout::k2001: pair.scale_factor = 8.0; break;
    case MiddleburyLayout::k2003: pair.scale_factor = Scale2003(width); break;
    case MiddleburyLayout::k2005: pair.scale_factor = Scale2005(width); break;
    case MiddleburyLayout::k2014: pair.scale_factor = 1.0; break;
  }
  if (layout == MiddleburyLayout::k2014) {
    pair.disparity = ReadPfmDisparity(files.disparity);
    if (!files.right_disparity.empty()) pair.right_disparity = ReadPfmDisparity(files.right_disparity);
  } else {
    pair.disparity = ReadScaledDisparity(files.disparity, pair.scale_factor);
    if (!files.right_disparity.empty()) {
      pair.right_disparity = ReadScaledDisparity(files.right_disparity, pair.scale_factor);
    }
  }
  if (pair.disparity.size() != left.grey.size()) {
    throw std::runtime_error("ground truth " + files.disparity + " is " +
                             std::to_string(pair.disparity.cols) + "x" +
                             std::to_string(pair.disparity.rows) + ", the images " +
                             std::to_string(width) + "x" + std::to_string(left.grey.rows));
  }
  if (!pair.right_disparity.empty() && pair.right_disparity.size() != pair.disparity.size()) {
    pair.right_disparity.release();
  }

  const cv::Mat known = pair.disparity == pair.disparity;  // false at NaN
  if (!files.mask.empty()) {
    const cv::Mat mask = calib::ReadImageFileWithin(files.mask, cv::IMREAD_GRAYSCALE);
    if (mask.empty() || mask.size() != pair.disparity.size()) {
      throw std::runtime_error("cannot use occlusion mask " + files.mask);
    }
    // 2014: 255 = non-occluded, 128 = occluded. 2001: palette index 1 (white) = counted.
    const double level = layout == MiddleburyLayout::k2014 ? 254.0 : 0.0;
    cv::Mat visible = mask > level;
    pair.nonoccluded = visible & known;
    pair.occlusion_source = "mask";
  } else if (!pair.right_disparity.empty()) {
    pair.nonoccluded = LeftRightConsistentMask(pair.disparity, pair.right_disparity, 1.0);
    pair.occlusion_source = "left-right check";
  } else {
    pair.nonoccluded = known.clone();
    pair.occlusion_source = "none";
  }

  if (layout == MiddleburyLayout::k2014 && !files.calib.empty()) {
    std::ifstream in(files.calib);
    std::stringstream text;
    text << in.rdbuf();
    pair.calibration = calib::ParseMiddleburyCalib(text.str());
  }
  // One search range for every method: [0, max ground truth], rounded up to a multiple of 16
  // (StereoBM/SGBM need that), so that no method is handed a narrower range than another.
  double max_truth = 0.0;
  cv::Mat truth_only;
  pair.disparity.copyTo(truth_only);
  truth_only.setTo(0.0f, ~known);
  cv::minMaxLoc(truth_only, nullptr, &max_truth);
  pair.min_disparity = 0.0;
  pair.max_disparity = 16.0 * std::ceil((max_truth + 1.0) / 16.0);
  return pair;
}

cv::Mat ReadPfm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open PFM " + path);
  std::string magic;
  int width = 0, height = 0;
  double scale = 0.0;
  in >> magic >> width >> height >> scale;
  if (!in || (magic != "Pf" && magic != "PF") || width <= 0 || height <= 0 || scale == 0.0 ||
      width > 100000 || height > 100000) {
    throw std::runtime_error("malformed PFM header in " + path);
  }
  in.get();  // the single whitespace byte after the scale
  const int channels = magic == "PF" ? 3 : 1;
  // The header alone must not decide how much memory is taken: a 100000 x 100000 header on a
  // tiny file would ask for 40 GB. The file has to hold every pixel it claims.
  const std::uintmax_t needed = static_cast<std::uintmax_t>(width) *
                                static_cast<std::uintmax_t>(height) *
                                static_cast<std::uintmax_t>(channels) * 4u;
  const std::streamoff data_start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff file_end = in.tellg();
  in.seekg(data_start);
  if (!in || data_start < 0 || file_end < data_start ||
      static_cast<std::uintmax_t>(file_end - data_start) < needed) {
    throw std::runtime_error("PFM " + path + " is truncated: its header says " +
                             std::to_string(width) + "x" + std::to_string(height) + " (" +
                             std::to_string(needed) + " bytes of data)");
  }
  cv::Mat image(height, width, CV_MAKETYPE(CV_32F, channels));
  const bool little_endian_file = scale < 0.0;
  const std::uint32_t probe = 1;
  unsigned char first_byte = 0;
  std::memcpy(&first_byte, &probe, 1);
  const bool little_endian_host = first_byte == 1;
  const std::size_t row_bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(channels) * 4;
  // Rows are stored bottom-to-top.
  for (int row = height - 1; row >= 0; --row) {
    char* data = reinterpret_cast<char*>(image.ptr(row));
    in.read(data, static_cast<std::streamsize>(row_bytes));
    if (!in) throw std::runtime_error("PFM " + path + " is truncated");
    if (little_endian_file != little_endian_host) {
      for (std::size_t i = 0; i < row_bytes; i += 4) {
        std::swap(data[i], data[i + 3]);
        std::swap(data[i + 1], data[i + 2]);
      }
    }
  }
  return image;
}

void WritePfm(const std::string& path, const cv::Mat& image) {
  if (image.type() != CV_32F || image.empty()) throw std::invalid_argument("WritePfm needs a CV_32F image");
  const std::uint32_t probe = 1;
  unsigned char first_byte = 0;
  std::memcpy(&first_byte, &probe, 1);
  if (first_byte != 1) throw std::runtime_error("WritePfm supports little-endian hosts only");
  std::string contents = "Pf\n" + std::to_string(image.cols) + " " + std::to_string(image.rows) + "\n-1\n";
  for (int row = image.rows - 1; row >= 0; --row) {
    contents.append(reinterpret_cast<const char*>(image.ptr(row)),
                    static_cast<std::size_t>(image.cols) * 4);
  }
  calib::WriteFileAtomically(path, contents);
}

}  // namespace hnnstereo::vision
