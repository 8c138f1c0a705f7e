// `hnnstereo serve`: the pick cell's loop. On each trigger from the robot side read the images
// again (or run a capture command first), sense the parts, publish their picks tallest first
// through the safety-gated link, wait for the acknowledge. Exits after --cycles N or a stop.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/cell_page_flags.h"
#include "app/cell_sensing.h"
#include "app/cli_support.h"
#include "app/commands.h"
#include "app/robot_link_flags.h"
#include "common/atomic_file.h"
#include "robot/cell_loop.h"
#include "vision/sensing/sensing_hints.h"
#include "web/cell_status.h"

namespace hnnstereo::app {
namespace {

/// The default pace of a self-triggered link: one cycle a second writes a few dryrun: lines a
/// second (about 1 KB/s), never a disk's worth.
constexpr double kSelfTriggeredPeriodS = 1.0;

struct ServeArgs {
  std::string left, right, calib, replay, capture, report;
  int cycles = 0;
  double idle_limit_s = 0.0;
  /// --period (s) between cycle starts; unset = kSelfTriggeredPeriodS for dryrun: and serial:
  /// (they trigger at once, so an unpaced loop would re-sense as fast as it can), 0 otherwise.
  std::optional<double> period_s;
  std::string config;  // consumed by ExpandConfigArguments in main
  CellSensingFlags cell;
  RobotLinkFlags link;
  CellPageFlags page;
};

double SteadySeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("cannot read '" + path + "'");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The command line's own checks, before anything is read or opened.
void CheckServeArgs(ServeArgs& args) {
  if (args.cycles < 0) throw std::invalid_argument("--cycles must be >= 0 (0 = until a stop)");
  if (!(args.idle_limit_s >= 0.0)) throw std::invalid_argument("--idle-limit must be >= 0");
  if (args.period_s && !(*args.period_s >= 0.0 && *args.period_s <= 86400.0)) {
    throw std::invalid_argument("--period must be in [0, 86400] s");
  }
  const bool sensing = args.replay.empty();
  if (sensing && (args.left.empty() || args.right.empty() || args.calib.empty())) {
    throw std::invalid_argument("serve needs --left, --right and --calib (or --replay "
                                "OBJECTS.json to publish fixed objects)");
  }
  if (!sensing && !(args.left.empty() && args.right.empty() && args.calib.empty() &&
                    args.capture.empty())) {
    throw std::invalid_argument("--replay replaces sensing: drop --left/--right/--calib/--capture");
  }
  if (args.link.robot.empty()) args.link.robot = "dryrun:picks.jsonl";
  // Images read on every trigger must exist now, unless --capture writes them first.
  if (sensing && args.capture.empty()) {
    for (const auto& [option, path] : {std::pair{"--left", args.left}, {"--right", args.right}}) {
      std::error_code error;
      if (!std::filesystem::is_regular_file(path, error)) {
        throw std::invalid_argument(std::string(option) + " '" + path + "' does not exist (serve "
                                    "reads it on every trigger; --capture CMD writes it first)");
      }
    }
  }
  CheckOutputsWritable({{"--report", args.report}});
}

// What each trigger senses: the pair read again (after --capture), or the --replay objects.
// Everything is loaded and checked when this is made, before the link opens (a PLC sees no
// half-started server); the kernels are compiled now, not on the first trigger.
class CellSensor {
 public:
  CellSensor(ServeArgs& args, std::optional<web::CellStatusRecorder>* status)
      : args_(args), status_(*status) {
    if (!args.replay.empty()) {
      AsSetupError("--replay", [&] {
        replayed_ = robot::SensedObjectsFromJson(ReadText(args.replay));
        if (status_) replayed_file_ = nlohmann::json::parse(ReadText(args.replay));
      });
      return;
    }
    args.cell.Resolve();
    calibration_ = AsSetupError([&] { return calib::LoadCalibration(args.calib); });
    if (const std::string problem = vision::TableFrameProblem(calibration_); !problem.empty()) {
      throw std::invalid_argument("--calib '" + args.calib + "': " + problem);
    }
    runtime_ = OpenRuntimeFor(args.cell.sensing.matcher.engine, args.cell.flags.device);
    WarmUpCellKernels(runtime_.get(), args.cell.sensing.matcher);
  }

  robot::SensedCycle operator()() {
    if (!args_.replay.empty()) {
      if (status_) status_->SetSensed(replayed_file_, {}, {});
      return robot::SensedCycle{replayed_, SteadySeconds()};
    }
    if (!args_.capture.empty()) {
      const int code = std::system(args_.capture.c_str());
      if (code != 0) {
        throw std::runtime_error("--capture command exited with status " + std::to_string(code));
      }
    }
    const double capture_time_s = SteadySeconds();
    const SensedPair pair = SenseCellPair(args_.left, args_.right, calibration_, args_.calib,
                                          args_.cell, runtime_.get());
    if (status_) {
      // The page draws on the left image as captured, through the lens (web/cell_status.h).
      status_->SetSensed(ObjectsFileJson(pair, args_.cell, args_.left, args_.right, args_.calib),
                         pair.left.original, calibration_.P1, calibration_.intrinsics);
    }
    return robot::SensedCycle{SensedObjectsOf(pair.report), capture_time_s};
  }

 private:
  ServeArgs& args_;
  std::optional<web::CellStatusRecorder>& status_;
  calib::StereoCalibration calibration_;
  std::unique_ptr<ocl::Runtime> runtime_;
  std::vector<robot::SensedObject> replayed_;
  nlohmann::json replayed_file_;
};

robot::CellLoopOptions ServeLoopOptions(const ServeArgs& args) {
  robot::CellLoopOptions loop = args.link.LoopOptions();
  loop.cycles = args.cycles;
  loop.idle_limit = std::chrono::milliseconds(static_cast<long>(args.idle_limit_s * 1000.0));
  const std::string scheme = robot::ParseLinkUri(args.link.robot).scheme;
  const bool self_triggered = scheme == "dryrun" || scheme == "serial";
  const double period_s = args.period_s.value_or(self_triggered ? kSelfTriggeredPeriodS : 0.0);
  loop.min_cycle_period = std::chrono::milliseconds(static_cast<long>(period_s * 1000.0));
  loop.stop_requested = InstallStopSignals();
  loop.on_cycle = PrintCycleLine;
  return loop;
}

void RunServe(ServeArgs& args) {
  CheckServeArgs(args);
  const std::optional<web::CellPageOptions> page = args.page.Resolve();
  // The page reads snapshots the loop publishes after each cycle (web/cell_status.h).
  web::CellStatusBoard board;
  std::optional<web::CellStatusRecorder> status;
  if (page) status.emplace(&board, "serve");
  CellSensor sensor(args, &status);
  robot::RobotFrame frame;
  // The page binds before the link opens: an address in use fails before a PLC sees anything.
  std::unique_ptr<web::CellPageServer> page_server;
  if (page) {
    status->PublishNow();
    page_server = StartCellPage(board, *page);
  }
  std::unique_ptr<robot::RobotLink> link = args.link.Open(&frame);

  robot::CellLoopOptions loop = ServeLoopOptions(args);
  std::printf("link: %s\n", link->Describe().c_str());
  std::fflush(stdout);
  if (status) {
    loop.on_cycle = [&](const robot::CycleLog& log) {
      PrintCycleLine(log);
      status->RecordCycle(log, *link);
    };
    loop.on_idle = [&] { status->RecordLink(*link); };
    status->PublishNow(link.get());
  }
  const robot::CellLoopReport report =
      robot::RunCellLoop(*link, frame, [&] { return sensor(); }, loop);
  const nlohmann::json json = CellLoopReportJson(report);
  std::printf("served %d cycles: %d poses sent, %d refused, %d sensing errors, %d ack timeouts, "
              "%d peers lost%s%s\n",
              report.cycles, report.poses_published, report.refused, report.sense_errors,
              report.ack_timeouts, report.peer_lost, report.stopped ? "; stopped" : "",
              report.idle_timeout ? "; idle limit reached" : "");
  if (!args.report.empty()) calib::WriteFileAtomically(args.report, json.dump(2) + "\n");
}

}  // namespace

void AddServeCommand(CLI::App& app) {
  auto args = std::make_shared<ServeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "serve",
      "The cell loop: on each trigger from the robot side read the images again, sense the parts, "
      "publish their picks (tallest first, safety-gated) and wait for the acknowledge.\n"
      "Examples:\n"
      "  hnnstereo serve --left L.png --right R.png --calib CAL.yml --frame FRAME.yml \\\n"
      "      --robot modbus-server://0.0.0.0:1502          # a PLC polls the registers\n"
      "  hnnstereo serve --replay objects.json --frame FRAME.yml --robot dryrun:picks.jsonl "
      "--cycles 3\n"
      "stdout: 'link: URI' (with the port bound), then one line per cycle. Transports: "
      "docs/robot.md; the Modbus register map: docs/robot_modbus.md; the vision-server and "
      "serial protocols: docs/robot_ascii.md.");
  cmd->add_option("--left", args->left, "Left image, read again on every trigger");
  cmd->add_option("--right", args->right, "Right image, read again on every trigger");
  cmd->add_option("--calib", args->calib, "CAL.yml of the cell (P1, P2; table at z = 0)");
  cmd->add_option("--capture", args->capture,
                  "Shell command run before each sensing (it writes --left/--right); a non-zero "
                  "exit publishes a sensing error for that cycle");
  cmd->add_option("--replay", args->replay,
                  "Publish the objects of this OBJECTS.json on every trigger instead of sensing "
                  "(commissioning the link without cameras; link tests)");
  cmd->add_option("--cycles", args->cycles, "Exit after this many triggered cycles (0 = until a "
                                            "stop from the robot side or SIGINT)")
      ->capture_default_str();
  cmd->add_option("--idle-limit", args->idle_limit_s,
                  "Exit when no trigger came for this long (s; 0 = wait forever)")
      ->capture_default_str();
  cmd->add_option("--period", args->period_s,
                  "At least this long between the starts of two cycles (s). Default: 1 for "
                  "dryrun: and serial: (they trigger at once), 0 for links the robot side "
                  "triggers");
  cmd->add_option("--report", args->report, "Write the loop's counters as JSON at exit");
  args->link.AddTo(cmd,
                   "The link: dryrun:FILE.jsonl (default dryrun:picks.jsonl), "
                   "modbus-server://HOST:PORT, modbus-client://HOST:PORT, "
                   "vision-server://HOST:PORT, serial:DEVICE?baud=2400 (port 0 = any free port)",
                   true);
  args->page.AddTo(cmd,
                   "Also serve the cell's web page and /api/* at HOST:PORT (127.0.0.1:0 = this "
                   "machine only, any free port; printed as 'http: URL'); docs/robot.md");
  args->cell.AddTo(cmd);
  cmd->add_option("--config", args->config,
                  "YAML file of options: 'long-option-name: value' per line; the command line "
                  "wins");
  cmd->callback([args] { RunServe(*args); });
}

}  // namespace hnnstereo::app
