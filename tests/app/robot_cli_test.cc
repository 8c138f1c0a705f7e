// The robot side of the command line: robot fit-frame/thesis-frame/show-frame/send, serve with
// the dry-run transport, pick --robot. Transports against real peers: tests/robot/peers.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.h"

namespace {

namespace fs = std::filesystem;
using hnnstereo::testing::CliResult;
using hnnstereo::testing::CliTest;
using hnnstereo::testing::RunCli;

std::vector<nlohmann::json> ReadJsonLines(const std::string& path) {
  std::ifstream in(path);
  std::vector<nlohmann::json> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(nlohmann::json::parse(line));
  return lines;
}

class RobotCli : public CliTest {
 protected:
  // An identity frame with a generous box: robot coordinates = world coordinates.
  std::string IdentityFrame() {
    std::ofstream(Path("touched.csv")) << "world_x,world_y,world_z,robot_x,robot_y,robot_z\n"
                                          "0,0,0,0,0,0\n100,0,0,100,0,0\n0,100,0,0,100,0\n"
                                          "0,0,50,0,0,50\n";
    const CliResult fit = RunCli("robot fit-frame --points " + Path("touched.csv") + " --out " +
                                 Path("frame.yml") +
                                 " --workspace-min -1000,-1000,-10 --workspace-max 1000,1000,500");
    EXPECT_EQ(fit.exit_code, 0) << fit.output;
    return Path("frame.yml");
  }
  void ExpectCleanFailure(const CliResult& result, const std::string& reason,
                          const std::vector<std::string>& not_written) {
    EXPECT_NE(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("hnnstereo: error: " + reason), std::string::npos)
        << result.output;
    for (const std::string& name : not_written) EXPECT_FALSE(fs::exists(Path(name))) << name;
  }
};

TEST_F(RobotCli, FitFrameRecoversTheThesisTransformFromTouchedPoints) {
  // Robot = thesis frame: x_r = 600 - X, y_r = 400 - Y, z_r = Z.
  std::ofstream points(Path("touched.csv"));
  points << "# touched with the gripper tip\n";
  for (const auto& [x, y, z] : std::vector<std::tuple<double, double, double>>{
           {0, 0, 0}, {250, 0, 0}, {0, 250, 0}, {250, 250, 100}, {120, 60, 30}}) {
    points << x << "," << y << "," << z << "," << 600 - x << "," << 400 - y << "," << z << "\n";
  }
  points.close();
  const CliResult fit =
      RunCli("robot fit-frame --points " + Path("touched.csv") + " --out " + Path("fit.yml") +
             " --workspace-min 100,-300,0 --workspace-max 600,300,450");
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  EXPECT_NE(fit.output.find("fitted 5 points: rms 0.000 mm"), std::string::npos) << fit.output;
  const CliResult shown =
      RunCli("robot show-frame --frame " + Path("fit.yml") + " --world 200,300,40");
  ASSERT_EQ(shown.exit_code, 0) << shown.output;
  EXPECT_NE(shown.output.find("robot (400.00, 100.00, 40.00): inside the workspace"),
            std::string::npos)
      << shown.output;
  // The fitted frame equals the one thesis-frame writes.
  ASSERT_EQ(RunCli("robot thesis-frame --out " + Path("thesis.yml")).exit_code, 0);
  const CliResult thesis =
      RunCli("robot show-frame --frame " + Path("thesis.yml") + " --world 200,300,40");
  EXPECT_NE(thesis.output.find("robot (400.00, 100.00, 40.00)"), std::string::npos)
      << thesis.output;
  const CliResult outside =
      RunCli("robot show-frame --frame " + Path("thesis.yml") + " --world 200,300,-40");
  EXPECT_NE(outside.output.find("OUTSIDE the workspace"), std::string::npos) << outside.output;
}

// Without --workspace-min/--workspace-max the safety box is the touched points' box plus the
// margin (50 mm) and the clearance above the highest point (300 mm), not a fixed +-400 mm.
TEST_F(RobotCli, FitFrameDefaultWorkspaceIsTheTouchedBoxPlusAMargin) {
  std::ofstream(Path("touched.csv")) << "0,0,0,500,-100,20\n200,0,0,700,-100,20\n"
                                        "0,150,0,500,50,20\n200,150,40,700,50,60\n";
  const CliResult fit =
      RunCli("robot fit-frame --points " + Path("touched.csv") + " --out " + Path("fit.yml"));
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  EXPECT_NE(fit.output.find("[450.0, 750.0] x [-150.0, 100.0] x [-30.0, 360.0]"),
            std::string::npos)
      << fit.output;
  EXPECT_NE(fit.output.find("workspace from the touched points' box"), std::string::npos)
      << fit.output;
  const CliResult set = RunCli("robot fit-frame --points " + Path("touched.csv") + " --out " +
                               Path("fit2.yml") + " --workspace-margin 10 --workspace-height 100");
  ASSERT_EQ(set.exit_code, 0) << set.output;
  EXPECT_NE(set.output.find("[490.0, 710.0] x [-110.0, 60.0] x [10.0, 160.0]"), std::string::npos)
      << set.output;
}

TEST_F(RobotCli, FitFrameRefusesDegenerateAndMalformedPoints) {
  std::ofstream(Path("line.csv")) << "0,0,0,0,0,0\n10,0,0,10,0,0\n20,0,0,20,0,0\n";
  ExpectCleanFailure(
      RunCli("robot fit-frame --points " + Path("line.csv") + " --out " + Path("f.yml")), "",
      {"f.yml"});
  std::ofstream(Path("short.csv")) << "0,0,0,0,0,0\n10,0,0,10,0\n";
  ExpectCleanFailure(
      RunCli("robot fit-frame --points " + Path("short.csv") + " --out " + Path("f.yml")),
      "points file", {"f.yml"});
  ExpectCleanFailure(RunCli("robot fit-frame --points " + Path("none.csv") + " --out " +
                            Path("f.yml")),
                     "cannot read points file", {"f.yml"});
  ExpectCleanFailure(RunCli("robot show-frame --frame " + Path("none.yml")), "frame file", {});
}

TEST_F(RobotCli, ServeReplaysObjectsThroughTheDryRunLink) {
  const std::string frame = IdentityFrame();
  std::ofstream(Path("objects.json"))
      << R"({"units":"mm","objects":[)"
      << R"({"id":1,"centroid":[10,20,30],"height":30,"yaw_deg":5},)"
      << R"({"id":2,"centroid":[-40,60,80],"height":80,"yaw_deg":-20},)"
      << R"({"id":3,"centroid":[5000,0,50],"height":50,"yaw_deg":0}]})";
  const CliResult served =
      RunCli("serve --replay " + Path("objects.json") + " --frame " + frame + " --robot dryrun:" +
             Path("picks.jsonl") + " --cycles 3 --period 0 --report " + Path("report.json"));
  ASSERT_EQ(served.exit_code, 0) << served.output;
  EXPECT_NE(served.output.find("link: dryrun:"), std::string::npos) << served.output;
  EXPECT_NE(served.output.find("cycle 3 request 3: 3 parts, 2 sent, 1 refused"),
            std::string::npos)
      << served.output;
  EXPECT_NE(served.output.find("refused: pick pose is outside the workspace box"),
            std::string::npos)
      << served.output;
  const auto lines = ReadJsonLines(Path("picks.jsonl"));
  ASSERT_EQ(lines.size(), 9u) << "3 x (one cycle line + two picks)";
  std::uint32_t last_sequence = 0;
  for (std::size_t i = 0; i < lines.size(); i += 3) {
    EXPECT_EQ(lines[i]["type"], "cycle");
    EXPECT_EQ(lines[i]["status"], 2) << "result ready (docs/robot.md status codes)";
    EXPECT_EQ(lines[i + 1]["object_id"], 2) << "tallest first";
    EXPECT_EQ(lines[i + 2]["object_id"], 1);
    const std::vector<double> expected = {-40.0, 60.0, 80.0};
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_NEAR(lines[i + 1]["position_mm"][axis].get<double>(), expected[axis], 1e-9);
    }
    for (std::size_t k = i + 1; k < i + 3; ++k) {
      EXPECT_GT(lines[k]["sequence"].get<std::uint32_t>(), last_sequence);
      last_sequence = lines[k]["sequence"].get<std::uint32_t>();
    }
  }
  std::ifstream report_file(Path("report.json"));
  const nlohmann::json report = nlohmann::json::parse(report_file);
  EXPECT_EQ(report["cycles"], 3);
  EXPECT_EQ(report["poses_published"], 6);
  EXPECT_EQ(report["refused"], 3);
  EXPECT_EQ(report["link"]["poses_sent"], 6);
  // Nearest-rank p95 of 3 cycles is the slowest one, never the median.
  EXPECT_EQ(report["cycle_ms"]["p95"], report["cycle_ms"]["max"]);
}

TEST_F(RobotCli, ServeRefusesBadInputBeforeOpeningTheLink) {
  const std::string frame = IdentityFrame();
  std::ofstream(Path("objects.json")) << R"({"objects":[]})";
  const std::string replay = " --replay " + Path("objects.json");
  const std::string dry = " --robot dryrun:" + Path("picks.jsonl");
  ExpectCleanFailure(RunCli("serve" + replay + " --frame " + frame + " --robot tcp://x:1"),
                     "robot URI", {"picks.jsonl"});
  ExpectCleanFailure(RunCli("serve" + replay + " --frame " + Path("nope.yml") + dry),
                     "frame file", {"picks.jsonl"});
  ExpectCleanFailure(RunCli("serve --replay " + Path("missing.json") + " --frame " + frame + dry),
                     "--replay: cannot read", {"picks.jsonl"});
  ExpectCleanFailure(RunCli("serve --frame " + frame + dry), "serve needs --left", {"picks.jsonl"});
  ExpectCleanFailure(
      RunCli("serve" + replay + " --left a.png --frame " + frame + dry), "--replay replaces",
      {"picks.jsonl"});
  ExpectCleanFailure(RunCli("serve" + replay + " --frame " + frame + dry + " --max-poses 0"),
                     "--max-poses must be", {"picks.jsonl"});
  ExpectCleanFailure(RunCli("serve" + replay + " --frame " + frame + dry + " --speed 2"),
                     "--speed must be", {"picks.jsonl"});
}

TEST_F(RobotCli, SendWritesACellCommand) {
  const std::string frame = IdentityFrame();
  const CliResult sent = RunCli("robot send --command stop --frame " + frame + " --robot dryrun:" +
                                Path("cell.jsonl"));
  ASSERT_EQ(sent.exit_code, 0) << sent.output;
  const auto lines = ReadJsonLines(Path("cell.jsonl"));
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0]["command"], "stop");
  ExpectCleanFailure(RunCli("robot send --command jump --frame " + frame + " --robot dryrun:" +
                            Path("jump.jsonl")),
                     "unknown --command", {"jump.jsonl"});
}

// The default rendered cell and the thesis frame agree: every part of `render --seed 7` (8
// parts, the tallest 131 mm) is sent, none refused as outside the workspace or beyond reach.
TEST_F(RobotCli, ServeSendsEveryPartOfTheRenderedCellThroughTheThesisFrame) {
  ASSERT_EQ(RunCli("render --seed 7 --quiet --out " + Path("s7")).exit_code, 0);
  ASSERT_EQ(RunCli("robot thesis-frame --quiet --out " + Path("frame.yml")).exit_code, 0);
  const CliResult served =
      RunCli("serve --left " + Path("s7/left.png") + " --right " + Path("s7/right.png") +
             " --calib " + Path("s7/calib.yml") + " --frame " + Path("frame.yml") +
             " --robot dryrun:" + Path("picks.jsonl") + " --cycles 1");
  ASSERT_EQ(served.exit_code, 0) << served.output;
  EXPECT_NE(served.output.find("8 parts, 8 sent, 0 refused"), std::string::npos) << served.output;
  EXPECT_EQ(served.output.find("refused:"), std::string::npos) << served.output;
  int picks = 0;
  for (const nlohmann::json& line : ReadJsonLines(Path("picks.jsonl"))) {
    if (line["type"] == "pick") ++picks;
    if (line["type"] == "cycle") EXPECT_EQ(line["status"], 2) << line;
  }
  EXPECT_EQ(picks, 8) << served.output;
}

// No cell command carries a pose, so none needs FRAME.yml; --command stays required.
TEST_F(RobotCli, SendNeedsNoFrame) {
  for (const std::string command : {"home", "stop"}) {
    const CliResult sent =
        RunCli("robot send --command " + command + " --robot dryrun:" + Path(command + ".jsonl"));
    ASSERT_EQ(sent.exit_code, 0) << sent.output;
    const auto lines = ReadJsonLines(Path(command + ".jsonl"));
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_EQ(lines[0]["command"], command);
  }
  const CliResult no_command = RunCli("robot send --robot dryrun:" + Path("none.jsonl"));
  EXPECT_EQ(no_command.exit_code, 2) << no_command.output;
  EXPECT_NE(no_command.output.find("--command"), std::string::npos) << no_command.output;
  EXPECT_FALSE(std::filesystem::exists(Path("none.jsonl")));
}

TEST_F(RobotCli, PickSendsTheSensedPartsThroughTheLink) {
  const std::string frame = IdentityFrame();
  ASSERT_EQ(RunCli("render --seed 5 --objects 3 --out " + Path("scene")).exit_code, 0);
  const std::string scene = Path("scene");
  const CliResult picked =
      RunCli("pick --left " + scene + "/left.png --right " + scene + "/right.png --calib " +
             scene + "/calib.yml --out " + Path("objects.json") + " --frame " + frame +
             " --robot dryrun:" + Path("picks.jsonl"));
  ASSERT_EQ(picked.exit_code, 0) << picked.output;
  std::ifstream objects_file(Path("objects.json"));
  const nlohmann::json objects = nlohmann::json::parse(objects_file)["objects"];
  const auto lines = ReadJsonLines(Path("picks.jsonl"));
  ASSERT_EQ(lines.size(), objects.size() + 1);
  ASSERT_GE(objects.size(), 2u);
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const nlohmann::json& pick = lines[i + 1];
    EXPECT_EQ(pick["object_id"], objects[i]["id"]);
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_NEAR(pick["position_mm"][axis].get<double>(),
                  objects[i]["centroid"][axis].get<double>(), 1e-6);
    }
  }
  ExpectCleanFailure(RunCli("pick --left " + scene + "/left.png --right " + scene +
                            "/right.png --calib " + scene + "/calib.yml --out " + Path("o2.json") +
                            " --robot dryrun:" + Path("p2.jsonl")),
                     "--robot needs --frame", {"o2.json", "p2.jsonl"});
}

TEST_F(RobotCli, ServeReadsTheImagesAgainOnEveryTrigger) {
  // The capture command alternates two rendered scenes (same cameras) into cur/; the third
  // capture fails: that cycle publishes a sensing error and the loop goes on.
  const std::string frame = IdentityFrame();
  ASSERT_EQ(RunCli("render --seed 5 --objects 3 --out " + Path("a")).exit_code, 0);
  ASSERT_EQ(RunCli("render --seed 5 --objects 5 --out " + Path("b")).exit_code, 0);
  fs::create_directories(Path("cur"));
  std::ofstream(Path("capture.sh"))
      << "n=$(cat " << Path("count") << " 2>/dev/null || echo 0); n=$((n+1)); echo $n > "
      << Path("count") << "\n"
      << "case $n in 1) s=a;; 2) s=b;; 3) exit 3;; *) s=a;; esac\n"
      << "cp " << Path("") << "$s/left.png " << Path("cur/left.png") << " && cp " << Path("")
      << "$s/right.png " << Path("cur/right.png") << "\n";
  const CliResult served = RunCli(
      "serve --left " + Path("cur/left.png") + " --right " + Path("cur/right.png") + " --calib " +
      Path("a/calib.yml") + " --capture 'sh " + Path("capture.sh") + "' --frame " + frame +
      " --robot dryrun:" + Path("picks.jsonl") + " --cycles 4 --period 0 --report " +
      Path("report.json"));
  ASSERT_EQ(served.exit_code, 0) << served.output;
  std::vector<nlohmann::json> cycles;
  for (const nlohmann::json& line : ReadJsonLines(Path("picks.jsonl"))) {
    if (line["type"] == "cycle") cycles.push_back(line);
  }
  ASSERT_EQ(cycles.size(), 4u);
  EXPECT_EQ(cycles[0]["status"], 2);
  EXPECT_EQ(cycles[1]["status"], 2);
  EXPECT_EQ(cycles[2]["status"], -1) << "capture failed";
  EXPECT_NE(cycles[2]["error"].get<std::string>().find("--capture"), std::string::npos);
  EXPECT_EQ(cycles[3]["status"], 2);
  std::ifstream truth_a(Path("a/truth.json")), truth_b(Path("b/truth.json"));
  const auto parts_a = nlohmann::json::parse(truth_a)["objects"].size();
  const auto parts_b = nlohmann::json::parse(truth_b)["objects"].size();
  ASSERT_NE(parts_a, parts_b);
  EXPECT_EQ(cycles[0]["poses"], parts_a) << "scene a";
  EXPECT_EQ(cycles[1]["poses"], parts_b) << "scene b, read again";
  EXPECT_EQ(cycles[3]["poses"], parts_a);
  std::ifstream report_file(Path("report.json"));
  EXPECT_EQ(nlohmann::json::parse(report_file)["sense_errors"], 1);
}

}  // namespace
