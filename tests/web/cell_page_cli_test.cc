// The cell's web page from the command line: `serve --http` sensing a rendered scene every cycle
// (dry-run link), read by a plain HTTP client and by headless Chromium; the token and bind rules
// at start; the cycle time with 50 clients polling the overlay and with clients that never read;
// `view` on one pick result.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>
#include <functional>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../app/cli_runner.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using hnnstereo::testing::CliResult;
using hnnstereo::testing::RunCli;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// `hnnstereo ARGUMENTS` running in the background, stdout and stderr into a log file.
class BackgroundCli {
 public:
  BackgroundCli(const std::string& arguments, std::string log) : log_(std::move(log)) {
    const std::string command = std::string("exec ") + HNNSTEREO_BINARY + " " + arguments;
    pid_ = fork();
    if (pid_ == 0) {
      const int fd = open(log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      dup2(fd, 1);
      dup2(fd, 2);
      execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~BackgroundCli() {
    if (pid_ > 0 && !exited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  std::string Output() const { return ReadFile(log_); }
  /// The rest of the first output line starting with `prefix`, waiting up to `timeout`.
  std::optional<std::string> WaitForLine(const std::string& prefix, std::chrono::seconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      std::istringstream lines(Output());
      for (std::string line; std::getline(lines, line);) {
        if (line.rfind(prefix, 0) == 0) return line.substr(prefix.size());
      }
      if (Exited()) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return std::nullopt;
  }
  bool Exited() {
    if (exited_) return true;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    return exited_;
  }
  /// SIGTERM, then the exit code (waits up to `timeout`, then SIGKILL and -1).
  int Stop(std::chrono::seconds timeout = std::chrono::seconds(120)) {
    if (!Exited()) kill(pid_, SIGTERM);
    const auto deadline = Clock::now() + timeout;
    while (!Exited() && Clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (!Exited()) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
      exited_ = true;
    }
    return exit_code_;
  }

 private:
  std::string log_;
  pid_t pid_ = -1;
  bool exited_ = false;
  int exit_code_ = -1;
};

int PortOf(const std::string& url) {
  const std::smatch match = [&] {
    std::smatch m;
    std::regex_search(url, m, std::regex(R"re(:(\d+)/)re"));
    return m;
  }();
  return match.empty() ? -1 : std::stoi(match[1]);
}

std::string IdentityFrame(const std::string& dir) {
  std::ofstream(dir + "/touched.csv") << "world_x,world_y,world_z,robot_x,robot_y,robot_z\n"
                                         "0,0,0,0,0,0\n100,0,0,100,0,0\n0,100,0,0,100,0\n"
                                         "0,0,50,0,0,50\n";
  const CliResult fit = RunCli("robot fit-frame --points " + dir + "/touched.csv --out " + dir +
                               "/frame.yml --workspace-min -1000,-1000,-10 "
                               "--workspace-max 1000,1000,500");
  EXPECT_EQ(fit.exit_code, 0) << fit.output;
  return dir + "/frame.yml";
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

bool HaveChromium() { return std::system("command -v chromium > /dev/null 2>&1") == 0; }

// One `serve --http` on the rendered scene of seed 100 for the whole suite: it senses the pair
// on every cycle (dry-run link: the next trigger comes at once).
class CellPageCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ =
        (fs::temp_directory_path() / ("hnnstereo_cell_page_" + std::to_string(getpid()))).string();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const CliResult rendered = RunCli("render --seed 100 --out " + dir_ + "/scene");
    ASSERT_EQ(rendered.exit_code, 0) << rendered.output;
    const std::string scene = dir_ + "/scene";
    const std::string pair = " --left " + scene + "/left.png --right " + scene +
                             "/right.png --calib " + scene + "/calib.yml";
    const CliResult picked = RunCli("pick" + pair + " --out " + dir_ + "/objects.json --quiet");
    ASSERT_EQ(picked.exit_code, 0) << picked.output;
    const std::string frame = IdentityFrame(dir_);
    serve_ = new BackgroundCli("serve" + pair + " --frame " + frame + " --robot dryrun:" + dir_ +
                                   "/picks.jsonl --http 127.0.0.1:0",
                               dir_ + "/serve.log");
    const auto url = serve_->WaitForLine("http: ", std::chrono::seconds(120));
    ASSERT_TRUE(url) << serve_->Output();
    url_ = *url;
    port_ = PortOf(url_);
    ASSERT_GT(port_, 0) << url_;
  }
  static void TearDownTestSuite() {
    if (serve_ != nullptr) {
      const int code = serve_->Stop();
      EXPECT_EQ(code, 0) << serve_->Output();
      delete serve_;
      serve_ = nullptr;
    }
    fs::remove_all(dir_);
  }
  void SetUp() override {
    if (serve_ == nullptr || port_ <= 0) GTEST_SKIP() << "serve did not start";
  }

  static nlohmann::json Get(const std::string& path) {
    httplib::Client client("127.0.0.1", port_);
    client.set_read_timeout(30, 0);
    auto response = client.Get(path.c_str());
    if (!response || response->status != 200) return nullptr;
    return nlohmann::json::parse(response->body);
  }
  static int CyclesDone() {
    const nlohmann::json status = Get("/api/status");
    return status.is_null() ? 0 : status["counters"]["cycles"].get<int>();
  }
  static void WaitForCycles(int cycles, std::chrono::seconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (CyclesDone() < cycles && Clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  /// The cycle times (ms) of the next `count` whole cycles (the one running now is skipped).
  static std::vector<double> NextCycleTimes(int count) {
    const int first = CyclesDone() + 2;
    WaitForCycles(first + count - 1, std::chrono::seconds(60 + 20 * count));
    std::vector<double> times;
    const nlohmann::json cycles = Get("/api/cycles");  // kept: the loop below refers into it
    if (cycles.is_null()) return times;
    for (const nlohmann::json& cycle : cycles["cycles"]) {
      const int n = cycle["cycle"].get<int>();
      if (n >= first && n < first + count) times.push_back(cycle["cycle_ms"].get<double>());
    }
    return times;
  }
  static nlohmann::json ObjectsOfPick() {
    return nlohmann::json::parse(ReadFile(dir_ + "/objects.json"))["objects"];
  }

  static std::string dir_, url_;
  static int port_;
  static BackgroundCli* serve_;
};
std::string CellPageCli::dir_, CellPageCli::url_;
int CellPageCli::port_ = -1;
BackgroundCli* CellPageCli::serve_ = nullptr;

TEST_F(CellPageCli, StatusReportsTheCyclesAndTheLinkAndObjectsAreThoseOfPick) {
  WaitForCycles(1, std::chrono::seconds(120));
  const nlohmann::json status = Get("/api/status");
  ASSERT_FALSE(status.is_null());
  EXPECT_EQ(status["mode"], "serve");
  EXPECT_GE(status["counters"]["cycles"].get<int>(), 1);
  EXPECT_EQ(status["counters"]["sense_errors"], 0);
  EXPECT_EQ(status["link"]["transport"], "dryrun:" + dir_ + "/picks.jsonl");
  EXPECT_GE(status["link"]["cycles_published"].get<int>(), 1);
  EXPECT_GE(status["link"]["last_request_sequence"].get<int>(), 1);
  EXPECT_TRUE(status["outlines"].get<bool>());
  const nlohmann::json picked = ObjectsOfPick();
  ASSERT_GE(picked.size(), 2u);
  const nlohmann::json served = Get("/api/objects");
  ASSERT_FALSE(served.is_null());
  ASSERT_EQ(served["objects"].size(), picked.size());
  EXPECT_EQ(served["units"], "mm");
  for (std::size_t i = 0; i < picked.size(); ++i) {
    EXPECT_EQ(served["objects"][i]["id"], picked[i]["id"]);
    EXPECT_NEAR(served["objects"][i]["height"].get<double>(), picked[i]["height"].get<double>(),
                0.5);
    EXPECT_EQ(status["parts"][i]["pick"], "sent") << status["parts"][i].dump();
  }
  EXPECT_FALSE(Get("/api/cycles")["cycles"].empty());
}

TEST_F(CellPageCli, HeadlessChromiumShowsEveryPartAndTheOverlay) {
  if (!HaveChromium()) {
    GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it for this test)";
  }
  WaitForCycles(1, std::chrono::seconds(120));
  const std::string profile = dir_ + "/chromium-profile";
  const std::string chromium =
      "timeout 180 chromium --headless --no-sandbox --disable-gpu "
      "--disable-dev-shm-usage --no-first-run --user-data-dir=" +
      profile + " --virtual-time-budget=15000 ";
  const std::string dom_path = dir_ + "/dom.html";
  ASSERT_EQ(std::system((chromium + "--dump-dom " + url_ + " > " + dom_path + " 2> " + dir_ +
                         "/chromium.log")
                            .c_str()),
            0)
      << ReadFile(dir_ + "/chromium.log");
  const std::string dom = ReadFile(dom_path);
  EXPECT_NE(dom.find("data-ready=\"1\""), std::string::npos) << "the page never rendered";
  EXPECT_TRUE(
      std::regex_search(dom, std::regex(R"re(<img[^>]*id="overlay"[^>]*data-loaded="1")re")))
      << "the overlay image did not load";
  std::map<int, double> rows;
  const std::regex row(R"re(<tr[^>]*class="part"[^>]*>)re");
  for (auto it = std::sregex_iterator(dom.begin(), dom.end(), row); it != std::sregex_iterator();
       ++it) {
    const std::string tag = it->str();
    std::smatch id, height;
    ASSERT_TRUE(std::regex_search(tag, id, std::regex(R"re(data-id="(\d+)")re"))) << tag;
    ASSERT_TRUE(std::regex_search(tag, height, std::regex(R"re(data-height="([-0-9.eE+]+)")re")))
        << tag;
    rows[std::stoi(id[1])] = std::stod(height[1]);
  }
  const nlohmann::json picked = ObjectsOfPick();
  EXPECT_EQ(rows.size(), picked.size()) << dom;
  const auto truth = nlohmann::json::parse(ReadFile(dir_ + "/scene/truth.json"))["objects"];
  EXPECT_EQ(rows.size(), truth.size()) << "every part of the scene has its row";
  for (const nlohmann::json& object : picked) {
    const int id = object["id"].get<int>();
    ASSERT_TRUE(rows.count(id)) << "no row for part " << id;
    EXPECT_NEAR(rows[id], object["height"].get<double>(), 0.5) << "part " << id;
  }
  // The screenshot is kept as the test's artifact.
  fs::create_directories(HNNSTEREO_ARTIFACT_DIR);
  const std::string shot = std::string(HNNSTEREO_ARTIFACT_DIR) + "/cell_page.png";
  fs::remove(shot);
  // The page's content is asserted above from the DOM; the screenshot is an artifact. Headless
  // chromium's --screenshot has hung here once for the whole `timeout` on a loaded 2-core
  // machine (the same command took 24 s alone), so it gets a second try before it counts.
  const std::string screenshot = chromium + "--hide-scrollbars --window-size=1360,1000 --screenshot=" +
                                 shot + " " + url_ + " >> " + dir_ + "/chromium.log 2>&1";
  int status = std::system(screenshot.c_str());
  if (status != 0) status = std::system(screenshot.c_str());
  ASSERT_EQ(status, 0) << ReadFile(dir_ + "/chromium.log");
  EXPECT_GT(fs::file_size(shot), 10000u) << shot;
  std::printf("screenshot: %s\n", shot.c_str());
}

// The cycle time with a load on the page against without it: rounds of a few cycles without,
// then a few with, so that the other work on the (shared, two-core) machine drifts into both
// alike; medians, so one preempted cycle does not decide. Up to three attempts: on a loaded
// machine one measurement can be off by more than 10 % by itself, a page that really slowed the
// loop fails all three.
struct LoadComparison {
  double median_without_ms = 0.0, median_with_ms = 0.0, ratio = 0.0;
};
template <typename StartLoad, typename StopLoad>
LoadComparison CompareCycleTimes(const std::function<std::vector<double>(int)>& next_cycle_times,
                                 StartLoad start_load, StopLoad stop_load) {
  constexpr int kRounds = 3, kCyclesPerPhase = 3;
  std::vector<double> without, with;
  for (int round = 0; round < kRounds; ++round) {
    const auto quiet = next_cycle_times(kCyclesPerPhase);
    without.insert(without.end(), quiet.begin(), quiet.end());
    start_load();
    const auto loaded = next_cycle_times(kCyclesPerPhase);
    with.insert(with.end(), loaded.begin(), loaded.end());
    stop_load();
  }
  LoadComparison result{Median(without), Median(with), 0.0};
  if (result.median_without_ms > 0.0)
    result.ratio = result.median_with_ms / result.median_without_ms;
  return result;
}

// The acceptance figure: 50 clients polling /api/overlay.png as fast as they can.
TEST_F(CellPageCli, FiftyClientsPollingTheOverlayKeepTheCycleTime) {
  WaitForCycles(1, std::chrono::seconds(120));
  std::atomic<bool> stop{false};
  std::atomic<long> served{0};
  std::vector<std::thread> clients;
  auto start_clients = [&] {
    stop = false;
    for (int k = 0; k < 50; ++k) {
      clients.emplace_back([&] {
        // On a cell the browsers run on other machines; here the clients share the cell's two
        // cores, so they yield to it like the page's own threads do (nice 19), or the test would
        // measure the clients' CPU rather than the page's effect on the loop.
        setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 19);
        httplib::Client client("127.0.0.1", port_);
        client.set_read_timeout(30, 0);
        while (!stop) {
          auto response = client.Get("/api/overlay.png");
          if (response && response->status == 200 && !response->body.empty()) ++served;
        }
      });
    }
  };
  auto stop_clients = [&] {
    stop = true;
    for (std::thread& client : clients) client.join();
    clients.clear();
  };
  LoadComparison best;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    const auto start = Clock::now();
    served = 0;
    const LoadComparison result = CompareCycleTimes(NextCycleTimes, start_clients, stop_clients);
    std::printf(
        "attempt %d: cycle time median %.0f ms without clients, %.0f ms with 50 clients "
        "polling /api/overlay.png (%ld images served, %.1f s): ratio %.3f\n",
        attempt, result.median_without_ms, result.median_with_ms, served.load(),
        std::chrono::duration<double>(Clock::now() - start).count(), result.ratio);
    std::fflush(stdout);
    ASSERT_GT(result.ratio, 0.0) << "no cycle times";
    EXPECT_GT(served.load(), 50) << "the clients were not served";
    if (attempt == 1 || result.ratio < best.ratio) best = result;
    if (best.ratio <= 1.10) break;
  }
  EXPECT_LE(best.ratio, 1.10) << "50 clients slowed the cell loop";
}

TEST_F(CellPageCli, ClientsThatNeverReadDoNotSlowTheLoop) {
  WaitForCycles(1, std::chrono::seconds(120));
  std::vector<int> stuck;
  auto start_stuck = [&] {
    for (int k = 0; k < 10; ++k) {
      const int fd = socket(AF_INET, SOCK_STREAM, 0);
      const int small = 4096;
      setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
      sockaddr_in address{};
      address.sin_family = AF_INET;
      address.sin_port = htons(static_cast<std::uint16_t>(port_));
      address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
      if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
        close(fd);
        continue;
      }
      // Many requests in a row, none of the answers ever read.
      std::string requests;
      for (int r = 0; r < 20; ++r) requests += "GET /api/overlay.png HTTP/1.1\r\nHost: x\r\n\r\n";
      (void)!write(fd, requests.data(), requests.size());
      stuck.push_back(fd);
    }
  };
  auto stop_stuck = [&] {
    for (int fd : stuck) close(fd);
    stuck.clear();
  };
  LoadComparison best;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    const LoadComparison result = CompareCycleTimes(NextCycleTimes, start_stuck, stop_stuck);
    std::printf(
        "attempt %d: cycle time median %.0f ms without, %.0f ms with 10 clients that "
        "never read: ratio %.3f\n",
        attempt, result.median_without_ms, result.median_with_ms, result.ratio);
    std::fflush(stdout);
    ASSERT_GT(result.ratio, 0.0) << "no cycle times";
    if (attempt == 1 || result.ratio < best.ratio) best = result;
    if (best.ratio <= 1.10) break;
  }
  EXPECT_LE(best.ratio, 1.10);
  EXPECT_FALSE(Get("/api/status").is_null()) << "the page still answers";
}

class CellPageStart : public hnnstereo::testing::CliTest {
 protected:
  std::string Replay() {
    std::ofstream(Path("objects.json"))
        << R"({"units": "mm", "objects": [{"id": 1, "centroid": [10, 20, 30], "height": 30,)"
        << R"( "yaw_deg": 5, "points": 40}]})";
    return " --replay " + Path("objects.json") + " --frame " + IdentityFrame(dir_.string()) +
           " --robot dryrun:" + Path("picks.jsonl");
  }
};

TEST_F(CellPageStart, ANonLoopbackBindWithoutATokenIsRefusedAtStart) {
  const std::string replay = Replay();
  for (const char* address : {"0.0.0.0:0", "[::]:0"}) {
    const CliResult refused = RunCli("serve" + replay + " --cycles 1 --http " + address);
    EXPECT_NE(refused.exit_code, 0) << refused.output;
    EXPECT_NE(refused.output.find("hnnstereo: error: --http"), std::string::npos) << refused.output;
    EXPECT_NE(refused.output.find("--http-token"), std::string::npos) << refused.output;
    EXPECT_FALSE(fs::exists(Path("picks.jsonl"))) << "the link opened before the check";
  }
  // An address in use: refused before the link opens too.
  const int holder = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(holder, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(listen(holder, 1), 0);
  socklen_t length = sizeof address;
  getsockname(holder, reinterpret_cast<sockaddr*>(&address), &length);
  const CliResult in_use = RunCli(
      "serve" + replay + " --cycles 1 --http 127.0.0.1:" + std::to_string(ntohs(address.sin_port)));
  close(holder);
  EXPECT_NE(in_use.exit_code, 0) << in_use.output;
  EXPECT_NE(in_use.output.find("hnnstereo: error: --http: cannot listen"), std::string::npos)
      << in_use.output;
  EXPECT_FALSE(fs::exists(Path("picks.jsonl"))) << "the link opened before the page failed";
  for (const char* bad : {"--http 127.0.0.1", "--http 127.0.0.1:99999", "--http-token t"}) {
    const CliResult refused = RunCli("serve" + replay + " --cycles 1 " + bad);
    EXPECT_NE(refused.exit_code, 0) << bad << refused.output;
    EXPECT_NE(refused.output.find("hnnstereo: error: "), std::string::npos) << refused.output;
  }
}

TEST_F(CellPageStart, WithATokenEveryRequestWithoutItGets401) {
  // A vision-server link with no robot connected: the loop waits for a trigger (publishing the
  // link's state) until stopped.
  std::ofstream(Path("objects.json"))
      << R"({"units": "mm", "objects": [{"id": 1, "centroid": [10, 20, 30], "height": 30,)"
      << R"( "yaw_deg": 5, "points": 40}]})";
  BackgroundCli serve("serve --replay " + Path("objects.json") + " --frame " +
                          IdentityFrame(dir_.string()) +
                          " --robot vision-server://127.0.0.1:0 --http 0.0.0.0:0 "
                          "--http-token cell-7f3a",
                      Path("serve.log"));
  const auto url = serve.WaitForLine("http: ", std::chrono::seconds(60));
  ASSERT_TRUE(url) << serve.Output();
  EXPECT_NE(url->find("token required"), std::string::npos);
  EXPECT_EQ(url->find("cell-7f3a"), std::string::npos) << "the token is not printed";
  httplib::Client client("127.0.0.1", PortOf(*url));
  for (const char* path : {"/", "/api/status", "/api/objects", "/api/cycles", "/api/left.png",
                           "/api/overlay.png", "/nope"}) {
    auto refused = client.Get(path);
    ASSERT_TRUE(refused) << path;
    EXPECT_EQ(refused->status, 401) << path;
  }
  auto status = client.Get("/api/status", {{"Authorization", "Bearer cell-7f3a"}});
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  const nlohmann::json link = nlohmann::json::parse(status->body)["link"];
  EXPECT_EQ(link["peer_connected"], false) << link.dump();
  EXPECT_NE(link["transport"].get<std::string>().find("vision-server://"), std::string::npos);
  auto objects = client.Get("/api/objects?token=cell-7f3a");
  ASSERT_TRUE(objects);
  EXPECT_EQ(objects->status, 404) << "no trigger yet: nothing sensed";
  auto missing = client.Get("/api/nope?token=cell-7f3a");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
  auto image = client.Get("/api/overlay.png?token=cell-7f3a");
  ASSERT_TRUE(image);
  EXPECT_EQ(image->status, 404) << "no image yet";
  if (HaveChromium()) {
    // The page opened as /?token=T passes the token on to its API requests.
    const std::string dom = Path("dom.html");
    ASSERT_EQ(
        std::system(("timeout 180 chromium --headless --no-sandbox --disable-gpu "
                     "--disable-dev-shm-usage --no-first-run --user-data-dir=" +
                     Path("profile") + " --virtual-time-budget=8000 --dump-dom 'http://127.0.0.1:" +
                     std::to_string(PortOf(*url)) + "/?token=cell-7f3a' > " + dom + " 2> /dev/null")
                        .c_str()),
        0);
    const std::string page = ReadFile(dom);
    EXPECT_NE(page.find("data-ready=\"1\""), std::string::npos) << page;
    EXPECT_NE(page.find("vision-server://"), std::string::npos) << "the link's row";
  }
  EXPECT_EQ(serve.Stop(), 0) << serve.Output();
}

TEST_F(CellPageStart, ViewShowsOnePickResult) {
  ASSERT_EQ(RunCli("render --seed 3 --objects 3 --out " + Path("s")).exit_code, 0);
  const CliResult picked =
      RunCli("pick --left " + Path("s/left.png") + " --right " + Path("s/right.png") + " --calib " +
             Path("s/calib.yml") + " --out " + Path("o.json") + " --quiet");
  ASSERT_EQ(picked.exit_code, 0) << picked.output;
  BackgroundCli view(
      "view --objects " + Path("o.json") + " --left " + Path("s/left.png") + " --duration 60",
      Path("view.log"));
  const auto url = view.WaitForLine("http: ", std::chrono::seconds(60));
  ASSERT_TRUE(url) << view.Output();
  httplib::Client client("127.0.0.1", PortOf(*url));
  auto objects = client.Get("/api/objects");
  ASSERT_TRUE(objects);
  ASSERT_EQ(objects->status, 200);
  EXPECT_EQ(objects->body, ReadFile(Path("o.json"))) << "served exactly as OBJECTS.json";
  auto status = client.Get("/api/status");
  ASSERT_TRUE(status);
  const nlohmann::json json = nlohmann::json::parse(status->body);
  EXPECT_EQ(json["mode"], "view");
  EXPECT_TRUE(json["outlines"].get<bool>()) << "P1 from the calib OBJECTS.json names";
  for (const nlohmann::json& part : json["parts"]) EXPECT_TRUE(part.contains("outline_px"));
  auto overlay = client.Get("/api/overlay.png");
  ASSERT_TRUE(overlay);
  EXPECT_EQ(overlay->status, 200);
  EXPECT_EQ(view.Stop(), 0) << view.Output();
  EXPECT_NE(
      RunCli("view --objects " + Path("missing.json") + " --left " + Path("s/left.png")).exit_code,
      0);
}

}  // namespace
