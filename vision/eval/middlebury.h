#pragma once
// Middlebury stereo data sets with ground truth (../shared/datasets/README.md): the 2001 sets
// (Tsukuba: PPM views + truedisp PGM / 16 + masks; Venus-like: im2/im6 + disp2.pgm / 8), 2003
// (im2/im6 + disp2.png / 4 at quarter size), 2005/2006 (view1/view5 + disp1.png / 3 at third
// size) and 2014 (im0/im1 + disp0GT.pfm + calib.txt + mask0nocc.png).
// Convention everywhere: a left pixel (x, y) with disparity d matches the right pixel (x - d, y).
//
// D. Scharstein, R. Szeliski, "A taxonomy and evaluation of dense two-frame stereo
// correspondence algorithms", IJCV 47, 2002; Scharstein & Szeliski CVPR 2003; Hirschmueller &
// Scharstein CVPR 2007; Scharstein et al., GCPR 2014.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>

#include "calib/calibration.h"

namespace hnnstereo::vision {

enum class MiddleburyLayout { k2001Tsukuba, k2001, k2003, k2005, k2014 };

/// "middlebury2001-tsukuba", "middlebury2001", "middlebury2003", "middlebury2005", "middlebury2014".
std::string_view MiddleburyLayoutName(MiddleburyLayout layout);

/// One rectified pair with its ground truth, as loaded from a Middlebury folder.
struct MiddleburyPair {
  std::string name;        ///< the folder's name, e.g. "middlebury2003_teddy"
  std::string directory;
  MiddleburyLayout layout = MiddleburyLayout::k2003;
  std::string left_path, right_path;
  cv::Mat left_original, right_original;  ///< as stored (colour), for overlays
  cv::Mat left_grey, right_grey;          ///< CV_8U working copies
  /// Left-view disparity in pixels (CV_32F), already divided by the layout's scale factor;
  /// NaN where the ground truth is unknown.
  cv::Mat disparity;
  /// Right-view disparity (CV_32F, NaN unknown) when the set ships one; else empty.
  cv::Mat right_disparity;
  /// CV_8U, 255 where the left pixel is visible in the right image (non-occluded) and has
  /// ground truth, 0 elsewhere. From the set's mask when it has one, else from a left-right
  /// check of the two disparity maps, else every pixel with ground truth.
  cv::Mat nonoccluded;
  std::string occlusion_source;  ///< "mask", "left-right check" or "none"
  double scale_factor = 1.0;     ///< stored value / this = disparity (px)
  double min_disparity = 0.0;    ///< search range for every method (px)
  double max_disparity = 64.0;   ///< search range (px): ground-truth maximum, rounded up to 16
  std::optional<calib::StereoCalibration> calibration;  ///< 2014 calib.txt (rectified)
};

/// The layout of a folder, or nullopt when it is not a recognised Middlebury set.
std::optional<MiddleburyLayout> DetectMiddleburyLayout(const std::string& directory);

/// `directory` itself when it is a recognised set, else its recognised immediate subfolders,
/// sorted by name. Empty when there are none.
std::vector<std::string> FindMiddleburyDatasets(const std::string& directory);

/// Loads a pair and its ground truth. Throws std::runtime_error with a one-line reason
/// (unrecognised folder, unreadable file, sizes that disagree).
MiddleburyPair LoadMiddlebury(const std::string& directory);

/// The pair at `factor` times its size, for camera-sized tests with real ground truth: the
/// images bicubic, the ground truth and masks nearest-neighbour with every disparity times
/// `factor` (a pixel x maps to factor x + (factor - 1) / 2), the search range and calibration
/// scaled alike; `name` gains "_x<factor>". factor >= 1; 1 returns the pair unchanged.
MiddleburyPair UpsampledMiddlebury(const MiddleburyPair& pair, double factor);

/// Reads a PFM image (header "Pf" grey or "PF" colour, negative scale = little-endian, rows
/// stored bottom-to-top) as CV_32F (CV_32FC3 for "PF"), top row first. Infinite values are kept.
/// Throws std::runtime_error on a malformed file.
cv::Mat ReadPfm(const std::string& path);

/// Writes a CV_32F image as a little-endian grey PFM ("Pf", scale -1). Throws on failure.
void WritePfm(const std::string& path, const cv::Mat& image);

/// Left-right consistency of two ground-truth maps: 255 where the left disparity d at (x, y) is
/// known, x - d lands inside the right image, and the right disparity there agrees within
/// `tolerance_px`; 0 elsewhere.
cv::Mat LeftRightConsistentMask(const cv::Mat& left_disparity, const cv::Mat& right_disparity,
                                double tolerance_px = 1.0);

}  // namespace hnnstereo::vision
