// The cell page's HTTP server against a plain HTTP client (cpp-httplib's): routes, 404/405/503,
// the token rule, the bind rule, OBJECTS.json served exactly, PNGs, and that the publishing side
// is not held up by a client that never reads.
#include "web/cell_page_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "robot/cell_loop.h"
#include "vision/stereo/lens_distortion.h"

namespace hnnstereo::web {
namespace {

// A camera 700 mm above the table looking straight down (f = 600 px, 640 x 480).
calib::ProjectionMatrix DownwardCamera() {
  Eigen::Matrix3d K;
  K << 600, 0, 320, 0, 600, 240, 0, 0, 1;
  Eigen::Matrix<double, 3, 4> Rt;
  // x_cam = X, y_cam = -Y, z_cam = 700 - Z.
  Rt << 1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 700;
  return K * Rt;
}

nlohmann::json TwoParts() {
  return nlohmann::json::parse(R"({
    "units": "mm",
    "objects": [
      {"id": 1, "centroid": [20.0, 10.0, 80.5], "height": 80.5, "yaw_deg": 30.0, "points": 120,
       "top_rectangle": {"centre": [20.0, 10.0], "length": 60.0, "width": 30.0, "yaw_deg": 30.0},
       "round": false},
      {"id": 2, "centroid": [-60.0, -40.0, 25.25], "height": 25.25, "yaw_deg": -10.0,
       "points": 80, "round": true, "top_circle": {"centre": [-60.0, -40.0], "radius": 20.0}}
    ],
    "left": "left.png"
  })");
}

class CellPageServerTest : public ::testing::Test {
 protected:
  void PublishScene() {
    CellStatusRecorder recorder(&board_, "view");
    cv::Mat left(480, 640, CV_8UC1, cv::Scalar(90));
    cv::rectangle(left, {300, 200, 60, 40}, cv::Scalar(200), cv::FILLED);
    recorder.SetSensed(TwoParts(), left, DownwardCamera());
    recorder.PublishNow();
  }
  CellStatusBoard board_;
};

TEST_F(CellPageServerTest, ServesThePageTheApiAndExactObjects) {
  PublishScene();
  CellPageServer server(board_, {});
  ASSERT_GT(server.port(), 0);
  EXPECT_EQ(server.Url(), "http://127.0.0.1:" + std::to_string(server.port()) + "/");
  httplib::Client client("127.0.0.1", server.port());

  auto page = client.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("<table id=\"parts\""), std::string::npos);
  // Self-contained: nothing loaded from elsewhere (the SVG namespace URI is a name, not a load).
  for (const char* external : {"src=\"http", "href=\"http", "src=\"//", "href=\"//", "url(",
                               "@import", "<link", "<script src", "https://"}) {
    EXPECT_EQ(page->body.find(external), std::string::npos) << external;
  }

  auto objects = client.Get("/api/objects");
  ASSERT_TRUE(objects);
  EXPECT_EQ(objects->status, 200);
  EXPECT_EQ(objects->body, TwoParts().dump(2) + "\n");

  auto status = client.Get("/api/status");
  ASSERT_TRUE(status);
  ASSERT_EQ(status->status, 200);
  const nlohmann::json json = nlohmann::json::parse(status->body);
  EXPECT_EQ(json["mode"], "view");
  ASSERT_EQ(json["parts"].size(), 2u);
  EXPECT_EQ(json["parts"][0]["id"], 1);
  EXPECT_DOUBLE_EQ(json["parts"][1]["height"].get<double>(), 25.25);
  EXPECT_EQ(json["parts"][0]["pick"], "no link");
  EXPECT_EQ(json["parts"][0]["outline_px"].size(), 4u);
  EXPECT_EQ(json["parts"][1]["outline_px"].size(), 36u);
  // Part 1's top at z = 80.5: depth 619.5, centre (20, 10) -> u = 320 + 600 * 20 / 619.5.
  EXPECT_NEAR(json["parts"][0]["centre_px"][0].get<double>(), 320 + 600 * 20 / 619.5, 0.06);
  EXPECT_NEAR(json["parts"][0]["centre_px"][1].get<double>(), 240 - 600 * 10 / 619.5, 0.06);
  EXPECT_TRUE(json["link"].is_null());
  EXPECT_EQ(json["image"]["width"], 640);

  for (const char* path : {"/api/left.png", "/api/overlay.png"}) {
    auto png = client.Get(path);
    ASSERT_TRUE(png) << path;
    EXPECT_EQ(png->status, 200) << path;
    EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
    const std::vector<unsigned char> bytes(png->body.begin(), png->body.end());
    const cv::Mat decoded = cv::imdecode(bytes, cv::IMREAD_COLOR);
    EXPECT_EQ(decoded.cols, 640) << path;
    EXPECT_EQ(decoded.rows, 480) << path;
  }
  auto cycles = client.Get("/api/cycles");
  ASSERT_TRUE(cycles);
  EXPECT_EQ(nlohmann::json::parse(cycles->body)["cycles"].size(), 0u);
}

TEST_F(CellPageServerTest, UnknownPathsAre404AndWritesAre405) {
  PublishScene();
  CellPageServer server(board_, {});
  httplib::Client client("127.0.0.1", server.port());
  for (const char* path : {"/nope", "/api", "/api/status/x", "/api/objects.json", "/index.html"}) {
    auto response = client.Get(path);
    ASSERT_TRUE(response) << path;
    EXPECT_EQ(response->status, 404) << path;
    EXPECT_NE(response->body.find("404"), std::string::npos) << path;
  }
  auto post = client.Post("/api/status", "{}", "application/json");
  ASSERT_TRUE(post);
  EXPECT_EQ(post->status, 405);
  auto del = client.Delete("/api/objects");
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 405);
}

TEST_F(CellPageServerTest, NothingPublishedIs503AndNoImageIs404) {
  CellPageServer server(board_, {});
  httplib::Client client("127.0.0.1", server.port());
  auto status = client.Get("/api/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 503);
  CellStatusRecorder recorder(&board_, "serve");
  recorder.SetSensed(TwoParts(), {}, std::nullopt);  // replayed objects: no image
  recorder.PublishNow();
  auto overlay = client.Get("/api/overlay.png");
  ASSERT_TRUE(overlay);
  EXPECT_EQ(overlay->status, 404);
  auto objects = client.Get("/api/objects");
  ASSERT_TRUE(objects);
  EXPECT_EQ(objects->status, 200);
}

TEST_F(CellPageServerTest, ATokenIsRequiredOnEveryRequest) {
  PublishScene();
  CellPageOptions options;
  options.token = "s3cret-token";
  CellPageServer server(board_, options);
  httplib::Client client("127.0.0.1", server.port());
  for (const char* path : {"/", "/api/status", "/api/objects", "/api/overlay.png", "/nope"}) {
    auto refused = client.Get(path);
    ASSERT_TRUE(refused) << path;
    EXPECT_EQ(refused->status, 401) << path;
    auto wrong = client.Get(std::string(path) + "?token=s3cret-tokem");
    ASSERT_TRUE(wrong) << path;
    EXPECT_EQ(wrong->status, 401) << path;
  }
  auto by_query = client.Get("/api/status?token=s3cret-token");
  ASSERT_TRUE(by_query);
  EXPECT_EQ(by_query->status, 200);
  auto by_header = client.Get("/api/objects", {{"Authorization", "Bearer s3cret-token"}});
  ASSERT_TRUE(by_header);
  EXPECT_EQ(by_header->status, 200);
  auto wrong_header = client.Get("/api/objects", {{"Authorization", "Bearer s3cret"}});
  ASSERT_TRUE(wrong_header);
  EXPECT_EQ(wrong_header->status, 401);
}

TEST(CellPageOptions, ANonLoopbackBindNeedsAToken) {
  CellStatusBoard board;
  for (const char* address : {"0.0.0.0:0", "[::]:0", "192.168.1.20:8080", "cell-pc:80"}) {
    const CellPageOptions options = ParseHttpAddress(address);
    EXPECT_NE(options.Check().find("--http-token"), std::string::npos) << address;
    EXPECT_THROW(CellPageServer(board, options), std::invalid_argument) << address;
  }
  for (const char* address : {"127.0.0.1:0", "localhost:8080", "[::1]:0", "127.0.0.2:1"}) {
    EXPECT_EQ(ParseHttpAddress(address).Check(), "") << address;
  }
  CellPageOptions with_token = ParseHttpAddress("0.0.0.0:0");
  with_token.token = "t";
  EXPECT_EQ(with_token.Check(), "");
  CellPageServer server(board, with_token);
  httplib::Client client("127.0.0.1", server.port());
  auto refused = client.Get("/api/status");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 401);
}

TEST(CellPageOptions, MalformedAddressesAreRefused) {
  for (const char* address : {"", "127.0.0.1", "127.0.0.1:", "127.0.0.1:http", "h:70000", "h:-1"}) {
    EXPECT_THROW(ParseHttpAddress(address), std::invalid_argument) << address;
  }
  EXPECT_EQ(ParseHttpAddress(":8080").host, "127.0.0.1");
  EXPECT_EQ(ParseHttpAddress("[::1]:8080").port, 8080);
}

// A calibration with lens distortion refers P1 to undistorted pixels; the page shows the image as
// captured, so a part's outline and centre go through the lens (k1 = -0.25 moves a point 190 px
// off centre by about 3 px).
TEST(CellState, OutlinesGoThroughTheLensIntoTheCapturedImagesPixels) {
  CellState state;
  state.left_image = cv::Mat(480, 640, CV_8UC1, cv::Scalar(90));
  state.P1 = DownwardCamera();
  state.objects = nlohmann::json::parse(R"({"objects": [
      {"id": 1, "centroid": [150.0, 100.0, 20.0], "height": 20.0, "yaw_deg": 0.0, "points": 90,
       "round": false, "top_rectangle": {"centre": [150.0, 100.0], "length": 40.0,
                                         "width": 30.0, "yaw_deg": 0.0}}]})");
  const nlohmann::json pinhole = state.PartsJson()[0];
  calib::Intrinsics lens;
  lens.K1 << 600, 0, 320, 0, 600, 240, 0, 0, 1;
  lens.K2 = lens.K1;
  lens.D1 = lens.D2 = {-0.25, 0.08, 0.001, -0.001};
  state.intrinsics = lens;
  const nlohmann::json through_lens = state.PartsJson()[0];
  // The page's pixels are rounded to 0.1 px (both ways).
  auto pixel = [](const nlohmann::json& p) {
    return Eigen::Vector2f(p[0].get<float>(), p[1].get<float>());
  };
  const Eigen::Vector2f centre = pixel(pinhole["centre_px"]);
  const Eigen::Vector2f expected = vision::DistortPoints({centre}, lens.K1, lens.D1).front();
  EXPECT_LT((pixel(through_lens["centre_px"]) - expected).norm(), 0.15);
  EXPECT_GT((pixel(through_lens["centre_px"]) - centre).norm(), 2.0) << "the lens moved it";
  ASSERT_EQ(through_lens["outline_px"].size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    const Eigen::Vector2f corner = pixel(pinhole["outline_px"][k]);
    EXPECT_LT((pixel(through_lens["outline_px"][k]) -
               vision::DistortPoints({corner}, lens.K1, lens.D1).front()).norm(), 0.15);
  }
  EXPECT_FALSE(state.DrawOverlay().empty());
}

TEST(CellStatusRecorder, CountsCyclesKeepsTheLast100AndMarksEachPick) {
  CellStatusBoard board;
  CellStatusRecorder recorder(&board, "serve");
  class NullLink final : public robot::RobotLink {
   public:
    NullLink() : RobotLink(robot::SafetyGate({}, true), {}) {}
    std::string Describe() const override { return "null"; }
    robot::Trigger WaitForTrigger(std::chrono::milliseconds) override { return {}; }
    robot::AckKind WaitForAcknowledge(std::chrono::milliseconds) override { return {}; }
    void SendCellCommand(robot::CellCommand) override {}
    robot::LinkStats Stats() const override { return {}; }

   protected:
    void Send(const robot::CycleResult&) override {}
  } link;
  for (int cycle = 1; cycle <= 130; ++cycle) {
    recorder.SetSensed(TwoParts(), {}, std::nullopt);
    robot::CycleLog log;
    log.cycle = cycle;
    log.request_sequence = static_cast<std::uint32_t>(cycle);
    log.objects = 2;
    log.published = 1;
    log.refused = 1;
    log.cycle_ms = cycle;
    log.picks = {{1, 7, true, ""}, {2, 8, false, "pick pose is outside the workspace box"}};
    if (cycle == 120) {
      log.status = robot::kErrorSensingFailed;
      log.error = "camera gone";
    }
    recorder.RecordCycle(log, link);
  }
  const auto snapshot = board.Latest();
  ASSERT_TRUE(snapshot);
  const nlohmann::json status = nlohmann::json::parse(snapshot->StatusText());
  EXPECT_EQ(status["counters"]["cycles"], 130);
  EXPECT_EQ(status["counters"]["sense_errors"], 1);
  EXPECT_EQ(status["counters"]["refused"], 130);
  EXPECT_EQ(status["last_error"]["cycle"], 120);
  EXPECT_NE(status["last_error"]["message"].get<std::string>().find("camera gone"),
            std::string::npos);
  EXPECT_EQ(status["parts"][0]["pick"], "sent");
  EXPECT_EQ(status["parts"][1]["pick"], "refused");
  EXPECT_EQ(status["parts"][1]["reason"], "pick pose is outside the workspace box");
  EXPECT_EQ(status["link"]["transport"], "null");
  EXPECT_EQ(status["link"]["last_request_sequence"], 130);
  const nlohmann::json cycles = nlohmann::json::parse(snapshot->CyclesText())["cycles"];
  ASSERT_EQ(cycles.size(), 100u);
  EXPECT_EQ(cycles.front()["cycle"], 31);
  EXPECT_EQ(cycles.back()["cycle"], 130);
  // The code the cell sees, as the link and the dry-run lines show it: 2 result ready, or the
  // negative error (never the loop's internal 0).
  EXPECT_EQ(cycles.front()["status"], robot::PublishedStatusCode(0));
  EXPECT_EQ(cycles.front()["status"], 2);
  EXPECT_EQ(cycles[120 - 31]["status"], robot::kErrorSensingFailed);
  EXPECT_EQ(status["last_cycle"]["status"], 2);
}

// A client that asks for the overlay and never reads the answer holds one HTTP thread until the
// write timeout; the publishing side (the loop) never waits for it.
TEST_F(CellPageServerTest, AClientThatNeverReadsDoesNotHoldUpPublishing) {
  CellStatusRecorder recorder(&board_, "serve");
  cv::Mat left(1200, 1600, CV_8UC3);
  cv::randu(left, cv::Scalar::all(0), cv::Scalar::all(255));  // incompressible: a large PNG
  recorder.SetSensed(TwoParts(), left, DownwardCamera());
  recorder.PublishNow();
  CellPageServer server(board_, {});
  std::vector<int> stuck;
  for (int k = 0; k < 4; ++k) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    const int small = 4096;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(server.port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    const std::string request = "GET /api/overlay.png HTTP/1.1\r\nHost: x\r\n\r\n";
    ASSERT_EQ(write(fd, request.data(), request.size()), static_cast<ssize_t>(request.size()));
    stuck.push_back(fd);  // never read
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  double worst_ms = 0.0;
  for (int k = 0; k < 200; ++k) {
    const auto start = std::chrono::steady_clock::now();
    recorder.SetSensed(TwoParts(), left, DownwardCamera());
    recorder.PublishNow();
    worst_ms =
        std::max(worst_ms,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
  }
  EXPECT_LT(worst_ms, 250.0) << "publishing waited for a stuck client";
  // Other clients are still served meanwhile.
  httplib::Client client("127.0.0.1", server.port());
  auto status = client.Get("/api/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  for (int fd : stuck) close(fd);
}

// Clients that connect and never send: on Linux (TCP_DEFER_ACCEPT) they do not reach the
// server's workers for the first 5 s, so a status request right after 200 of them is answered
// at once (without it: 1.5 s behind 8 of them, no answer in 20 s behind 200). After the 5 s
// they are accepted and do queue (read timeout 5 s each); that is not fixed (docs/robot.md).
// `count` loopback connections to `port` that never send anything (fewer if one fails).
std::vector<int> ConnectSilently(int port, int count) {
  std::vector<int> fds;
  for (int k = 0; k < count; ++k) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
      close(fd);
      break;
    }
    fds.push_back(fd);
  }
  return fds;
}

TEST_F(CellPageServerTest, SilentConnectionsDoNotQueueInFrontOfARequest) {
  PublishScene();
  CellPageServer server(board_, {});
  const std::vector<int> silent = ConnectSilently(server.port(), 200);
  ASSERT_EQ(silent.size(), 200u);
  httplib::Client client("127.0.0.1", server.port());
  client.set_read_timeout(3, 0);
  const auto start = std::chrono::steady_clock::now();
  auto status = client.Get("/api/status");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (int fd : silent) close(fd);
  ASSERT_TRUE(status) << "no answer behind 200 silent connections";
  EXPECT_EQ(status->status, 200);
  EXPECT_LT(seconds, 2.0);
}

// After the accept deferral (5 s) the kernel hands the silent connections over anyway. With a
// fixed pool of 8 workers and a 5 s read timeout each of the 200 held a worker in turn: a request
// 8 s after they opened got no answer within 30 s. Now extra workers take them and drop each
// after the 1 s read timeout.
TEST_F(CellPageServerTest, SilentConnectionsPastTheAcceptDeferralDoNotStallARequest) {
  PublishScene();
  CellPageServer server(board_, {});
  const std::vector<int> silent = ConnectSilently(server.port(), 200);
  ASSERT_EQ(silent.size(), 200u);
  std::this_thread::sleep_for(std::chrono::seconds(8));
  httplib::Client client("127.0.0.1", server.port());
  client.set_read_timeout(10, 0);
  const auto start = std::chrono::steady_clock::now();
  auto status = client.Get("/api/status");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (int fd : silent) close(fd);
  ASSERT_TRUE(status) << "no answer 8 s after 200 silent connections opened";
  EXPECT_EQ(status->status, 200);
  EXPECT_LT(seconds, 3.0);
  std::printf("status answered in %.3f s, 8 s after 200 silent connections opened\n", seconds);
}

}  // namespace
}  // namespace hnnstereo::web
