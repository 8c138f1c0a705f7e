// The match command's contract: files, report keys, and bad input (a one-line reason, a
// non-zero exit, no output file).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iterator>
#include <map>
#include <utility>
#include <cstdio>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "cli_runner.h"
#include "host/cpu_engines.h"
#include "host/network_file.h"

namespace {

namespace fs = std::filesystem;
using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;
const std::string& kTeddy = hnnstereo::testing::kTeddyDir;

class MatchCli : public hnnstereo::testing::CliTest {
 protected:
  std::string Teddy(const std::string& extra) const {
    return "match --left " + kTeddy + "/im2.png --right " + kTeddy + "/im6.png --out " +
           Path("m.csv") + " --max-features 1500 " + extra;
  }
  // A failed command prints one line starting "hnnstereo: error:" and writes nothing.
  void ExpectCleanFailure(const CliResult& result, const std::string& reason) const {
    EXPECT_NE(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("hnnstereo: error: "), std::string::npos) << result.output;
    EXPECT_NE(result.output.find(reason), std::string::npos) << result.output;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      EXPECT_TRUE(name.rfind("input", 0) == 0) << "unexpected output file " << name;
    }
  }
};

TEST_F(MatchCli, WritesTheContractFiles) {
  const CliResult result = RunCli(Teddy("--rectified --max-disparity 64 --report " + Path("r.json") +
                                  " --overlay " + Path("o.png")));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  std::ifstream csv(Path("m.csv"));
  std::string header, row;
  std::getline(csv, header);
  EXPECT_EQ(header, "xl,yl,xr,yr,activation,confidence");
  int rows = 0;
  while (std::getline(csv, row)) ++rows;
  EXPECT_GT(rows, 300);
  std::ifstream report_file(Path("r.json"));
  const nlohmann::json report = nlohmann::json::parse(report_file);
  for (const char* key : {"engine", "device", "n_left", "n_right", "n_neurons", "n_connections",
                          "iterations", "energy_initial", "energy_final", "timing_ms"}) {
    EXPECT_TRUE(report.contains(key)) << key;
  }
  for (const char* key : {"features", "candidates", "network", "weights", "solve", "decode", "total"}) {
    EXPECT_TRUE(report["timing_ms"].contains(key)) << key;
  }
  EXPECT_EQ(report["n_matches"].get<int>(), rows);
  EXPECT_LT(report["energy_final"].get<double>(), report["energy_initial"].get<double>());
  // The matches are in MATCHES.csv, not repeated in the report (a full-Teddy report was 6 MB).
  EXPECT_FALSE(report.contains("matches"));
  EXPECT_LT(fs::file_size(Path("r.json")), 16u * 1024u);
  const cv::Mat overlay = cv::imread(Path("o.png"));
  EXPECT_EQ(overlay.cols, 900);
  EXPECT_EQ(overlay.rows, 375 + 56) << "the images, then the legend";
}

// --report-matches: every match with its confidence features, for fitting the confidence.
TEST_F(MatchCli, ReportListsTheMatchesWhenAsked) {
  const CliResult result = RunCli(Teddy("--rectified --max-disparity 64 --engine cpu --report " +
                                        Path("r.json") + " --report-matches"));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(Path("r.json")));
  ASSERT_TRUE(report.contains("matches"));
  EXPECT_EQ(report["matches"]["columns"][5], "confidence");
  EXPECT_EQ(report["matches"]["rows"].size(), report["n_matches"].get<std::size_t>());
}

// --ply: the matches triangulated in the calibration's world frame. With a Middlebury calib.txt
// (f = 1000 px, principal point (200, 180), baseline 100 mm) a match of disparity d lies at
// z = f b / d, x = (x_l - 200) z / f in the left camera's frame. Without --calib: refused.
TEST_F(MatchCli, PlyHoldsTheTriangulatedMatches) {
  std::ofstream(Path("input_calib.txt"))
      << "cam0=[1000 0 200; 0 1000 180; 0 0 1]\ncam1=[1000 0 200; 0 1000 180; 0 0 1]\n"
         "doffs=0\nbaseline=100\nwidth=450\nheight=375\n";
  const CliResult result = RunCli(Teddy("--calib " + Path("input_calib.txt") +
                                        " --max-disparity 64 --engine cpu --ply " + Path("p.ply")));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find(Path("p.ply")), std::string::npos) << "not among the files written";
  std::ifstream ply(Path("p.ply"));
  std::string line;
  std::size_t vertices = 0;
  while (std::getline(ply, line) && line != "end_header") {
    if (line.rfind("element vertex ", 0) == 0) vertices = std::stoul(line.substr(15));
  }
  std::ifstream csv(Path("m.csv"));
  std::getline(csv, line);  // header
  std::size_t checked = 0;
  while (std::getline(csv, line)) {
    double xl = 0, yl = 0, xr = 0, yr = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &xl, &yl, &xr, &yr), 4) << line;
    if (!(xl - xr > 0.0)) continue;  // at infinity or behind: no point
    double x = 0, y = 0, z = 0;
    ASSERT_TRUE(ply >> x >> y >> z) << "fewer points than matches with d > 0";
    ply.ignore(64, '\n');
    const double expected_z = 1000.0 * 100.0 / (xl - xr);
    EXPECT_NEAR(z, expected_z, 1e-4 * expected_z) << line;
    EXPECT_NEAR(x, (xl - 200.0) * expected_z / 1000.0, 1e-4 * expected_z + 1e-3) << line;
    ++checked;
  }
  EXPECT_EQ(checked, vertices);
  EXPECT_GT(checked, 300u);
  fs::remove(Path("m.csv"));
  fs::remove(Path("p.ply"));
  ExpectCleanFailure(RunCli(Teddy("--rectified --max-disparity 64 --ply " + Path("q.ply"))),
                     "--ply needs --calib");
}

// --save-network: the network as solved, which a replay solves to the same state (the cpu
// engine: the match's own iterations and final energy).
TEST_F(MatchCli, SavedNetworkReplaysAsTheMatchSolvedIt) {
  const CliResult result = RunCli(Teddy("--rectified --max-disparity 64 --engine cpu --report " +
                                        Path("r.json") + " --save-network " + Path("n.hnnet")));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  std::ifstream report_file(Path("r.json"));
  const nlohmann::json report = nlohmann::json::parse(report_file);
  std::ifstream file(Path("n.hnnet"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const hnnstereo::hnn::CapturedNetwork net = hnnstereo::hnn::ParseNetwork(bytes);
  EXPECT_EQ(net.problem.n_neurons(), report["n_neurons"].get<int>());
  EXPECT_EQ(net.problem.n_left(), report["n_left"].get<int>());
  const hnnstereo::hnn::SolveReport replay =
      hnnstereo::hnn::SolveCpu(net.problem, net.energy, net.dynamics);
  EXPECT_EQ(replay.iterations, report["iterations"].get<int>());
  EXPECT_NEAR(replay.energy_final, report["energy_final"].get<double>(),
              1e-9 * std::abs(replay.energy_final));
  // An unwritable --save-network is refused before any work, with nothing written.
  for (const char* name : {"m.csv", "r.json", "n.hnnet"}) fs::remove(Path(name));
  ExpectCleanFailure(RunCli(Teddy("--rectified --save-network " + Path("no/such/dir/n.hnnet"))),
                     "--save-network");
}

TEST_F(MatchCli, HelpTeachesTheOptions) {
  const CliResult result = RunCli("match --help");
  EXPECT_EQ(result.exit_code, 0);
  for (const char* option : {"--left", "--rectified", "--calib", "--max-disparity", "--engine",
                             "--dense", "--report", "--overlay", "--config", "--zrange"}) {
    EXPECT_NE(result.output.find(option), std::string::npos) << option;
  }
}

TEST_F(MatchCli, MissingImage) {
  ExpectCleanFailure(RunCli("match --left " + Path("nope.png") + " --right " + kTeddy +
                         "/im6.png --rectified --out " + Path("m.csv")),
                     "does not exist");
}

TEST_F(MatchCli, UnreadableImage) {
  std::ofstream(Path("input_text.png")) << "not an image";
  ExpectCleanFailure(RunCli("match --left " + Path("input_text.png") + " --right " + kTeddy +
                         "/im6.png --rectified --out " + Path("m.csv")),
                     "cannot be read");
}

TEST_F(MatchCli, DifferentImageSizes) {
  cv::imwrite(Path("input_small.png"), cv::Mat(100, 120, CV_8UC1, cv::Scalar(80)));
  ExpectCleanFailure(RunCli("match --left " + kTeddy + "/im2.png --right " + Path("input_small.png") +
                         " --rectified --out " + Path("m.csv")),
                     "size");
}

TEST_F(MatchCli, NoFeatures) {
  cv::imwrite(Path("input_flat_l.png"), cv::Mat(100, 120, CV_8UC1, cv::Scalar(80)));
  cv::imwrite(Path("input_flat_r.png"), cv::Mat(100, 120, CV_8UC1, cv::Scalar(81)));
  ExpectCleanFailure(RunCli("match --left " + Path("input_flat_l.png") + " --right " +
                         Path("input_flat_r.png") + " --rectified --out " + Path("m.csv")),
                     "no features");
}

TEST_F(MatchCli, NoCandidates) {
  ExpectCleanFailure(RunCli(Teddy("--rectified --min-disparity 443 --max-disparity 449")),
                     "no candidate");
}

TEST_F(MatchCli, NaNInTheFundamentalMatrix) {
  std::ofstream(Path("input_cal.yml"))
      << "%YAML:1.0\n---\nP1: !!opencv-matrix\n   rows: 3\n   cols: 4\n   dt: d\n"
         "   data: [ 500., 0., 225., 0., 0., 500., 187., 0., 0., 0., 1., 0. ]\n"
         "P2: !!opencv-matrix\n   rows: 3\n   cols: 4\n   dt: d\n"
         "   data: [ 500., 0., 225., -50000., 0., 500., 187., 0., 0., 0., 1., 0. ]\n"
         "F: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
         "   data: [ 0., 0., 0., 0., 0., -1., 0., .Nan, 0. ]\n";
  ExpectCleanFailure(RunCli(Teddy("--calib " + Path("input_cal.yml"))), "non-finite");
}

TEST_F(MatchCli, OverTheMemoryBudget) {
  const CliResult result = RunCli(Teddy("--rectified --dense --memory-budget-mb 1"));
  ExpectCleanFailure(result, "memory budget");
  EXPECT_NE(result.output.find("neurons"), std::string::npos) << result.output;
}

TEST_F(MatchCli, ASparseNetworkOverTheBudgetMatchesASpreadShareAndSaysSo) {
  ExpectCleanFailure(RunCli(Teddy("--rectified --max-disparity 64 --memory-budget-mb 0.3 "
                                  "--no-fit-memory-budget")),
                     "memory budget");
  const CliResult fitted = RunCli(Teddy("--rectified --max-disparity 64 --memory-budget-mb 0.3 "
                                        "--report " + Path("r.json")));
  ASSERT_EQ(fitted.exit_code, 0) << fitted.output;
  EXPECT_NE(fitted.output.find("memory budget: the network over all"), std::string::npos)
      << fitted.output;
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(Path("r.json")));
  ASSERT_TRUE(report.contains("memory_fit")) << report.dump();
  EXPECT_LT(report["memory_fit"]["left_features_matched"].get<int>(), report["n_left"].get<int>());
  EXPECT_GT(report["memory_fit"]["needed_bytes"].get<double>(), 0.3 * (1 << 20));
}

TEST_F(MatchCli, BenchAtCameraSizesComparesWithStereoSgbmPerSize) {
  const CliResult result =
      RunCli("bench --out " + Path("cam.json") + " --camera-sizes 0.1,0.6 --repeats 1 --engine cpu");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const nlohmann::json bench = nlohmann::json::parse(std::ifstream(Path("cam.json")));
  ASSERT_EQ(bench["camera_sizes"].size(), 2u);
  const double sizes[] = {0.1, 0.6};
  for (std::size_t i = 0; i < 2; ++i) {
    const nlohmann::json& row = bench["camera_sizes"][i];
    EXPECT_NEAR(row["megapixels"].get<double>(), sizes[i], 0.01 * sizes[i]);
    EXPECT_GT(row["stereo_sgbm_ms"].get<double>(), 0.0);
    EXPECT_GT(row["ms_per_1000_features"].get<double>(), 0.0);
    EXPECT_GT(row["peak_resident_mb"].get<double>(), 10.0);
  }
  // Teddy at 0.6 MP (disparities to 117) is matched coarse-to-fine, at 0.1 MP it is not.
  EXPECT_EQ(bench["camera_sizes"][0]["coarse_to_fine_levels"], 0);
  EXPECT_EQ(bench["camera_sizes"][1]["coarse_to_fine_levels"], 1);
  EXPECT_GE(bench["ms_per_1000_features_spread"].get<double>(), 1.0);
  const CliResult bad = RunCli("bench --out " + Path("bad.json") + " --camera-sizes 1,x");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--camera-sizes must be"), std::string::npos) << bad.output;
}

TEST_F(MatchCli, NoOpenClPlatformFallsBackToTheCpuEngine) {
  const CliResult result = RunCli(Teddy("--rectified --max-disparity 64 --report " + Path("r.json")),
                            "OCL_ICD_VENDORS=" + Path("no_vendors") + " OPENCL_VENDOR_PATH=" +
                                Path("no_vendors"));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("notice"), std::string::npos) << result.output;
  std::ifstream report_file(Path("r.json"));
  EXPECT_EQ(nlohmann::json::parse(report_file)["engine"], "cpu");
}

TEST_F(MatchCli, ConfigFileSetsOptions) {
  std::ofstream(Path("input_options.yml")) << "# matcher options\nmax_disparity: 64\nengine: cpu\nrectified: true\n";
  const CliResult result = RunCli(Teddy("--config " + Path("input_options.yml") + " --report " + Path("r.json")));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  std::ifstream report_file(Path("r.json"));
  const auto report = nlohmann::json::parse(report_file);
  EXPECT_EQ(report["engine"], "cpu");
  EXPECT_EQ(report["candidate_options"]["max_disparity"].get<double>(), 64.0);
}

}  // namespace

namespace {

// Issue 41: a setup error found before any work exits 2, always.
TEST_F(MatchCli, SetupErrorsExitTwo) {
  std::ofstream(Path("input_text.png")) << "not an image";
  cv::imwrite(Path("input_small.png"), cv::Mat(100, 120, CV_8UC1, cv::Scalar(80)));
  for (const std::string& arguments :
       {"match --left " + Path("nope.png") + " --right " + kTeddy + "/im6.png --rectified",
        "match --left " + kTeddy + "/im2.png --right " + Path("input_small.png") + " --rectified",
        "match --left " + kTeddy + "/im2.png --right " + kTeddy + "/im6.png --calib " + kTeddy +
            "/im2.png"}) {
    const CliResult result = RunCli(arguments + " --out " + Path("m.csv"));
    EXPECT_EQ(result.exit_code, 2) << arguments << "\n" << result.output;
    EXPECT_FALSE(fs::exists(Path("m.csv")));
  }
}

// Issue 41: nonsense parameters are refused, naming the option.
TEST_F(MatchCli, NonsenseRangesAreRefusedNamingTheOption) {
  ExpectCleanFailure(RunCli(Teddy("--rectified --max-disparity 0")), "--max-disparity 0.0 must be");
  ExpectCleanFailure(RunCli(Teddy("--rectified --max-disparity -5")), "--max-disparity");
  ExpectCleanFailure(RunCli(Teddy("--rectified --dt 0")), "--dt must be");
  ExpectCleanFailure(RunCli(Teddy("--rectified --top-k -3")), "--top-k must be");
  ExpectCleanFailure(RunCli(Teddy("--rectified --max-steps 0")), "--max-steps must be >= 1");
  ExpectCleanFailure(RunCli(Teddy("--rectified --engine cpu --device 3")),
                     "--device '3' is for --engine opencl");
  ExpectCleanFailure(RunCli(Teddy("--rectified --overlay " + Path("o.jpgx"))), "--overlay");
}

// Issue 41: a calibration made for another image size is refused, as pick refuses it.
TEST_F(MatchCli, CalibrationOfAnotherImageSizeIsRefused) {
  std::ofstream(Path("input_cal.yml"))
      << "%YAML:1.0\n---\nP1: !!opencv-matrix\n   rows: 3\n   cols: 4\n   dt: d\n"
         "   data: [ 500., 0., 320., 0., 0., 500., 240., 0., 0., 0., 1., 0. ]\n"
         "P2: !!opencv-matrix\n   rows: 3\n   cols: 4\n   dt: d\n"
         "   data: [ 500., 0., 320., -50000., 0., 500., 240., 0., 0., 0., 1., 0. ]\n"
         "image_width: 640\nimage_height: 480\n";
  const CliResult result = RunCli("match --left " + kTeddy + "/im2.png --right " + kTeddy +
                                  "/im6.png --calib " + Path("input_cal.yml") + " --out " +
                                  Path("m.csv"));
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_NE(result.output.find("is for 640x480 images, the pair is 450x375"), std::string::npos)
      << result.output;
}

// Issue 41: a disparity map other tools read, with the matches' disparities at their pixels.
TEST_F(MatchCli, DisparityMapsHoldTheMatchesDisparities) {
  const CliResult result = RunCli(Teddy("--rectified --max-disparity 64 --disparity " +
                                        Path("d.pfm")));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  ASSERT_EQ(RunCli(Teddy("--rectified --max-disparity 64 --disparity " + Path("d.png"))).exit_code,
            0);
  const cv::Mat pfm = cv::imread(Path("d.pfm"), cv::IMREAD_UNCHANGED);
  const cv::Mat png = cv::imread(Path("d.png"), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(pfm.type(), CV_32FC1);
  ASSERT_EQ(png.type(), CV_16UC1);
  ASSERT_EQ(pfm.size(), cv::Size(450, 375));
  ASSERT_EQ(png.size(), cv::Size(450, 375));
  // The last match at a pixel is the one the map holds (the maps are written in MATCHES.csv order).
  std::ifstream csv(Path("m.csv"));
  std::string line;
  std::getline(csv, line);
  std::map<std::pair<int, int>, float> expected;
  while (std::getline(csv, line)) {
    float xl = 0, yl = 0, xr = 0, yr = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%f,%f,%f,%f", &xl, &yl, &xr, &yr), 4) << line;
    expected[{static_cast<int>(std::lround(yl)), static_cast<int>(std::lround(xl))}] = xl - xr;
  }
  ASSERT_GT(expected.size(), 1000u);
  for (const auto& [pixel, d] : expected) {
    EXPECT_NEAR(pfm.at<float>(pixel.first, pixel.second), d, 2e-3);
    if (d > 0) EXPECT_NEAR(png.at<std::uint16_t>(pixel.first, pixel.second) / 256.0, d, 1.0 / 256);
  }
  std::size_t known = 0;
  for (int y = 0; y < pfm.rows; ++y) {
    for (int x = 0; x < pfm.cols; ++x) known += std::isnan(pfm.at<float>(y, x)) ? 0 : 1;
  }
  EXPECT_EQ(known, expected.size()) << "NaN wherever nothing matched";
}

TEST_F(MatchCli, EveryCommandTakesVersion) {
  for (const std::string command : {"match", "pick", "serve", "robot send", "calibrate"}) {
    const CliResult result = RunCli(command + " --version");
    EXPECT_EQ(result.exit_code, 0) << command << ": " << result.output;
    EXPECT_NE(result.output.find("hnnstereo 0.1.0"), std::string::npos) << result.output;
  }
}

TEST_F(MatchCli, DisparityMapsNeedARectifiedPair) {
  ExpectCleanFailure(RunCli("match --left " + kTeddy + "/im2.png --right " + kTeddy +
                            "/im6.png --out " + Path("m.csv") + " --disparity " + Path("e.pfm")),
                     "--disparity needs a rectified pair");
}

}  // namespace
