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
#include <sstream>
#include <stdexcept>

#include "app/cell_page_flags.h"
#include "app/cell_sensing.h"
#include "app/cli_support.h"
#include "app/commands.h"
#include "app/robot_link_flags.h"
#include "common/atomic_file.h"
#include "robot/cell_loop.h"
#include "web/cell_status.h"

namespace hnnstereo::app {
namespace {

struct ServeArgs {
  std::string left, right, calib, replay, capture, report;
  int cycles = 0;
  double idle_limit_s = 0.0;
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

void RunServe(ServeArgs& args) {
  if (args.cycles < 0) throw std::invalid_argument("--cycles must be >= 0 (0 = until a stop)");
  if (!(args.idle_limit_s >= 0.0)) throw std::invalid_argument("--idle-limit must be >= 0");
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
  const std::optional<web::CellPageOptions> page = args.page.Resolve();
  // The page reads snapshots the loop publishes after each cycle (web/cell_status.h).
  web::CellStatusBoard board;
  std::optional<web::CellStatusRecorder> status;
  if (page) status.emplace(&board, "serve");

  // Everything that can be checked is checked before the link opens (a PLC sees no half-started
  // server): the sensing flags, the calibration, the replayed objects, the frame.
  robot::SenseFunction sense;
  calib::StereoCalibration calibration;
  std::vector<robot::SensedObject> replayed;
  nlohmann::json replayed_file;
  std::unique_ptr<ocl::Runtime> runtime;
  if (sensing) {
    args.cell.Resolve();
    calibration = calib::LoadCalibration(args.calib);
    runtime = OpenRuntimeFor(args.cell.sensing.matcher.engine, args.cell.flags.device);
    // Compile the kernels now, not on the first trigger (the PLC would wait for it).
    WarmUpCellKernels(runtime.get(), args.cell.sensing.matcher);
    sense = [&] {
      if (!args.capture.empty()) {
        const int code = std::system(args.capture.c_str());
        if (code != 0) {
          throw std::runtime_error("--capture command exited with status " + std::to_string(code));
        }
      }
      const double capture_time_s = SteadySeconds();
      const SensedPair pair = SenseCellPair(args.left, args.right, calibration, args.calib,
                                            args.cell, runtime.get());
      if (status) {
        status->SetSensed(ObjectsFileJson(pair, args.cell, args.left, args.right, args.calib),
                          OverlayImageOf(pair), calibration.P1);
      }
      return robot::SensedCycle{SensedObjectsOf(pair.report), capture_time_s};
    };
  } else {
    replayed = robot::SensedObjectsFromJson(ReadText(args.replay));
    if (status) replayed_file = nlohmann::json::parse(ReadText(args.replay));
    sense = [&] {
      if (status) status->SetSensed(replayed_file, {}, {});
      return robot::SensedCycle{replayed, SteadySeconds()};
    };
  }
  CheckOutputsWritable({{"--report", args.report}});
  robot::RobotFrame frame;
  // The page binds before the link opens: an address in use fails before a PLC sees anything.
  std::unique_ptr<web::CellPageServer> page_server;
  if (page) {
    status->PublishNow();
    page_server = StartCellPage(board, *page);
  }
  std::unique_ptr<robot::RobotLink> link = args.link.Open(&frame);

  robot::CellLoopOptions loop = args.link.LoopOptions();
  loop.cycles = args.cycles;
  loop.idle_limit = std::chrono::milliseconds(static_cast<long>(args.idle_limit_s * 1000.0));
  loop.stop_requested = InstallStopSignals();
  loop.on_cycle = PrintCycleLine;
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
  const robot::CellLoopReport report = robot::RunCellLoop(*link, frame, sense, loop);
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
