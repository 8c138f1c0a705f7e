#include "common/input_limits.h"

#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace hnnstereo::calib {

namespace {

std::uint32_t BigEndian32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}
std::uint32_t Read16(const unsigned char* p, bool little_endian) {
  return little_endian ? (std::uint32_t{p[1]} << 8 | p[0]) : (std::uint32_t{p[0]} << 8 | p[1]);
}
std::uint32_t Read32(const unsigned char* p, bool little_endian) {
  return little_endian ? (Read16(p + 2, true) << 16 | Read16(p, true))
                       : (Read16(p, false) << 16 | Read16(p + 2, false));
}

// Sizes above INT_MAX are reported as INT_MAX: over every limit, and no overflow on the way.
int ClampSide(std::uint64_t side) { return side > 0x7fffffffu ? 0x7fffffff : static_cast<int>(side); }

bool PngSize(const std::vector<unsigned char>& b, int* width, int* height) {
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  // Signature, then the IHDR chunk (length, "IHDR", width, height), always first (PNG spec 5.6).
  if (b.size() < 24 || !std::equal(kSignature, kSignature + 8, b.begin())) return false;
  if (b[12] != 'I' || b[13] != 'H' || b[14] != 'D' || b[15] != 'R') return false;
  *width = ClampSide(BigEndian32(&b[16]));
  *height = ClampSide(BigEndian32(&b[20]));
  return true;
}

bool JpegSize(const std::vector<unsigned char>& b, int* width, int* height) {
  if (b.size() < 4 || b[0] != 0xFF || b[1] != 0xD8) return false;
  std::size_t at = 2;
  while (at + 4 <= b.size()) {
    if (b[at] != 0xFF) return false;
    const unsigned char marker = b[at + 1];
    if (marker == 0xFF) {  // fill byte
      ++at;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length field
      at += 2;
      continue;
    }
    const std::size_t length = Read16(&b[at + 2], false);
    if (length < 2) return false;
    // Start of frame: SOF0..SOF15 without DHT (C4), JPG (C8) and DAC (CC).
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
      if (at + 9 > b.size()) return false;
      *height = static_cast<int>(Read16(&b[at + 5], false));
      *width = static_cast<int>(Read16(&b[at + 7], false));
      return true;
    }
    if (marker == 0xDA || marker == 0xD9) return false;  // scan data before any frame header
    at += 2 + length;
  }
  return false;
}

bool BmpSize(const std::vector<unsigned char>& b, int* width, int* height) {
  if (b.size() < 26 || b[0] != 'B' || b[1] != 'M') return false;
  const std::uint32_t header_size = Read32(&b[14], true);
  if (header_size == 12) {  // BITMAPCOREHEADER: 16-bit sizes
    *width = static_cast<int>(Read16(&b[18], true));
    *height = static_cast<int>(Read16(&b[20], true));
    return true;
  }
  // Signed 32-bit; a negative height means top-down rows.
  const auto w = static_cast<std::int32_t>(Read32(&b[18], true));
  const auto h = static_cast<std::int32_t>(Read32(&b[22], true));
  *width = ClampSide(static_cast<std::uint64_t>(std::llabs(w)));
  *height = ClampSide(static_cast<std::uint64_t>(std::llabs(h)));
  return true;
}

// PBM/PGM/PPM (P1..P6): magic, then width and height as decimal text, '#' comments between.
// PAM (P7): "WIDTH w" and "HEIGHT h" lines.
bool PnmSize(const std::vector<unsigned char>& b, int* width, int* height) {
  if (b.size() < 3 || b[0] != 'P' || b[1] < '1' || b[1] > '7') return false;
  const std::string head(b.begin(), b.begin() + static_cast<long>(std::min<std::size_t>(b.size(), 4096)));
  std::istringstream in(head.substr(2));
  auto next_token = [&in](std::string* token) {
    while (in >> *token) {
      if ((*token)[0] != '#') return true;
      std::string rest;
      std::getline(in, rest);  // the rest of a comment line
    }
    return false;
  };
  auto to_side = [](const std::string& token, int* side) {
    long long value = 0;
    if (!ParseIntWithin(token, 0, 0x7fffffff, &value)) return false;
    *side = static_cast<int>(value);
    return true;
  };
  std::string token;
  if (b[1] == '7') {
    bool have_width = false, have_height = false;
    while (next_token(&token) && token != "ENDHDR") {
      std::string value;
      if (token == "WIDTH" && next_token(&value)) have_width = to_side(value, width);
      if (token == "HEIGHT" && next_token(&value)) have_height = to_side(value, height);
    }
    return have_width && have_height;
  }
  std::string second;
  return next_token(&token) && to_side(token, width) && next_token(&second) &&
         to_side(second, height);
}

// TIFF: the first image file directory's ImageWidth (256) and ImageLength (257) entries.
bool TiffSize(const std::vector<unsigned char>& b, int* width, int* height) {
  if (b.size() < 8) return false;
  bool little_endian = false;
  if (b[0] == 'I' && b[1] == 'I') {
    little_endian = true;
  } else if (!(b[0] == 'M' && b[1] == 'M')) {
    return false;
  }
  if (Read16(&b[2], little_endian) != 42) return false;  // 43 = BigTIFF: not read here
  const std::uint64_t ifd = Read32(&b[4], little_endian);
  if (ifd + 2 > b.size()) return false;
  const std::uint32_t entries = Read16(&b[ifd], little_endian);
  bool have_width = false, have_height = false;
  for (std::uint32_t e = 0; e < entries; ++e) {
    const std::uint64_t at = ifd + 2 + 12ull * e;
    if (at + 12 > b.size()) return false;
    const std::uint32_t tag = Read16(&b[at], little_endian);
    const std::uint32_t type = Read16(&b[at + 2], little_endian);
    if (tag != 256 && tag != 257) continue;
    std::uint64_t value = 0;
    if (type == 3) {  // SHORT
      value = Read16(&b[at + 8], little_endian);
    } else if (type == 4) {  // LONG
      value = Read32(&b[at + 8], little_endian);
    } else {
      return false;
    }
    if (tag == 256) *width = ClampSide(value), have_width = true;
    if (tag == 257) *height = ClampSide(value), have_height = true;
  }
  return have_width && have_height;
}

// Captures what is written to file descriptor 2 while it lives (libpng, libjpeg and OpenCV's
// codecs print their complaints there, before the caller could say anything). One capture at a
// time in the process; output of other threads in that window is captured too and handed back by
// Release().
class StderrCapture {
 public:
  StderrCapture() : lock_(Mutex()) {
    std::fflush(stderr);
    std::cerr.flush();
    file_ = std::tmpfile();
    if (file_ == nullptr) return;
    saved_ = ::dup(2);
    if (saved_ < 0 || ::dup2(::fileno(file_), 2) < 0) {
      if (saved_ >= 0) ::close(saved_);
      saved_ = -1;
      std::fclose(file_);
      file_ = nullptr;
    }
  }
  StderrCapture(const StderrCapture&) = delete;
  StderrCapture& operator=(const StderrCapture&) = delete;
  ~StderrCapture() { Release(); }

  /// Restores stderr and returns what was written meanwhile.
  std::string Release() {
    if (file_ == nullptr) return {};
    std::fflush(stderr);
    std::cerr.flush();
    ::dup2(saved_, 2);
    ::close(saved_);
    std::string text;
    std::rewind(file_);
    char chunk[4096];
    std::size_t got = 0;
    while ((got = std::fread(chunk, 1, sizeof chunk, file_)) > 0 && text.size() < (1u << 20)) {
      text.append(chunk, got);
    }
    std::fclose(file_);
    file_ = nullptr;
    return text;
  }

 private:
  static std::mutex& Mutex() {
    static std::mutex mutex;
    return mutex;
  }
  std::lock_guard<std::mutex> lock_;
  std::FILE* file_ = nullptr;
  int saved_ = -1;
};

// The first line of a library's complaint, trimmed, for a one-line message.
std::string FirstLine(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
  if (line.size() > 200) line = line.substr(0, 200) + "...";
  return line;
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

std::string ImageLimits::Check() const {
  if (max_file_bytes == 0) return "ImageLimits.max_file_bytes must be > 0";
  if (min_side_px < 1) return "ImageLimits.min_side_px must be >= 1";
  if (max_side_px < min_side_px) return "ImageLimits.max_side_px must be >= min_side_px";
  if (max_pixels < std::int64_t{min_side_px} * min_side_px) {
    return "ImageLimits.max_pixels must be >= min_side_px^2";
  }
  return {};
}

bool ReadImageHeaderSize(const std::vector<unsigned char>& encoded, int* width, int* height) {
  return PngSize(encoded, width, height) || JpegSize(encoded, width, height) ||
         BmpSize(encoded, width, height) || PnmSize(encoded, width, height) ||
         TiffSize(encoded, width, height);
}

cv::Mat ReadImageFileWithin(const std::string& path, int flags, const ImageLimits& limits) {
  if (const std::string problem = limits.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::exists(path, error)) throw std::runtime_error("image '" + path + "' does not exist");
  if (fs::is_directory(path, error)) {
    throw std::runtime_error("image '" + path + "' is a directory, not an image file");
  }
  const std::uintmax_t bytes = fs::file_size(path, error);
  if (error) throw std::runtime_error("image '" + path + "' cannot be read: " + error.message());
  if (bytes == 0) throw std::runtime_error("image '" + path + "' is empty (0 bytes)");
  if (bytes > limits.max_file_bytes) {
    throw std::runtime_error("image '" + path + "' is " + std::to_string(bytes) +
                             " bytes, more than the limit of " +
                             std::to_string(limits.max_file_bytes) + " (ImageLimits.max_file_bytes)");
  }
  std::vector<unsigned char> encoded(static_cast<std::size_t>(bytes));
  {
    std::ifstream file(path, std::ios::binary);
    if (!file.read(reinterpret_cast<char*>(encoded.data()), static_cast<std::streamsize>(bytes))) {
      throw std::runtime_error("image '" + path + "' cannot be read");
    }
  }
  auto check_size = [&](int width, int height, const char* source) {
    if (width > limits.max_side_px || height > limits.max_side_px ||
        std::int64_t{width} * height > limits.max_pixels) {
      throw std::runtime_error("image '" + path + "' is " + SizeText(width, height) + " pixels " +
                               source + ", beyond the limits of " +
                               std::to_string(limits.max_side_px) + " px per side and " +
                               std::to_string(limits.max_pixels) + " pixels (ImageLimits)");
    }
    if (width < limits.min_side_px || height < limits.min_side_px) {
      throw std::runtime_error("image '" + path + "' is " + SizeText(width, height) + " pixels " +
                               source + ", smaller than the minimum of " +
                               std::to_string(limits.min_side_px) + " px per side (ImageLimits)");
    }
  };
  // DICOM ("DICM" after a 128-byte preamble) is refused before decoding: OpenCV hands it to GDCM,
  // whose reader asserts on a malformed file and aborts the process (Debian's libgdcm 3.0 keeps
  // its asserts; a 132-byte file found by fuzz_image_loader). A pick cell's cameras write none.
  if (encoded.size() >= 132 && std::equal(encoded.begin() + 128, encoded.begin() + 132,
                                          reinterpret_cast<const unsigned char*>("DICM"))) {
    throw std::runtime_error("image '" + path + "' is a DICOM file; DICOM is not read (PNG, "
                             "JPEG, BMP, PNM, TIFF and the other common formats are)");
  }
  int width = 0, height = 0;
  if (ReadImageHeaderSize(encoded, &width, &height)) check_size(width, height, "by its header");

  cv::Mat image;
  std::string complaint;
  {
    StderrCapture capture;
    try {
      image = cv::imdecode(encoded, flags);
    } catch (const cv::Exception& e) {
      image.release();  // a codec that throws on a corrupt file: same answer as unreadable
      complaint = e.err;
    }
    const std::string printed = capture.Release();
    if (complaint.empty()) complaint = FirstLine(printed);
    // A decoded image: what was printed was a warning (or another thread's output), not our
    // error; hand it on unchanged.
    if (!image.empty() && !printed.empty()) std::cerr << printed << std::flush;
  }
  if (image.empty()) {
    throw std::runtime_error("image '" + path +
                             "' cannot be read (not an image or unsupported format)" +
                             (complaint.empty() ? std::string() : ": " + FirstLine(complaint)));
  }
  check_size(image.cols, image.rows, "decoded");  // formats whose header is not read above
  return image;
}

std::string CheckMatrixNode(const cv::FileNode& node, std::size_t max_elements) {
  if (node.empty()) return {};
  if (node.isSeq()) {
    return node.size() <= max_elements ? std::string()
                                       : "has " + std::to_string(node.size()) + " numbers, more than " +
                                             std::to_string(max_elements);
  }
  if (!node.isMap()) return node.isInt() || node.isReal() ? std::string() : "is not a matrix";
  const cv::FileNode rows = node["rows"], cols = node["cols"], type = node["dt"];
  if (!rows.isInt() || !cols.isInt() || !type.isString()) {
    return "is not a matrix (rows, cols and dt missing or not whole numbers)";
  }
  // dt: an optional channel count, then the element type ("d", "3f").
  const std::string dt = static_cast<std::string>(type);
  long long channels = 1;
  std::size_t digits = 0;
  while (digits < dt.size() && digits < 4 && dt[digits] >= '0' && dt[digits] <= '9') ++digits;
  if (digits > 0 && !ParseIntWithin(dt.substr(0, digits), 1, 512, &channels)) {
    return "has a bad element type '" + dt + "'";
  }
  const long long row_count = static_cast<int>(rows), col_count = static_cast<int>(cols);
  if (row_count < 0 || col_count < 0 ||
      static_cast<unsigned long long>(row_count) * static_cast<unsigned long long>(col_count) *
              static_cast<unsigned long long>(channels) >
          max_elements) {
    return "claims " + std::to_string(row_count) + "x" + std::to_string(col_count) +
           " elements, more than " + std::to_string(max_elements);
  }
  return {};
}

std::string TextInputLimits::Check() const {
  if (max_file_bytes == 0) return "TextInputLimits.max_file_bytes must be > 0";
  if (!(max_abs_mm > 0.0) || !std::isfinite(max_abs_mm)) {
    return "TextInputLimits.max_abs_mm must be a finite number > 0";
  }
  if (max_image_side_px <= 0) return "TextInputLimits.max_image_side_px must be > 0";
  return {};
}

std::string CheckYamlText(const std::string& text) {
  if (text.find('\0') != std::string::npos) return "contains a NUL byte; only YAML text is read";
  // cv::FileStorage skips a UTF-8 byte order mark, then reads "<?xml" as XML.
  const std::size_t start = text.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0;
  if (text.compare(start, 5, "<?xml") == 0) return "is XML; only OpenCV YAML is read";
  bool before_first_key = true;
  bool dashes_seen = false;
  int number = 0;
  for (std::size_t at = start; at < text.size();) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    std::string line = text.substr(at, end - at);
    at = end + 1;
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = "line " + std::to_string(number) + ": ";
    if (!before_first_key) {
      if (line.rfind("...", 0) == 0) return where + "'...' ends the YAML document; only one is read";
      continue;
    }
    const std::size_t first = line.find_first_not_of(' ');
    if (first == std::string::npos || line[first] == '#' || line[first] == '%') continue;
    if (!dashes_seen && line.compare(first, 3, "---") == 0 &&
        line.find_first_not_of(' ', first + 3) == std::string::npos) {
      dashes_seen = true;
      continue;
    }
    const unsigned char c = static_cast<unsigned char>(line[0]);
    if (first != 0 || !(std::isalnum(c) || c == '_')) {
      return where + "the top level must be a map whose keys start in column 1 (OpenCV YAML)";
    }
    before_first_key = false;
  }
  return {};
}

std::string ReadTextFileWithin(const std::string& path, const std::string& what,
                               const TextInputLimits& limits) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::exists(path, error)) throw std::runtime_error(what + " '" + path + "' does not exist");
  if (!fs::is_regular_file(path, error)) {
    throw std::runtime_error(what + " '" + path + "' is not a regular file");
  }
  const std::uintmax_t bytes = fs::file_size(path, error);
  if (error) throw std::runtime_error(what + " '" + path + "' cannot be read: " + error.message());
  if (bytes > limits.max_file_bytes) {
    throw std::runtime_error(what + " '" + path + "' is " + std::to_string(bytes) +
                             " bytes, more than the limit of " +
                             std::to_string(limits.max_file_bytes) + " for a text input file");
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error(what + " '" + path + "' cannot be read");
  std::ostringstream buffer;
  buffer << file.rdbuf();
  if (file.bad()) throw std::runtime_error(what + " '" + path + "' cannot be read");
  std::string text = buffer.str();
  // A file that grew after the size check (a writer still busy) is still held to the limit.
  if (text.size() > limits.max_file_bytes) {
    throw std::runtime_error(what + " '" + path + "' is larger than the limit of " +
                             std::to_string(limits.max_file_bytes) + " bytes");
  }
  return text;
}

bool ParseIntWithin(const std::string& text, long long min_value, long long max_value,
                    long long* value) {
  std::size_t begin = text.find_first_not_of(" \t\r\n");
  std::size_t end = text.find_last_not_of(" \t\r\n");
  if (begin == std::string::npos) return false;
  const std::string trimmed = text.substr(begin, end - begin + 1);
  char* stop = nullptr;
  errno = 0;
  const long long parsed = std::strtoll(trimmed.c_str(), &stop, 10);
  if (stop == trimmed.c_str() || *stop != '\0' || errno == ERANGE) return false;
  if (parsed < min_value || parsed > max_value) return false;
  *value = parsed;
  return true;
}

}  // namespace hnnstereo::calib
