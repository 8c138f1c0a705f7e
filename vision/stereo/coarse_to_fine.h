#pragma once
// Coarse-to-fine matching of camera-sized rectified pairs (feature-vs-disparity network): the
// pair is first matched at half size (itself coarse-to-fine while still large), and each
// full-size left feature then searches only a band of disparity levels around the coarse matches
// near it. The support-point idea of ELAS (Geiger, Roser & Urtasun, "Efficient Large-Scale
// Stereo Matching", ACCV 2010), with the Hopfield network as the matcher at every level: the
// candidates, the network and the left-right check then cost per feature what they cost on a
// small pair, whatever the image size and disparity range.

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "vision/stereo/candidates.h"

namespace hnnstereo::ocl {
class Runtime;
}

namespace hnnstereo::vision {

struct MatcherOptions;

struct CoarseToFineOptions {
  /// Rectified pairs of more megapixels than this are matched coarse-to-fine (0 = never). The
  /// default leaves every pair up to 0.5 megapixels (the Middlebury and ETH3D pairs, the
  /// 640 x 480 cell) matched in one pass over the whole disparity range.
  double min_megapixels = 0.5;
  /// The half-size match detects at most this share of the full-size left features (at least
  /// 1,000; spread over the image, FeatureOptions::max_features): the bands need support near
  /// every feature, not a match for every coarse edge pixel (docs/decisions.md).
  double coarse_feature_share = 0.125;
  /// A band reaches this many levels beyond the disparities of the coarse matches that back it
  /// (each side): a coarse match's disparity, doubled, is within about 2 levels of the fine one.
  int band_margin = 3;
  /// Half-sides (coarse pixels) of the squares around a feature's coarse position whose coarse
  /// matches give its band, tried in turn until one holds a match; a feature with none in the
  /// last searches the whole range.
  std::array<int, 3> support_half_sides = {2, 6, 24};
  std::string Check() const;
};

/// What the coarse level chose, for REPORT.json ("coarse_to_fine").
struct CoarseToFineReport {
  bool applied = false;
  int levels = 0;                 ///< halvings above this level (1: matched once at half size)
  cv::Size coarse_size;           ///< the half-size pair's
  int coarse_matches = 0;         ///< left-right checked matches of the half-size pair
  double mean_band_levels = 0.0;  ///< disparity levels a full-size feature searches, on average
  int features_whole_range = 0;   ///< features no coarse match backs: they search every level
  double ms = 0.0;                ///< the half-size match and the bands
};

/// Whether MatchStereo matches this pair coarse-to-fine.
bool CoarseToFineApplies(const MatcherOptions& options, cv::Size image_size);

/// Per left feature of the full-size pair, bands of disparity levels (clipped to the options'
/// range): `search`, the levels its candidates come from (the coarse matches in the smallest
/// square that holds one); `check`, the levels the left-right check searches back over (those in
/// the largest square: an occluding surface up to 2 x 24 px away is still found).
struct CoarseBands {
  std::vector<DisparityBand> search, check;
};

/// Matches the half-size pair (MatchStereo, recursively coarse-to-fine, then a left-right check
/// and the sub-pixel fit) and returns each left feature's bands.
CoarseBands CoarseDisparityBands(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                                const std::vector<Eigen::Vector2f>& left_points,
                                                const MatcherOptions& options, ocl::Runtime* runtime,
                                                CoarseToFineReport* report);

}  // namespace hnnstereo::vision
