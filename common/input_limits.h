#pragma once
// Limits on what the project reads from files a person or another program wrote (CAL.yml,
// FRAME.yml, Middlebury calib.txt, target.yml, points files, --config files, images, PFM): a file
// from a broken or hostile source is refused with a one-line reason before it costs memory or
// time, and a number that cannot be meant (NaN, infinity, a coordinate of 10^300 mm) never
// reaches the geometry.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace hnnstereo::calib {

/// The limits on text input files. The defaults are far above any real file of the project (a
/// CAL.yml is ~2 kB, a points file of 1000 points ~40 kB) and far below what would hurt.
struct TextInputLimits {
  /// Largest text file read into memory, bytes. 16 MiB: 400x the largest real points file.
  std::uintmax_t max_file_bytes = std::uintmax_t{16} << 20;
  /// Largest magnitude of a coordinate or length, mm (world points, target poses, workspace
  /// bounds). 10^7 mm = 10 km: no pick cell is larger, and squares of it stay exact enough in
  /// double for the DLT's normal equations.
  double max_abs_mm = 1e7;
  /// Largest image width or height a calibration may name, pixels (matches ImageLimits).
  int max_image_side_px = 65536;

  /// Empty when the limits themselves are usable, else a readable reason.
  std::string Check() const;
};

/// The limits on image files (camera images, target images, ground truth). Checked on the file's
/// size and on the width and height its header states, before any pixel is decoded, so that a
/// decompression bomb (a small PNG that inflates to gigabytes) or a forged header costs nothing.
struct ImageLimits {
  /// Largest image file, bytes. 256 MiB: a 16-bit colour 8192 x 8192 TIFF stored raw is 384 MiB
  /// but every camera image of the project is a few MB; raise it for raw scientific images.
  std::uintmax_t max_file_bytes = std::uintmax_t{256} << 20;
  /// Largest width or height, pixels (OpenCV's own limit is 2^20).
  int max_side_px = 65536;
  /// Most pixels (width x height): bounds the decoded memory, ~0.5 GB for a 16-bit colour image
  /// of 64 Mpx and its double-precision grey conversion. 2^26 = 67,108,864 (8192 x 8192).
  std::int64_t max_pixels = std::int64_t{1} << 26;
  /// Smallest width or height, pixels: below 16 px no 7 x 7 correlation window plus the feature
  /// detectors' borders fits, and a 1 x 1 "image" is a broken export, not a camera frame.
  int min_side_px = 16;

  /// Empty when the limits themselves are usable, else a readable reason.
  std::string Check() const;
};

/// Width and height stated by the header of an encoded image (PNG, JPEG, BMP, PNM/PAM, TIFF), read
/// without decoding; false for other formats or a header too short to say.
bool ReadImageHeaderSize(const std::vector<unsigned char>& encoded, int* width, int* height);

/// Reads and decodes the image file `path` with cv::imdecode `flags` (e.g. cv::IMREAD_UNCHANGED),
/// within `limits`. Throws std::runtime_error with one line naming the file: missing, a
/// directory, empty, larger than the limits (file size or header size, checked before decoding),
/// smaller than min_side_px, or unreadable. What the codec libraries print while decoding (libpng,
/// libjpeg, libtiff) goes into that line instead of onto stderr before it.
cv::Mat ReadImageFileWithin(const std::string& path, int flags, const ImageLimits& limits = {});

/// Empty when the OpenCV FileStorage node `node` is a matrix or list of at most `max_elements`
/// numbers, else a reason. Call before `node >> cv::Mat`: OpenCV allocates rows x cols x channels
/// from the header before it looks at the data, so a 1 kB CAL.yml claiming "rows: 100000,
/// cols: 100000" asks for 80 GB (found by fuzz_cal_yml).
std::string CheckMatrixNode(const cv::FileNode& node, std::size_t max_elements);

/// Empty when `text` (a whole CAL.yml, target.yml or FRAME.yml) may be handed to
/// cv::FileStorage as YAML, else a reason. OpenCV 4.6's parsers fail on two kinds of text
/// (found by fuzz_frame_yml; CAL.yml and target.yml failed on the same inputs):
///  - OpenCV picks its parser from the first bytes whatever format flag it is given, and its XML
///    parser dereferences a null pointer on a text that ends inside its header ("<?xml version=").
///    Text OpenCV would read as XML is refused.
///  - After the first YAML document OpenCV skips three characters (a "---" or "..." marker) and
///    loops forever when it then stands on a '-' that does not start "---" (a document whose top
///    level ends before the end of the text: an indented top level, or "...-"). The project's
///    files are one document whose top level is a block map from column 1, as OpenCV writes
///    them: only comments, directives ('%') and one "---" may come before the first key, the first
///    key starts in column 1 with a letter, digit or '_', and no line starts with "...".
/// NUL bytes are refused too (OpenCV would stop reading at the first).
std::string CheckYamlText(const std::string& text);

/// Reads the whole text file `path` (named `what` in messages, e.g. "calibration file").
/// Throws std::runtime_error with one line when it does not exist, is not a regular file, is
/// larger than `limits.max_file_bytes` or cannot be read.
std::string ReadTextFileWithin(const std::string& path, const std::string& what,
                               const TextInputLimits& limits = {});

/// Parses a whole decimal integer ("640", "-3"; no trailing text, no fraction) within
/// [min_value, max_value] into `*value`; false otherwise. Unlike std::atoi it never has
/// undefined behaviour on overflow.
bool ParseIntWithin(const std::string& text, long long min_value, long long max_value,
                    long long* value);

}  // namespace hnnstereo::calib
