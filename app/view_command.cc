// `hnnstereo view`: one `pick` result (OBJECTS.json and its left image) on the cell's web page,
// for commissioning without a running cell: the same page and API as `serve --http`.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "app/cell_page_flags.h"
#include "app/cli_support.h"
#include "app/commands.h"
#include "app/robot_link_flags.h"
#include "calib/calibration.h"
#include "robot/pick_planning.h"
#include "common/image.h"
#include "web/cell_status.h"

namespace hnnstereo::app {
namespace {

struct ViewArgs {
  std::string objects, left, calib;
  double duration_s = 0.0;
  bool quiet = false;
  CellPageFlags page;
};

void RunView(ViewArgs& args) {
  if (!(args.duration_s >= 0.0)) throw std::invalid_argument("--duration must be >= 0");
  if (args.page.http.empty()) args.page.http = "127.0.0.1:0";
  const web::CellPageOptions page = *args.page.Resolve();
  std::ifstream in(args.objects);
  if (!in) throw std::invalid_argument("cannot read --objects '" + args.objects + "'");
  std::stringstream text;
  text << in.rdbuf();
  // Inputs that cannot be used are a refused setup (exit 2), found before the page starts.
  const nlohmann::json objects = AsSetupError("--objects '" + args.objects + "'", [&] {
    robot::SensedObjectsFromJson(text.str());  // names a malformed file's problem
    return nlohmann::json::parse(text.str());
  });
  const vision::LoadedImage left = AsSetupError("--left", [&] { return vision::LoadImage(args.left); });

  // The outlines need P1: --calib, else the calibration OBJECTS.json names (pick writes it).
  std::string calib_path = args.calib;
  const bool calib_given = !calib_path.empty();
  if (!calib_given && objects.contains("calib") && objects["calib"].is_string()) {
    calib_path = objects["calib"].get<std::string>();
  }
  std::optional<calib::ProjectionMatrix> P1;
  std::optional<calib::Intrinsics> intrinsics;  // the outlines go through the lens (cell_status.h)
  if (!calib_path.empty()) {
    try {
      const calib::StereoCalibration calibration = calib::LoadCalibration(calib_path);
      P1 = calibration.P1;
      intrinsics = calibration.intrinsics;
    } catch (const std::exception& error) {
      if (calib_given) throw std::invalid_argument(std::string("--calib: ") + error.what());
      std::cerr << "hnnstereo: notice: the parts are shown without outlines: cannot use the "
                   "calibration OBJECTS.json names ("
                << error.what() << "); give --calib\n";
    }
  }
  web::CellStatusBoard board;
  web::CellStatusRecorder status(&board, "view");
  status.SetSensed(objects, left.original, P1, intrinsics);
  status.PublishNow();
  const auto server = StartCellPage(board, page);
  if (!args.quiet) {
    std::printf("showing %zu parts of %s until %s\n",
                objects.contains("objects") ? objects["objects"].size() : std::size_t{0},
                args.objects.c_str(),
                args.duration_s > 0.0 ? "--duration ends" : "Ctrl-C (SIGINT) or SIGTERM");
  }
  std::fflush(stdout);
  const std::atomic<bool>* stop = InstallStopSignals();
  const auto end = std::chrono::steady_clock::now() +
                   std::chrono::milliseconds(static_cast<long>(args.duration_s * 1000.0));
  while (!stop->load() && (args.duration_s == 0.0 || std::chrono::steady_clock::now() < end)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

}  // namespace

void AddViewCommand(CLI::App& app) {
  auto args = std::make_shared<ViewArgs>();
  CLI::App* cmd = app.add_subcommand(
      "view",
      "Show one pick result on the cell's web page (the page of 'serve --http'): the left image "
      "with the parts' outlines, ids, centres and yaw lines, and the parts table.\n"
      "Example:\n"
      "  hnnstereo pick --left L.png --right R.png --calib CAL.yml --out objects.json\n"
      "  hnnstereo view --objects objects.json --left L.png --http 127.0.0.1:8080\n"
      "  # then open http://127.0.0.1:8080/ in a browser\n"
      "stdout: 'http: URL'. Runs until Ctrl-C (or --duration).");
  cmd->add_option("--objects", args->objects, "OBJECTS.json written by 'pick'")->required();
  cmd->add_option("--left", args->left, "The left image the parts were sensed on")->required();
  cmd->add_option("--calib", args->calib,
                  "CAL.yml for the outlines (P1); default: the 'calib' OBJECTS.json names");
  args->page.AddTo(cmd,
                   "Serve the page at HOST:PORT (default 127.0.0.1:0: this machine only, "
                   "any free port)");
  // The URL is what view is run for (port 0 picks a free one), so --quiet keeps that line.
  cmd->add_flag("--quiet", args->quiet, "Print only the 'http: URL' line");
  cmd->add_option("--duration", args->duration_s, "Exit after this long (s; 0 = until a stop)")
      ->capture_default_str();
  cmd->callback([args] { RunView(*args); });
}

}  // namespace hnnstereo::app
