#include "robot/cell_loop.h"

#include <algorithm>
#include <optional>
#include <stdexcept>
#include <thread>

#include "common/timing.h"

namespace hnnstereo::robot {
namespace {

using common::MillisecondsSince;

}  // namespace

std::string CellLoopOptions::Check() const {
  if (cycles < 0) return "cycles must be >= 0 (0 = until a stop)";
  if (trigger_poll.count() <= 0) return "trigger_poll must be positive";
  if (ack_timeout.count() <= 0) return "ack_timeout must be positive";
  if (idle_limit.count() < 0) return "idle_limit must be >= 0";
  if (min_cycle_period.count() < 0) return "min_cycle_period must be >= 0";
  return planning.Check();
}

CellLoopReport RunCellLoop(RobotLink& link, const RobotFrame& frame, const SenseFunction& sense,
                           const CellLoopOptions& options) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  if (auto error = frame.Check(); !error.empty()) throw std::invalid_argument("frame: " + error);
  CellLoopReport report;
  std::uint32_t next_sequence = 1;
  auto stop_requested = [&] {
    return options.stop_requested != nullptr && options.stop_requested->load();
  };
  auto idle_since = std::chrono::steady_clock::now();
  std::optional<std::chrono::steady_clock::time_point> last_cycle_start;
  while (options.cycles == 0 || report.cycles < options.cycles) {
    if (stop_requested()) {
      report.stopped = true;
      break;
    }
    if (last_cycle_start) {
      // Pace the loop: sleep in short slices so a stop request is still seen at once.
      const auto next_start = *last_cycle_start + options.min_cycle_period;
      const auto now = std::chrono::steady_clock::now();
      if (now < next_start) {
        std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
            next_start - now, std::chrono::milliseconds(50)));
        continue;
      }
    }
    const Trigger trigger = link.WaitForTrigger(options.trigger_poll);
    if (trigger.kind == TriggerKind::kStop) {
      report.stopped = true;
      break;
    }
    if (trigger.kind == TriggerKind::kIdle) {
      if (options.on_idle) options.on_idle();
      if (options.idle_limit.count() > 0 &&
          std::chrono::steady_clock::now() - idle_since > options.idle_limit) {
        report.idle_timeout = true;
        break;
      }
      continue;
    }
    const auto cycle_start = std::chrono::steady_clock::now();
    last_cycle_start = cycle_start;
    CycleLog log;
    log.cycle = ++report.cycles;
    log.request_sequence = trigger.request_sequence;
    CycleResult cycle;
    cycle.request_sequence = trigger.request_sequence;
    try {
      SensedCycle sensed = sense();
      log.sense_ms = MillisecondsSince(cycle_start);
      log.objects = static_cast<int>(sensed.objects.size());
      SortTallestFirst(&sensed.objects);
      for (const SensedObject& object : sensed.objects) {
        cycle.picks.push_back(PlanPick(object, frame.robot_from_world, options.planning,
                                       next_sequence++, sensed.capture_time_s));
      }
    } catch (const std::exception& error) {
      log.sense_ms = MillisecondsSince(cycle_start);
      ++report.sense_errors;
      cycle.picks.clear();
      cycle.status = kErrorSensingFailed;
      cycle.error = error.what();
    }
    const auto publish_start = std::chrono::steady_clock::now();
    const int transport_refused_before = link.Stats().transport_refused;
    const PublishReport published = link.Publish(cycle);
    // Picks the transport itself refused (admitted by the gate) are not "sent".
    const int transport_refused = link.Stats().transport_refused - transport_refused_before;
    log.published = published.admitted - transport_refused;
    log.refused = published.refused + transport_refused;
    log.status = cycle.status == 0 && published.admitted == 0 && published.refused > 0
                     ? kErrorAllRefused
                     : cycle.status;
    log.error = log.status == kErrorAllRefused && cycle.status == 0
                    ? "the safety gate refused every pose of this cycle"
                    : cycle.error;
    report.poses_published += log.published;
    report.refused += log.refused;
    log.picks = published.outcomes;
    const auto ack_start = std::chrono::steady_clock::now();
    log.publish_ms = std::chrono::duration<double, std::milli>(ack_start - publish_start).count();
    log.ack = link.WaitForAcknowledge(options.ack_timeout);
    log.ack_ms = MillisecondsSince(ack_start);
    if (log.ack == AckKind::kTimeout) ++report.ack_timeouts;
    if (log.ack == AckKind::kPeerLost) ++report.peer_lost;
    log.cycle_ms = MillisecondsSince(cycle_start);
    report.cycle_ms.push_back(log.cycle_ms);
    if (options.on_cycle) options.on_cycle(log);
    idle_since = std::chrono::steady_clock::now();
    if (log.ack == AckKind::kStop) {
      report.stopped = true;
      break;
    }
  }
  report.link = link.Stats();
  return report;
}

}  // namespace hnnstereo::robot
