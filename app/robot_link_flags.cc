#include "app/robot_link_flags.h"

#include "api/matcher_settings.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <stdexcept>

namespace hnnstereo::app {
namespace {

std::atomic<bool> g_stop_requested{false};

// The link's option fields and the flags that set them (errors name the flags).
const api::OptionNameTable& LinkOptionNameTable() {
  static const api::OptionNameTable table = {
      {"max_speed_fraction", "--max-speed"}, {"max_reach_mm", "--max-reach"},
      {"speed_fraction", "--speed"},         {"approach_mm", "--approach"},
      {"retreat_mm", "--retreat"},           {"max_poses", "--max-poses"},
      {"io_timeout", "--io-timeout"},        {"heartbeat_period", "--heartbeat"}};
  return table;
}

void ThrowIfProblem(const std::string& problem) {
  if (!problem.empty()) throw std::invalid_argument(api::InOptionNames(problem, LinkOptionNameTable()));
}

extern "C" void OnStopSignal(int) { g_stop_requested.store(true); }

const char* AckName(robot::AckKind ack) {
  switch (ack) {
    case robot::AckKind::kAcknowledged: return "acknowledged";
    case robot::AckKind::kTimeout: return "ack timeout";
    case robot::AckKind::kStop: return "stop";
    case robot::AckKind::kPeerLost: return "peer lost";
  }
  return "?";
}

}  // namespace

void RobotLinkFlags::AddTo(CLI::App* cmd, const std::string& robot_help, bool frame_required) {
  cmd->add_option("--robot", robot, robot_help);
  auto* frame_option =
      cmd->add_option("--frame", frame,
                      "FRAME.yml: robot_from_world (4x4), workspace_min/max (mm, robot frame), "
                      "rms_mm (see 'hnnstereo robot fit-frame')");
  if (frame_required) frame_option->required();
  cmd->add_option("--io-timeout", io_timeout_ms, "One request/response on the wire (ms)")
      ->capture_default_str();
  cmd->add_option("--heartbeat", heartbeat_ms, "Heartbeat period (ms; Modbus register 10)")
      ->capture_default_str();
  cmd->add_option("--ack-timeout", ack_timeout_s,
                  "Wait this long for the robot side to acknowledge a result (s)")
      ->capture_default_str();
  max_reach_option =
      cmd->add_option("--max-reach", max_reach_mm,
                      "Safety gate: refuse poses farther than this from the robot base (mm; "
                      "default FRAME.yml's max_reach_mm when it has one)")
          ->capture_default_str();
  cmd->add_option("--max-speed", max_speed, "Safety gate: speeds above this fraction are clamped")
      ->capture_default_str();
  cmd->add_option("--speed", planning.speed_fraction, "Requested speed (fraction of maximum)")
      ->capture_default_str();
  cmd->add_option("--approach", planning.approach_mm, "Approach from this far above (mm)")
      ->capture_default_str();
  cmd->add_option("--retreat", planning.retreat_mm, "Lift this far after gripping (mm)")
      ->capture_default_str();
  cmd->add_option("--max-poses", max_poses, "Poses published per cycle, tallest first (1-64)")
      ->capture_default_str();
}

std::unique_ptr<robot::RobotLink> RobotLinkFlags::Open(robot::RobotFrame* frame_out) const {
  if (frame.empty()) {
    throw std::invalid_argument("--robot needs --frame FRAME.yml (robot_from_world); make one "
                                "with 'hnnstereo robot fit-frame' or 'robot thesis-frame'");
  }
  return OpenWithFrame(frame_out);
}

std::unique_ptr<robot::RobotLink> RobotLinkFlags::OpenForCellCommands() const {
  return OpenWithFrame(nullptr);
}

std::unique_ptr<robot::RobotLink> RobotLinkFlags::OpenWithFrame(robot::RobotFrame* frame_out) const {
  robot::ParseLinkUri(robot);  // a bad URI fails before any file is read
  ThrowIfProblem(planning.Check());
  if (!(io_timeout_ms >= 1.0) || !(heartbeat_ms >= 1.0) || !(ack_timeout_s > 0.0)) {
    throw std::invalid_argument("--io-timeout, --heartbeat and --ack-timeout must be positive");
  }
  robot::SafetyLimits limits;
  limits.max_reach_mm = max_reach_mm;
  const bool frame_given = !frame.empty();
  if (frame_given) {
    const robot::RobotFrame loaded = robot::LoadRobotFrame(frame);
    limits.workspace_min = loaded.workspace_min;
    limits.workspace_max = loaded.workspace_max;
    const bool reach_given = max_reach_option != nullptr && max_reach_option->count() > 0;
    if (loaded.max_reach_mm && !reach_given) limits.max_reach_mm = *loaded.max_reach_mm;
    if (frame_out != nullptr) *frame_out = loaded;
  }
  limits.max_speed_fraction = max_speed;
  ThrowIfProblem(limits.Check());
  robot::LinkOptions options;
  options.io_timeout = std::chrono::milliseconds(static_cast<long>(io_timeout_ms));
  options.heartbeat_period = std::chrono::milliseconds(static_cast<long>(heartbeat_ms));
  options.max_poses = max_poses;
  ThrowIfProblem(options.Check());
  return robot::OpenLink(robot, robot::SafetyGate(limits, frame_given), options);
}

robot::CellLoopOptions RobotLinkFlags::LoopOptions() const {
  robot::CellLoopOptions options;
  options.ack_timeout = std::chrono::milliseconds(static_cast<long>(ack_timeout_s * 1000.0));
  options.planning = planning;
  return options;
}

nlohmann::json CellLoopReportJson(const robot::CellLoopReport& report) {
  std::vector<double> sorted = report.cycle_ms;
  std::sort(sorted.begin(), sorted.end());
  // Nearest-rank percentile: the smallest value with at least p of the cycles at or below it
  // (3 cycles: p95 is the largest, never the median).
  auto percentile = [&](double p) {
    if (sorted.empty()) return 0.0;
    const auto rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(sorted.size())));
    return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
  };
  const robot::LinkStats& s = report.link;
  return {{"cycles", report.cycles},
          {"poses_published", report.poses_published},
          {"refused", report.refused},
          {"sense_errors", report.sense_errors},
          {"ack_timeouts", report.ack_timeouts},
          {"peer_lost", report.peer_lost},
          {"stopped", report.stopped},
          {"idle_timeout", report.idle_timeout},
          {"cycle_ms", {{"median", percentile(0.5)}, {"p95", percentile(0.95)},
                        {"max", sorted.empty() ? 0.0 : sorted.back()}}},
          {"link", {{"connections", s.connections},
                    {"reconnects", s.reconnects},
                    {"triggers", s.triggers},
                    {"duplicate_triggers", s.duplicate_triggers},
                    {"malformed", s.malformed},
                    {"cycles_published", s.cycles_published},
                    {"poses_sent", s.poses_sent},
                    {"dropped_on_reconnect", s.dropped_on_reconnect},
                    {"transport_refused", s.transport_refused}}}};
}

void PrintCycleLine(const robot::CycleLog& log) {
  // The status code the cell sees (docs/robot.md): 2 result ready, or a negative error code.
  const int status = robot::PublishedStatusCode(log.status);
  std::printf("cycle %d request %u: %d parts, %d sent, %d refused, status %d%s%s, %s, sense %.0f "
              "ms, cycle %.0f ms\n",
              log.cycle, log.request_sequence, log.objects, log.published, log.refused, status,
              log.error.empty() ? "" : " ", log.error.empty() ? "" : ("(" + log.error + ")").c_str(),
              AckName(log.ack), log.sense_ms, log.cycle_ms);
  std::fflush(stdout);
}

const std::atomic<bool>* InstallStopSignals() {
  std::signal(SIGINT, OnStopSignal);
  std::signal(SIGTERM, OnStopSignal);
  std::signal(SIGPIPE, SIG_IGN);  // a vanished peer is an error return, not a kill
  return &g_stop_requested;
}

}  // namespace hnnstereo::app
