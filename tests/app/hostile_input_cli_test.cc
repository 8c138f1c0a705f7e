// Hostile and absurd input files through the command line: each is refused with one line
// "hnnstereo: error: ..." and the CLI's error exit status, with no library noise (libpng...)
// before it, no crash and no output file. The hostile files are made here at run time (the
// decompression bomb is 400 kB; nothing large is committed).

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "cli_runner.h"

namespace hnnstereo::testing {
namespace {

namespace fs = std::filesystem;

const std::string kTeddyLeft = kTeddyDir + "/im2.png";
const std::string kTeddyRight = kTeddyDir + "/im6.png";

void Append32(std::string* out, std::uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<char>(value >> shift));
}

void AppendChunk(std::string* png, const std::string& type, const std::string& data) {
  Append32(png, static_cast<std::uint32_t>(data.size()));
  const std::string body = type + data;
  png->append(body);
  Append32(png, static_cast<std::uint32_t>(
                    crc32(0, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()))));
}

// A grey 8-bit PNG of `width` x `height` whose rows are all zero, compressed row by row so that
// the bomb never exists inflated in this process either.
// The PNG signature and its IHDR chunk: what a reader sees of the size before any pixel.
std::string PngHeader(std::uint32_t width, std::uint32_t height) {
  std::string png = "\x89PNG\r\n\x1a\n";
  std::string ihdr;
  Append32(&ihdr, width);
  Append32(&ihdr, height);
  ihdr += std::string("\x08\x00\x00\x00\x00", 5);  // 8 bit, grey, deflate, no filter, no interlace
  AppendChunk(&png, "IHDR", ihdr);
  return png;
}

std::string ZeroPng(std::uint32_t width, std::uint32_t height) {
  std::string png = PngHeader(width, height);
  z_stream stream{};
  EXPECT_EQ(deflateInit(&stream, 9), Z_OK);
  const std::vector<unsigned char> row(width + 1, 0);  // filter byte + pixels
  std::vector<unsigned char> out(1 << 16);
  std::string idat;
  for (std::uint32_t y = 0; y <= height; ++y) {
    const bool last = y == height;
    stream.next_in = const_cast<unsigned char*>(row.data());
    stream.avail_in = last ? 0 : static_cast<uInt>(row.size());
    do {
      stream.next_out = out.data();
      stream.avail_out = static_cast<uInt>(out.size());
      deflate(&stream, last ? Z_FINISH : Z_NO_FLUSH);
      idat.append(reinterpret_cast<char*>(out.data()), out.size() - stream.avail_out);
    } while (stream.avail_out == 0);
  }
  deflateEnd(&stream);
  AppendChunk(&png, "IDAT", idat);
  AppendChunk(&png, "IEND", "");
  return png;
}

class HostileInputCli : public CliTest {
 protected:
  void WriteFile(const std::string& name, const std::string& contents) const {
    std::ofstream(Path(name), std::ios::binary) << contents;
  }
  // One line "hnnstereo: error: ..." containing `reason`, exit status `code`, no output file.
  void ExpectRefused(const CliResult& result, int code, const std::string& reason) const {
    EXPECT_EQ(result.exit_code, code) << result.output;
    EXPECT_EQ(result.output.rfind("hnnstereo: error: ", 0), 0u) << result.output;
    EXPECT_NE(result.output.find(reason), std::string::npos) << result.output;
    EXPECT_EQ(std::count(result.output.begin(), result.output.end(), '\n'), 1) << result.output;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      EXPECT_EQ(entry.path().filename().string().rfind("input", 0), 0u)
          << "a refused command wrote " << entry.path();
    }
  }
  CliResult MatchLeft(const std::string& left) const {
    return RunCli("match --left " + left + " --right " + kTeddyRight + " --rectified --engine cpu --out " +
                  Path("m.csv"));
  }
  // A rectified pair's calibration in CAL.yml form; `extra` lines are appended.
  std::string CalYml(const std::string& extra) const {
    return "%YAML:1.0\n---\n"
           "P1: !!opencv-matrix\n   rows: 3\n   cols: 4\n   dt: d\n"
           "   data: [ 500., 0., 225., 0., 0., 500., 187., 0., 0., 0., 1., 0. ]\n"
           "P2: !!opencv-matrix\n   rows: 3\n   cols: 4\n   dt: d\n"
           "   data: [ 500., 0., 225., -50000., 0., 500., 187., 0., 0., 0., 1., 0. ]\n" +
           extra;
  }
  CliResult MatchWithCalib(const std::string& calib) const {
    return RunCli("match --left " + kTeddyLeft + " --right " + kTeddyRight + " --calib " + calib +
                  " --engine cpu --out " + Path("m.csv"));
  }
};

TEST_F(HostileInputCli, DecompressionBombIsRefusedFromItsHeaderBeforeDecoding) {
  // 20000 x 20000 grey = 400 Mpx (under OpenCV's own 2^30 limit): 391 kB on disk, 400 MB once
  // inflated. Before the limit it was decoded (7.7 s, 1.6 GB resident).
  WriteFile("input_bomb.png", ZeroPng(20000, 20000));
  ASSERT_LT(fs::file_size(Path("input_bomb.png")), 1u << 20);
  const auto start = std::chrono::steady_clock::now();
  const CliResult result = MatchLeft(Path("input_bomb.png"));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ExpectRefused(result, 2, "is 20000x20000 pixels by its header, beyond the limits");
  RecordProperty("refusal_seconds", std::to_string(seconds));
}

TEST_F(HostileInputCli, HundredThousandSquaredHeaderIsRefused) {
  WriteFile("input_huge.png", PngHeader(100000, 100000));
  ExpectRefused(MatchLeft(Path("input_huge.png")), 2, "100000x100000 pixels by its header");
  // The same claim in a JPEG frame header (65535 x 65535, the format's largest).
  const std::string jpeg = std::string("\xFF\xD8\xFF\xC0\x00\x0B\x08\xFF\xFF\xFF\xFF\x01\x01\x11\x00",
                                       15);
  WriteFile("input_huge.jpg", jpeg);
  ExpectRefused(MatchLeft(Path("input_huge.jpg")), 2, "65535x65535 pixels by its header");
}

TEST_F(HostileInputCli, OnePixelImageIsRefused) {
  ASSERT_TRUE(cv::imwrite(Path("input_one.png"), cv::Mat(1, 1, CV_8UC1, cv::Scalar(7))));
  ExpectRefused(MatchLeft(Path("input_one.png")), 2, "is 1x1 pixels by its header, smaller than");
  // A format whose header is not read before decoding is held to the same limits after it.
  ASSERT_TRUE(cv::imwrite(Path("input_thin.webp"), cv::Mat(4, 600, CV_8UC1, cv::Scalar(7))));
  ExpectRefused(MatchLeft(Path("input_thin.webp")), 2, "is 600x4 pixels decoded, smaller than");
}

TEST_F(HostileInputCli, MalformedDicomIsRefusedNotAnAbort) {
  // fuzz_image_loader: 132 bytes, a TIFF byte order mark, zeros, "DICM" at offset 128. OpenCV
  // gave it to GDCM, whose reader asserted (is.good()) and aborted the process with no message
  // (SIGABRT, exit 134).
  std::string dicom("II\0*P\0\xb8", 7);
  dicom.resize(126, '\0');
  dicom += "5\nDICM";
  ASSERT_EQ(dicom.size(), 132u);
  WriteFile("input_dicom.tif", dicom);
  ExpectRefused(MatchLeft(Path("input_dicom.tif")), 2, "is a DICOM file; DICOM is not read");
}

TEST_F(HostileInputCli, OversizedFileIsRefusedWithoutReadingIt) {
  // A sparse 300 MB file that starts like a PNG: refused on its size (limit 256 MiB).
  {
    std::ofstream out(Path("input_big.png"), std::ios::binary);
    out << ZeroPng(64, 64);
  }
  fs::resize_file(Path("input_big.png"), 300u << 20);
  ExpectRefused(MatchLeft(Path("input_big.png")), 2, "bytes, more than the limit of 268435456");
}

TEST_F(HostileInputCli, TruncatedPngGivesOneLineWithoutLibpngNoise) {
  std::vector<unsigned char> encoded;
  cv::Mat texture(64, 64, CV_8UC1);
  cv::randu(texture, 0, 255);
  ASSERT_TRUE(cv::imencode(".png", texture, encoded));
  WriteFile("input_cut.png", std::string(encoded.begin(), encoded.begin() + 80));
  const CliResult result = MatchLeft(Path("input_cut.png"));
  // libpng's own "libpng error: ..." line used to come first; now its text is in the one line.
  ExpectRefused(result, 2, "cannot be read (not an image or unsupported format)");
}

TEST_F(HostileInputCli, CalYmlNonFiniteAndAbsurdNumbersAreRefused) {
  WriteFile("input_width.yml", CalYml("image_width: 1.0e+300\nimage_height: 375\n"));
  ExpectRefused(MatchWithCalib(Path("input_width.yml")), 2,
                "'image_width' must be a whole number of pixels in [0, 65536]");
  WriteFile("input_nan_p.yml", CalYml("").replace(CalYml("").find("500."), 4, ".nan"));
  ExpectRefused(MatchWithCalib(Path("input_nan_p.yml")), 2, "non-finite");
  WriteFile("input_nan_k.yml",
            CalYml("K1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                   "   data: [ .nan, 0., 225., 0., 500., 187., 0., 0., 1. ]\n"
                   "K2: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                   "   data: [ 500., 0., 225., 0., 500., 187., 0., 0., 1. ]\n"));
  ExpectRefused(MatchWithCalib(Path("input_nan_k.yml")), 2, "intrinsics");
  // A matrix header claiming 100000 x 100000 doubles: OpenCV allocated the 80 GB before reading
  // the data (found by fuzz_cal_yml); now refused from the header.
  WriteFile("input_rows.yml",
            "%YAML:1.0\n---\nP1: !!opencv-matrix\n   rows: 100000\n   cols: 100000\n   dt: d\n"
            "   data: [ 1., 2. ]\n");
  ExpectRefused(MatchWithCalib(Path("input_rows.yml")), 2,
                "'P1' claims 100000x100000 elements, more than 12");
}

TEST_F(HostileInputCli, MiddleburyCalibTxtNonFiniteAndAbsurdNumbersAreRefused) {
  const std::string cams = "cam0=[500 0 225; 0 500 187; 0 0 1]\ncam1=[500 0 225; 0 500 187; 0 0 1]\n";
  WriteFile("input_nan.txt", cams + "baseline=nan\n");
  ExpectRefused(MatchWithCalib(Path("input_nan.txt")), 2, "'baseline' must be a finite non-zero");
  WriteFile("input_zero.txt", cams + "baseline=0\n");
  ExpectRefused(MatchWithCalib(Path("input_zero.txt")), 2, "'baseline' must be a finite non-zero");
  // std::atoi read this with undefined behaviour (overflow).
  WriteFile("input_wide.txt", cams + "baseline=100\nwidth=99999999999999\n");
  ExpectRefused(MatchWithCalib(Path("input_wide.txt")), 2, "'width' must be a whole number");
  WriteFile("input_inf.txt", "cam0=[inf 0 225; 0 500 187; 0 0 1]\n"
                             "cam1=[500 0 225; 0 500 187; 0 0 1]\nbaseline=100\n");
  ExpectRefused(MatchWithCalib(Path("input_inf.txt")), 2, "'cam0' is not a 3x3 matrix");
}

TEST_F(HostileInputCli, FrameYmlNonFiniteAndAbsurdNumbersAreRefused) {
  auto frame = [](const std::string& transform, const std::string& workspace_max) {
    return "%YAML:1.0\n---\nrobot_from_world: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n"
           "   data: [ " + transform + " ]\n"
           "workspace_min: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
           "   data: [ -1000., -1000., -100. ]\n"
           "workspace_max: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
           "   data: [ " + workspace_max + " ]\nrms_mm: 0.\n";
  };
  const std::string identity = "1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.";
  WriteFile("input_ok.yml", frame(identity, "1000., 1000., 1000."));
  ASSERT_EQ(RunCli("robot show-frame --frame " + Path("input_ok.yml")).exit_code, 0);
  WriteFile("input_nan.yml", frame("1., 0., 0., .nan, 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.",
                                   "1000., 1000., 1000."));
  ExpectRefused(RunCli("robot show-frame --frame " + Path("input_nan.yml")), 2, "not finite");
  WriteFile("input_inf.yml", frame(identity, "1000., .inf, 1000."));
  const CliResult infinite = RunCli("robot show-frame --frame " + Path("input_inf.yml"));
  EXPECT_EQ(infinite.exit_code, 2) << infinite.output;
  EXPECT_EQ(std::count(infinite.output.begin(), infinite.output.end(), '\n'), 1) << infinite.output;
}

TEST_F(HostileInputCli, PfmWithForgedHeaderOrAbsurdDisparityIsRefused) {
  // A Middlebury 2014 folder: im0/im1, calib.txt, disp0.pfm.
  fs::create_directories(Path("input_set"));
  fs::copy_file(kTeddyLeft, Path("input_set/im0.png"), fs::copy_options::overwrite_existing);
  fs::copy_file(kTeddyRight, Path("input_set/im1.png"), fs::copy_options::overwrite_existing);
  WriteFile("input_set/calib.txt", "cam0=[500 0 225; 0 500 187; 0 0 1]\n"
                                   "cam1=[500 0 225; 0 500 187; 0 0 1]\nbaseline=100\n"
                                   "width=450\nheight=375\nndisp=64\n");
  // Header claims 100000 x 100000 floats (40 GB) on a 20-byte file: no allocation, one line.
  WriteFile("input_set/disp0.pfm", "Pf\n100000 100000\n-1\n");
  // Unusable input, found before any work: a refused setup (exit 2).
  ExpectRefused(RunCli("eval --dataset " + Path("input_set") + " --out " + Path("eval.json")), 2,
                "is truncated: its header says 100000x100000");
  // A finite but absurd disparity (1e30 px in a 450 px wide image).
  std::string pfm = "Pf\n450 375\n-1\n";
  std::vector<float> values(450 * 375, 10.0f);
  values[1234] = 1e30f;
  pfm.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
  WriteFile("input_set/disp0.pfm", pfm);
  ExpectRefused(RunCli("eval --dataset " + Path("input_set") + " --out " + Path("eval.json")), 2,
                "outside [0, 450]");
}

TEST_F(HostileInputCli, ConfigYamlNonFiniteNumbersAreRefused) {
  auto match_with_config = [&](const std::string& name, const std::string& text) {
    WriteFile(name, text);
    return RunCli("match --left " + kTeddyLeft + " --right " + kTeddyRight +
                  " --rectified --engine cpu --out " + Path("m.csv") + " --config " + Path(name));
  };
  // inf used to become a budget of "0.0 MB" (an undefined double-to-size_t conversion).
  ExpectRefused(match_with_config("input_inf.yml", "memory-budget-mb: inf\n"), 2,
                "option 'memory-budget-mb' needs a finite number (got 'inf')");
  ExpectRefused(match_with_config("input_1e300.yml", "memory-budget-mb: 1e300\n"), 2,
                "memory-budget-mb must be a number in (0, 1099511627776]");
  ExpectRefused(match_with_config("input_nan.yml", "max-epipolar: nan\n"), 2,
                "option 'max-epipolar' needs a finite number (got 'nan')");
  // Finite but absurd: A = 1e308 overflowed the energy (report: energy null, no match).
  ExpectRefused(match_with_config("input_a.yml", "A: 1e308\n"), 2,
                "A must be >= 0 and <= 1e6");
  ExpectRefused(match_with_config("input_dt.yml", "dt: 1e308\n"), 2,
                "--dt must be a positive number <= 1e6");
  // A --config file beyond the text-file limit (16 MiB) is not read into memory.
  {
    std::ofstream out(Path("input_big.yml"));
    out << "seed: 1\n";
  }
  fs::resize_file(Path("input_big.yml"), 17u << 20);
  ExpectRefused(RunCli("match --left " + kTeddyLeft + " --right " + kTeddyRight +
                       " --rectified --out " + Path("m.csv") + " --config " + Path("input_big.yml")),
                2, "more than the limit of 16777216");
}

TEST_F(HostileInputCli, PointsFileAbsurdNumbersAreRefused) {
  std::string good;
  for (int i = 0; i < 8; ++i) {
    good += std::to_string(10 * i) + " " + std::to_string(7 * i % 5) + " " + std::to_string(i % 3) +
            " " + std::to_string(100 + 3 * i) + " " + std::to_string(50 + 5 * i) + "\n";
  }
  WriteFile("input_right.txt", good);
  WriteFile("input_huge.txt", good + "1e300 0 0 10 10\n");
  ExpectRefused(RunCli("calibrate --points-left " + Path("input_huge.txt") + " --points-right " +
                       Path("input_right.txt") + " --out " + Path("cal.yml")),
                2, "is beyond +-1e7");
  WriteFile("input_nan.txt", good + "nan 0 0 10 10\n");
  ExpectRefused(RunCli("calibrate --points-left " + Path("input_nan.txt") + " --points-right " +
                       Path("input_right.txt") + " --out " + Path("cal.yml")),
                2, "non-finite");
}

TEST_F(HostileInputCli, TargetYmlAbsurdNumbersAreRefused) {
  fs::create_directories(Path("input_target"));
  ASSERT_TRUE(cv::imwrite(Path("input_target/l.png"), cv::Mat(64, 64, CV_8UC1, cv::Scalar(0))));
  auto target = [&](const std::string& grid, const std::string& origin) {
    WriteFile("input_target/target.yml",
              "%YAML:1.0\n---\n" + grid + "pitch_mm: 25\nheights:\n"
              "  - { left: l.png, right: l.png, origin_mm: [" + origin + "] }\n"
              "  - { left: l.png, right: l.png, origin_mm: [0, 0, 50] }\n");
    return RunCli("calibrate --target circles --dir " + Path("input_target") + " --out " +
                  Path("cal.yml"));
  };
  // rows x cols = 10^24 circles; the cast to int was undefined.
  ExpectRefused(target("rows: 1e12\ncols: 1e12\n", "0, 0, 0"), 2,
                "'rows' must be a whole number in [2, 1000]");
  ExpectRefused(target("rows: 4\ncols: 5\n", "0, 1e300, 0"), 2, "beyond +-1e7 mm");
  ExpectRefused(target("rows: 4\ncols: 5\n", "0, .nan, 0"), 2, "non-finite");
  // A pose matrix header claiming 65536 x 65536 doubles (32 GB before the data was looked at;
  // found by fuzz_target_yml).
  WriteFile("input_target/target.yml",
            "%YAML:1.0\n---\nrows: 4\ncols: 5\npitch_mm: 25\nheights:\n"
            "  - { left: l.png, right: l.png, world_from_target: !!opencv-matrix "
            "{ rows: 65536, cols: 65536, dt: d, data: [ 1., 0. ] } }\n"
            "  - { left: l.png, right: l.png, origin_mm: [0, 0, 50] }\n");
  ExpectRefused(RunCli("calibrate --target circles --dir " + Path("input_target") + " --out " +
                       Path("cal.yml")),
                2, "world_from_target claims 65536x65536 elements, more than 16");
}

}  // namespace
}  // namespace hnnstereo::testing
