// The eval command's contract: EVAL.json, Markdown, plot; a clean failure on a folder without a
// Middlebury set.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;

using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;
const std::string& kTeddy = hnnstereo::testing::kTeddyDir;

class EvalCli : public hnnstereo::testing::CliTest {};

TEST_F(EvalCli, WritesJsonMarkdownAndPlotForOneSet) {
  const CliResult result =
      RunCli("eval --dataset " + kTeddy + " --out " + Path("eval.json") + " --markdown " +
             Path("eval.md") + " --engine cpu --max-features 1500 --max-steps 150");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("| middlebury2003_teddy | hnn-default |"), std::string::npos)
      << result.output;
  std::ifstream file(Path("eval.json"));
  const nlohmann::json json = nlohmann::json::parse(file);
  ASSERT_EQ(json["pairs"].size(), 1u);
  const nlohmann::json& pair = json["pairs"][0];
  EXPECT_EQ(pair["layout"], "middlebury2003");
  std::vector<std::string> methods;
  for (const auto& method : pair["methods"]) methods.push_back(method["method"]);
  EXPECT_EQ(methods, (std::vector<std::string>{"hnn-default", "hnn-thesis", "wta-zncc", "opencv-bm",
                                                "opencv-sgbm"}));
  const nlohmann::json& hnn = pair["methods"][0];
  for (const char* key : {"precision_1px", "precision_2px", "occluded_precision_1px", "density",
                          "n_matches", "n_occluded", "time_ms"}) {
    EXPECT_TRUE(hnn.contains(key)) << key;
  }
  EXPECT_GT(hnn["n_matches"].get<int>(), 300);
  EXPECT_GT(hnn["precision_1px"].get<double>(), 0.5);
  EXPECT_LE(hnn["precision_1px"].get<double>(), hnn["precision_2px"].get<double>());
  // Baselines at the same pixels.
  EXPECT_EQ(pair["methods"][2]["n_matches"], hnn["n_matches"]);
  EXPECT_EQ(json["overall"].size(), 5u);
  const cv::Mat plot = cv::imread(Path("eval.png"));
  EXPECT_FALSE(plot.empty());
  std::ifstream markdown(Path("eval.md"));
  std::string header;
  std::getline(markdown, header);
  EXPECT_NE(header.find("precision 1 px"), std::string::npos);
  std::stringstream rest;
  rest << markdown.rdbuf();
  EXPECT_NE(rest.str().find("| pair | method | 25 % | 50 % | 75 % | full: density % | full: error % |"),
            std::string::npos) << rest.str();
  EXPECT_NE(rest.str().find("| middlebury2003_teddy | opencv-sgbm (sweep) |"), std::string::npos);
  EXPECT_NE(rest.str().find("Ranking check"), std::string::npos);

  // Ranked by confidence: every method over all edge pixels, in the JSON and one plot per pair.
  ASSERT_TRUE(json.contains("ranked"));
  std::vector<std::string> ranked;
  for (const auto& method : pair["ranked"]) ranked.push_back(method["method"]);
  EXPECT_EQ(ranked, (std::vector<std::string>{"hnn-default", "hnn-thesis", "wta-zncc (margin)",
                                               "opencv-sgbm (sweep)", "opencv-bm (sweep)"}));
  const nlohmann::json& sgbm = pair["ranked"][3];
  ASSERT_EQ(sgbm["sweep"].size(), 10u);
  EXPECT_EQ(sgbm["sweep"][0]["uniqueness_ratio"], 0);
  EXPECT_GE(sgbm["sweep"][0]["density"].get<double>(), sgbm["sweep"][9]["density"].get<double>());
  EXPECT_GT(pair["ranked"][2]["full"]["density"].get<double>(), 0.9) << "WTA answers everywhere";
  bool has_overall_hnn = false;
  for (const auto& row : json["ranked"]["table"]) {
    has_overall_hnn |= row["pair"] == "overall" && row["method"] == "hnn-default";
  }
  EXPECT_TRUE(has_overall_hnn);
  EXPECT_EQ(json["ranked"]["hnn_vs_sgbm"].size(), 2u);  // the pair and overall
  const cv::Mat ranked_plot = cv::imread(Path("eval.middlebury2003_teddy.png"));
  ASSERT_FALSE(ranked_plot.empty());
  EXPECT_GE(ranked_plot.cols, 800);
  // The confidence calibration of both HNN presets: the pair, its scene (indoor) and overall.
  EXPECT_EQ(pair["scene"], "indoor");
  const nlohmann::json& calibration = json["ranked"]["confidence_calibration"];
  ASSERT_EQ(calibration.size(), 6u);
  EXPECT_EQ(calibration[1]["group"], "indoor");
  double binned = 0.0;
  for (const auto& bin : calibration[2]["bins"]) binned += bin["matches"].get<double>();
  EXPECT_NEAR(binned, pair["methods"][0]["n_nonoccluded"].get<double>(), 0.5);
  EXPECT_FALSE(cv::imread(Path("eval.calibration.png")).empty());
  // The vendored Teddy ships its right-view ground truth: occlusions from the left-right check,
  // as for the shared copy, and eval says so.
  EXPECT_EQ(pair["occlusion_source"], "left-right check");
  EXPECT_NE(result.output.find("no occlusion mask: occluded pixels are those failing"),
            std::string::npos) << result.output;
}

// The first preset's overrides reach the run, and EVAL.json records what ran.
TEST_F(EvalCli, OverridesOfTheFirstPresetAreRecorded) {
  const CliResult result =
      RunCli("eval --dataset " + kTeddy + " --out " + Path("eval.json") +
             " --presets hnn-default --no-baselines --engine cpu --max-features 400 --quiet"
             " --A 1.5 --T 2 --support-gamma 25 --top-k 2 --no-lr-check --no-subpixel");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  std::ifstream file(Path("eval.json"));
  const nlohmann::json preset = nlohmann::json::parse(file)["presets"][0];
  EXPECT_EQ(preset["name"], "hnn-default");
  EXPECT_DOUBLE_EQ(preset["A"].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(preset["T"].get<double>(), 2.0);
  EXPECT_EQ(preset["top_k"], 2);
  EXPECT_EQ(preset["data_term"]["kind"], "census");
  EXPECT_DOUBLE_EQ(preset["data_term"]["support_gamma"].get<double>(), 25.0);
  EXPECT_EQ(preset["left_right_check"], false);  // match's --x/--no-x pairs
  EXPECT_EQ(preset["subpixel"], false);
}

TEST_F(EvalCli, FolderWithoutASetFailsCleanly) {
  fs::create_directories(Path("input_empty"));
  const CliResult result = RunCli("eval --dataset " + Path("input_empty") + " --out " + Path("eval.json"));
  EXPECT_EQ(result.exit_code, 2) << result.output;  // a refused setup
  EXPECT_NE(result.output.find("hnnstereo: error: --dataset: no Middlebury set"), std::string::npos)
      << result.output;
  EXPECT_FALSE(fs::exists(Path("eval.json")));
}

TEST_F(EvalCli, UnknownPresetFailsCleanly) {
  const CliResult result = RunCli("eval --dataset " + kTeddy + " --out " + Path("eval.json") +
                               " --presets nonsense");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.output.find("unknown preset"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(Path("eval.json")));
}

TEST_F(EvalCli, HelpNamesTheLayoutsAndOptions) {
  const CliResult result = RunCli("eval --help");
  EXPECT_EQ(result.exit_code, 0);
  for (const char* word : {"--dataset", "--out", "--markdown", "--plot", "--presets", "--warped",
                           "2014", "PFM"}) {
    EXPECT_NE(result.output.find(word), std::string::npos) << word;
  }
}

}  // namespace
