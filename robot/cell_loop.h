#pragma once
// The pick cell's loop (`hnnstereo serve`): wait for a trigger from the robot side, sense, plan
// the picks tallest first, publish them through the link (safety-gated), wait for the
// acknowledge. The sensing is a callback, so this loop knows nothing of images or matching.

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "robot/frame_io.h"
#include "robot/link.h"
#include "robot/pick_planning.h"

namespace hnnstereo::robot {

struct SensedCycle {
  std::vector<SensedObject> objects;  ///< any order; the loop sorts tallest first
  double capture_time_s = 0.0;        ///< steady-clock seconds when the images were taken
};
/// Senses one cycle. Throws (any std::exception) when it cannot; the cycle is then published
/// with status kErrorSensingFailed and the loop goes on.
using SenseFunction = std::function<SensedCycle()>;

/// What happened in one cycle (for the per-cycle log line and the report).
struct CycleLog {
  int cycle = 0;                       ///< 1-based
  std::uint32_t request_sequence = 0;
  int objects = 0;                     ///< sensed
  int published = 0;                   ///< admitted and sent
  int refused = 0;
  int status = 0;                      ///< as published
  std::string error;
  AckKind ack = AckKind::kAcknowledged;
  double sense_ms = 0.0;
  double publish_ms = 0.0;             ///< the safety gate and the transport's send
  double ack_ms = 0.0;                 ///< waiting for the acknowledge
  double cycle_ms = 0.0;               ///< trigger to acknowledge
  std::vector<PickOutcome> picks;      ///< each candidate pick: sent or refused and why
};

struct CellLoopOptions {
  int cycles = 0;  ///< stop after this many triggered cycles; 0 = until a stop
  /// Each WaitForTrigger blocks at most this long, so a stop request is seen within it.
  std::chrono::milliseconds trigger_poll{250};
  /// Give up waiting for the acknowledge after this long (the next trigger replaces the result).
  std::chrono::milliseconds ack_timeout{10000};
  /// Give up waiting for any trigger after this long without one; 0 = wait forever.
  std::chrono::milliseconds idle_limit{0};
  /// At least this long between the starts of two cycles; 0 = none. Self-triggered links
  /// (dryrun:, serial:) trigger at once, so this is what paces them.
  std::chrono::milliseconds min_cycle_period{0};
  PickPlanningOptions planning;
  const std::atomic<bool>* stop_requested = nullptr;  ///< e.g. set by SIGINT; may be null
  std::function<void(const CycleLog&)> on_cycle;      ///< called after every cycle; may be empty
  /// Called after each trigger poll that brought no trigger (about every trigger_poll), so a
  /// status display can follow the link between cycles; may be empty.
  std::function<void()> on_idle;
  std::string Check() const;
};

struct CellLoopReport {
  int cycles = 0;
  int poses_published = 0;
  int refused = 0;
  int sense_errors = 0;
  int ack_timeouts = 0;
  int peer_lost = 0;
  bool stopped = false;      ///< a stop from the peer or stop_requested ended the loop
  bool idle_timeout = false; ///< idle_limit passed without a trigger
  std::vector<double> cycle_ms;
  LinkStats link;
};

/// Runs the loop. Pick sequence numbers start at 1 and increase by one per pick over the run.
CellLoopReport RunCellLoop(RobotLink& link, const RobotFrame& frame, const SenseFunction& sense,
                           const CellLoopOptions& options);

}  // namespace hnnstereo::robot
