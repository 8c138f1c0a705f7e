// dryrun:FILE.jsonl - the default transport: every published pick (and every cycle) becomes one
// JSON line, flushed as it is written, so a cell can be commissioned without a robot. A file that
// exists is appended to, never truncated: it is a log of every run.
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "robot/link.h"

namespace hnnstereo::robot {
namespace {

const char* GripperName(GripperAction action) {
  switch (action) {
    case GripperAction::kNone: return "none";
    case GripperAction::kOpen: return "open";
    case GripperAction::kClose: return "close";
  }
  return "?";
}

class DryRunLink final : public RobotLink {
 public:
  DryRunLink(const LinkUri& uri, SafetyGate gate, LinkOptions options)
      : RobotLink(std::move(gate), std::move(options)), path_(uri.path) {
    out_.open(path_, std::ios::out | std::ios::app);
    if (!out_) throw std::runtime_error("dryrun: cannot write '" + path_ + "'");
  }

  std::string Describe() const override { return "dryrun:" + path_; }

  Trigger WaitForTrigger(std::chrono::milliseconds) override {
    ++stats_.triggers;
    return {TriggerKind::kTrigger, ++request_sequence_};
  }

  AckKind WaitForAcknowledge(std::chrono::milliseconds) override { return AckKind::kAcknowledged; }

  void SendCellCommand(CellCommand command) override {
    Write({{"type", "cell"}, {"command", CellCommandName(command)}});
  }

  LinkStats Stats() const override { return stats_; }

 protected:
  void Send(const CycleResult& admitted) override {
    Write({{"type", "cycle"},
           {"request_sequence", admitted.request_sequence},
           // The code the cell sees (docs/robot.md): 2 result ready, or a LinkErrorCode.
           {"status", PublishedStatusCode(admitted.status)},
           {"error", admitted.error},
           {"poses", admitted.picks.size()}});
    for (const PickCommand& pick : admitted.picks) {
      const Eigen::Quaterniond& q = pick.orientation;
      Write({{"type", "pick"},
             {"request_sequence", admitted.request_sequence},
             {"sequence", pick.sequence},
             {"capture_time_s", pick.capture_time_s},
             {"object_id", pick.object_id},
             {"position_mm", {pick.position_mm.x(), pick.position_mm.y(), pick.position_mm.z()}},
             {"quaternion_wxyz", {q.w(), q.x(), q.y(), q.z()}},
             {"yaw_deg", pick.yaw_deg},
             {"approach_mm", pick.approach_mm},
             {"retreat_mm", pick.retreat_mm},
             {"gripper", GripperName(pick.gripper)},
             {"speed_fraction", pick.speed_fraction}});
      ++stats_.poses_sent;
    }
    ++stats_.cycles_published;
  }

 private:
  void Write(const nlohmann::json& line) {
    out_ << line.dump() << "\n";
    out_.flush();
    if (!out_) throw std::runtime_error("dryrun: write to '" + path_ + "' failed");
  }

  std::string path_;
  std::ofstream out_;
  std::uint32_t request_sequence_ = 0;
  LinkStats stats_;
};

}  // namespace

std::unique_ptr<RobotLink> MakeDryRunLink(const LinkUri& uri, SafetyGate gate, LinkOptions options) {
  return std::make_unique<DryRunLink>(uri, std::move(gate), std::move(options));
}

}  // namespace hnnstereo::robot
