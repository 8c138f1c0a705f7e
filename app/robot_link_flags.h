#pragma once
// The robot link on the command line, shared by `pick --robot`, `serve` and `robot send`:
// the URI, FRAME.yml, the safety limits beyond the frame's workspace, timeouts and pick planning.

#include <CLI/CLI.hpp>
#include <atomic>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "robot/cell_loop.h"
#include "robot/frame_io.h"
#include "robot/link.h"

namespace hnnstereo::app {

struct RobotLinkFlags {
  std::string robot;          ///< URI; empty = no link (pick) or the serve default
  std::string frame;          ///< FRAME.yml
  double io_timeout_ms = 2000.0;
  double heartbeat_ms = 1000.0;
  double ack_timeout_s = 10.0;
  double max_reach_mm = robot::SafetyLimits{}.max_reach_mm;
  CLI::Option* max_reach_option = nullptr;  ///< given: wins over FRAME.yml's max_reach_mm
  double max_speed = robot::SafetyLimits{}.max_speed_fraction;
  int max_poses = 16;
  robot::PickPlanningOptions planning;
  /// Adds --robot, --frame (required or not) and the link options.
  void AddTo(CLI::App* cmd, const std::string& robot_help, bool frame_required);
  /// Loads FRAME.yml and opens the link with the frame's workspace and these limits.
  /// Throws std::invalid_argument / std::runtime_error with a one-line reason.
  std::unique_ptr<robot::RobotLink> Open(robot::RobotFrame* frame_out) const;
  /// The link for cell commands only (home, open, close, stop carry no pose): FRAME.yml is
  /// optional; without it the safety gate refuses every pose (no robot_from_world is known).
  std::unique_ptr<robot::RobotLink> OpenForCellCommands() const;
  robot::CellLoopOptions LoopOptions() const;

 private:
  /// Opens the link; without --frame its gate refuses every pose.
  std::unique_ptr<robot::RobotLink> OpenWithFrame(robot::RobotFrame* frame_out) const;
};

/// The loop report as JSON (serve --report, pick --robot).
nlohmann::json CellLoopReportJson(const robot::CellLoopReport& report);

/// One human-readable line per cycle on stdout (flushed: peers and logs read it live).
void PrintCycleLine(const robot::CycleLog& log);

/// Set by SIGINT/SIGTERM once InstallStopSignals() ran; the cell loop polls it.
const std::atomic<bool>* InstallStopSignals();

}  // namespace hnnstereo::app
