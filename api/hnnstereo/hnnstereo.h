#pragma once
// hnnstereo as a library: the one header a user includes (installed as <hnnstereo/hnnstereo.h>,
// target hnnstereo::hnnstereo of find_package(hnnstereo CONFIG)).
//
// The facade exposes only std types, cv::Mat and Eigen matrices; the option structs, the OpenCL
// runtime and the engines stay behind a pimpl, so the internal headers are not installed and a
// user never learns which in-class default differs from the CLI's preset: a Matcher is a preset
// name plus overrides named like the CLI's flags, resolved by the same code as `hnnstereo match`
// (ResolveMatcherSettings in api/matcher_settings.h), so the two give the same matches.
//
//   hnnstereo::Matcher matcher;  // preset "hnn-default", OpenCL device from the environment
//   cv::Mat left = cv::imread("im2.png"), right = cv::imread("im6.png");
//   hnnstereo::MatchResult result = matcher.Match(left, right, 64);  // rectified pair
//   for (const hnnstereo::Match& m : result.matches) use(m.xl, m.yl, m.xr, m.yr, m.confidence);
//
// Errors: bad input throws std::invalid_argument, a failed match (no features, no candidates,
// over the memory budget...) std::runtime_error; the message is the CLI's one-line reason.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#if defined(__GNUC__) || defined(__clang__)
#define HNNSTEREO_API __attribute__((visibility("default")))
#else
#define HNNSTEREO_API
#endif

namespace hnnstereo {

/// The library version, "MAJOR.MINOR.PATCH" (the CMake project version).
HNNSTEREO_API const char* Version();

/// One accepted match (a row of MATCHES.csv): pixel coordinates of the images as given, 0-based,
/// a pixel's centre at integer coordinates, sub-pixel allowed.
struct Match {
  float xl = 0, yl = 0;    ///< left image point (px)
  float xr = 0, yr = 0;    ///< right image point (px)
  float activation = 0;    ///< the winning neuron's final output V in [0, 1] (saturates near 1)
  float confidence = 0;    ///< in [0, 1], higher = more likely correct; ranks matches
};

/// Milliseconds per stage; `total` excludes image loading (as REPORT.json's timing_ms).
struct MatchTiming {
  double features = 0, candidates = 0, weights = 0, solve = 0, decode = 0, total = 0;
};

/// What the match did: the main figures of REPORT.json, and the whole object as JSON text.
struct MatchReport {
  std::string engine;   ///< engine that ran: "opencl", "cpu" or "thesis"
  std::string device;   ///< "<device> (<platform>)" for opencl, else "cpu"
  std::string preset;   ///< the preset the settings came from
  std::string notice;   ///< e.g. why the opencl engine fell back to cpu; empty when none
  int n_left = 0, n_right = 0, n_neurons = 0;
  std::int64_t n_connections = 0;
  int iterations = 0;
  double energy_initial = 0, energy_final = 0;
  MatchTiming timing_ms;
  /// The REPORT.json object of `hnnstereo match --report` (same keys, minus the file names
  /// "left" and "right"), as JSON text.
  std::string json;
};

struct MatchResult {
  std::vector<Match> matches;  ///< one element per accepted match
  MatchReport report;
};

/// Overrides of a preset's settings, named like the `hnnstereo match` flags without the dashes,
/// values as on the command line: {"max-features", "1500"}, {"engine", "cpu"}, {"device", "1"},
/// {"top-k", "8"}, {"no-lr-check", "true"}... MatcherOptionNames() lists them; an unknown name or
/// a bad value throws std::invalid_argument naming it.
using MatcherOverrides = std::map<std::string, std::string>;

/// The override names a Matcher accepts.
HNNSTEREO_API std::vector<std::string> MatcherOptionNames();
/// The preset names ("hnn-default" first).
HNNSTEREO_API std::vector<std::string> PresetNames();

/// A stereo calibration (CAL.yml or a Middlebury calib.txt): world frame in mm, table z = 0.
/// Cheap to copy (shared, immutable).
class HNNSTEREO_API Calibration {
 public:
  Calibration();  ///< empty(): no calibration
  bool empty() const;
  Eigen::Matrix<double, 3, 4> P1() const;  ///< left camera, x1 ~ P1 X
  Eigen::Matrix<double, 3, 4> P2() const;  ///< right camera, x2 ~ P2 X
  Eigen::Matrix3d F() const;               ///< x2^T F x1 = 0
  Eigen::Vector3d C1() const;              ///< left camera centre (world, mm)
  Eigen::Vector3d C2() const;              ///< right camera centre (world, mm)
  int image_width() const;                 ///< 0 when the file does not say
  int image_height() const;
  bool rectified() const;                  ///< epipolar lines are image rows
  bool has_distortion() const;             ///< lens distortion (chessboard calibration)

 private:
  struct Impl;
  friend struct CalibrationAccess;
  std::shared_ptr<const Impl> impl_;
};

/// Reads a CAL.yml (OpenCV FileStorage YAML) or a Middlebury calib.txt. Throws
/// std::runtime_error with a one-line reason on a missing, unreadable or invalid file.
HNNSTEREO_API Calibration LoadCalibration(const std::string& path);

/// The stereo matcher: features -> candidates -> Hopfield network -> decoded, refined matches.
///
/// Thread safety: a Matcher holds one OpenCL context and queue; call it from one thread at a
/// time (calls on one Matcher from several threads must be serialised by the caller). Separate
/// Matchers are independent and may run concurrently.
class HNNSTEREO_API Matcher {
 public:
  /// Preset "hnn-default"; the OpenCL device from the environment (HNNSTEREO_OPENCL_PLATFORM,
  /// HNNSTEREO_OPENCL_DEVICE), else the first GPU, else the first device; with no OpenCL
  /// platform, the cpu engine and a notice (on stderr once, and in every report).
  Matcher();
  /// A named preset (PresetNames()) and overrides (MatcherOptionNames(); "device" picks the
  /// OpenCL device by index or name substring, "engine" opencl|cpu|thesis). Throws
  /// std::invalid_argument for an unknown preset, option or a bad value.
  explicit Matcher(const std::string& preset, const MatcherOverrides& overrides = {});
  ~Matcher();
  Matcher(Matcher&&) noexcept;
  Matcher& operator=(Matcher&&) noexcept;
  Matcher(const Matcher&) = delete;
  Matcher& operator=(const Matcher&) = delete;

  /// A rectified pair (epipolar lines are rows), disparities x_l - x_r in
  /// [min-disparity, max_disparity] px. Images: same size, 8/16-bit, grey or BGR(A) as
  /// cv::imread gives them.
  MatchResult Match(const cv::Mat& left, const cv::Mat& right, double max_disparity);
  /// A calibrated pair: gated by F (rows when the calibration is rectified); with lens
  /// distortion, matched on undistorted images and reported in the pixels as given.
  MatchResult Match(const cv::Mat& left, const cv::Mat& right, const Calibration& calibration);

  const std::string& preset() const;
  /// The OpenCL device in use, or "cpu" (no OpenCL, or engine cpu/thesis).
  std::string device() const;
  /// Why the opencl engine is not used (empty when it is, or was not asked for).
  std::string notice() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A part on the table (an OBJECTS.json object), world frame of the calibration, mm.
struct SensedObject {
  int id = 0;                                           ///< 1.., tallest first
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();   ///< centre of the top face
  double height = 0;                                    ///< top face above the table
  double yaw_deg = 0;                                   ///< top face orientation, (-90, 90]
  int points = 0;                                       ///< triangulated points of the part
};

struct SensingResult {
  std::vector<SensedObject> objects;  ///< tallest first
  std::string json;                   ///< the OBJECTS.json object of `hnnstereo pick`, as text
  std::string notice;                 ///< e.g. the cpu fallback
};

/// The pick pipeline of `hnnstereo pick` with its defaults: match the calibrated pair,
/// triangulate, cluster, estimate each part's pose. `overrides` as for Matcher (matcher flags
/// only). Opens the OpenCL device per call; throws as Matcher::Match does.
HNNSTEREO_API SensingResult SensePositions(const cv::Mat& left, const cv::Mat& right,
                                           const Calibration& calibration,
                                           const MatcherOverrides& overrides = {});

}  // namespace hnnstereo
