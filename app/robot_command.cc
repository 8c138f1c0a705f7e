// `hnnstereo robot ...`: the robot side's commissioning tools - fit FRAME.yml from touched
// points, write the thesis cell's frame, show a frame (and map a world point through it), send a
// cell command (home, open, close, stop) through a link.
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "app/cli_support.h"
#include "app/commands.h"
#include "app/robot_link_flags.h"
#include "robot/frame_io.h"
#include "robot/frames.h"

namespace hnnstereo::app {
namespace {

Eigen::Vector3d ParseVector3(const std::string& text, const std::string& option) {
  std::stringstream in(text);
  Eigen::Vector3d v;
  char comma1 = 0, comma2 = 0;
  if (!(in >> v.x() >> comma1 >> v.y() >> comma2 >> v.z()) || comma1 != ',' || comma2 != ',' ||
      !(in >> std::ws).eof() || !v.allFinite()) {
    throw std::invalid_argument(option + " must be X,Y,Z (three numbers), got '" + text + "'");
  }
  return v;
}

// Touched points: one "world_x,world_y,world_z,robot_x,robot_y,robot_z" per line (mm);
// '#' comments, blank lines and one header line of non-numbers are skipped.
void ReadTouchedPoints(const std::string& path, std::vector<Eigen::Vector3d>* world,
                       std::vector<Eigen::Vector3d>* robot_points) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("cannot read points file '" + path + "'");
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    for (char& c : line) {
      if (c == ',' || c == ';' || c == '\t') c = ' ';
    }
    std::stringstream fields(line);
    double v[6];
    int n = 0;
    while (n < 6 && fields >> v[n]) ++n;
    const bool complete = n == 6 && (fields >> std::ws).eof();
    if (!complete) {
      if (line_number == 1 && n == 0) continue;  // header
      throw std::invalid_argument("points file '" + path + "' line " +
                                  std::to_string(line_number) +
                                  ": expected 6 numbers world_x,world_y,world_z,robot_x,robot_y,"
                                  "robot_z (mm)");
    }
    world->emplace_back(v[0], v[1], v[2]);
    robot_points->emplace_back(v[3], v[4], v[5]);
  }
}

void PrintFrame(const robot::RobotFrame& frame) {
  const Eigen::Matrix4d m = frame.robot_from_world.matrix();
  std::printf("robot_from_world:\n");
  for (int r = 0; r < 4; ++r) {
    std::printf("  %10.5f %10.5f %10.5f %10.3f\n", m(r, 0), m(r, 1), m(r, 2), m(r, 3));
  }
  std::printf("workspace (robot frame, mm): [%.1f, %.1f] x [%.1f, %.1f] x [%.1f, %.1f]\n",
              frame.workspace_min.x(), frame.workspace_max.x(), frame.workspace_min.y(),
              frame.workspace_max.y(), frame.workspace_min.z(), frame.workspace_max.z());
  std::printf("rms_mm: %.3f\n", frame.rms_mm);
  if (frame.max_reach_mm) std::printf("max_reach_mm: %.1f\n", *frame.max_reach_mm);
}

void AddFitFrame(CLI::App* robot_cmd) {
  struct Args {
    std::string points, out, workspace_min, workspace_max;
    double margin_mm = 50.0;
    double height_mm = 300.0;
    robot::FrameFitOptions fit;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = robot_cmd->add_subcommand(
      "fit-frame",
      "Fit robot_from_world from three or more points touched with the robot's tool (least-squares "
      "rigid transform, Umeyama 1991 without scale) and write FRAME.yml.\n"
      "POINTS.csv: world_x,world_y,world_z,robot_x,robot_y,robot_z per line (mm; world = the "
      "calibration's table frame).");
  cmd->add_option("--points", args->points, "Touched points CSV")->required();
  cmd->add_option("--out", args->out, "Output FRAME.yml")->required();
  cmd->add_option("--workspace-min", args->workspace_min,
                  "Safety box corner X,Y,Z (robot, mm); default: the touched points' box minus "
                  "--workspace-margin");
  cmd->add_option("--workspace-max", args->workspace_max,
                  "Safety box corner X,Y,Z (robot, mm); default: the touched points' box plus "
                  "--workspace-margin in x and y, and --workspace-height above the highest");
  cmd->add_option("--workspace-margin", args->margin_mm,
                  "Default box: margin around the touched points in x, y and below (mm)")
      ->capture_default_str();
  cmd->add_option("--workspace-height", args->height_mm,
                  "Default box: clearance above the highest touched point (mm; parts, approach "
                  "and retreat must fit)")
      ->capture_default_str();
  cmd->add_option("--max-rms", args->fit.max_rms_mm, "Refuse a fit with a larger RMS (mm)")
      ->capture_default_str();
  cmd->callback([args] {
    CheckOutputsWritable({{"--out", args->out}});
    if (!(args->margin_mm >= 0.0) || !(args->height_mm > 0.0)) {
      throw std::invalid_argument("--workspace-margin must be >= 0 and --workspace-height > 0");
    }
    std::vector<Eigen::Vector3d> world, robot_points;
    ReadTouchedPoints(args->points, &world, &robot_points);
    robot::RobotFrame frame;
    // The default safety box is the touched points' box (where the tool has been, so where the
    // cell is) plus a margin, not a fixed +-400 mm that may hold a wall or miss the table.
    const bool from_points = args->workspace_min.empty() || args->workspace_max.empty();
    if (from_points && !robot_points.empty()) {
      Eigen::Vector3d low = robot_points.front(), high = robot_points.front();
      for (const Eigen::Vector3d& p : robot_points) {
        low = low.cwiseMin(p);
        high = high.cwiseMax(p);
      }
      frame.workspace_min = low - Eigen::Vector3d::Constant(args->margin_mm);
      frame.workspace_max = high + Eigen::Vector3d(args->margin_mm, args->margin_mm, args->height_mm);
    }
    if (!args->workspace_min.empty()) {
      frame.workspace_min = ParseVector3(args->workspace_min, "--workspace-min");
    }
    if (!args->workspace_max.empty()) {
      frame.workspace_max = ParseVector3(args->workspace_max, "--workspace-max");
    }
    const robot::FrameFitReport fit = robot::FitRobotFromWorld(world, robot_points, args->fit);
    frame.robot_from_world = fit.robot_from_world;
    frame.rms_mm = fit.rms_mm;
    robot::SaveRobotFrame(args->out, frame);
    std::printf("fitted %d points: rms %.3f mm, max residual %.3f mm\n", fit.n_points, fit.rms_mm,
                fit.max_residual_mm);
    if (from_points) {
      std::printf("workspace from the touched points' box: %.0f mm margin, %.0f mm above the "
                  "highest (--workspace-min/--workspace-max to set it)\n",
                  args->margin_mm, args->height_mm);
    }
    PrintFrame(frame);
    std::printf("wrote %s\n", args->out.c_str());
  });
}

void AddThesisFrame(CLI::App* robot_cmd) {
  auto out = std::make_shared<std::string>();
  CLI::App* cmd = robot_cmd->add_subcommand(
      "thesis-frame",
      "Write the thesis cell's frame: x_r = 600 - X, y_r = 400 - Y, z_r = Z (mm; a half turn "
      "about z), with a workspace box and reach (max_reach_mm) that cover the table of the "
      "rendered default cell ('hnnstereo render').");
  cmd->add_option("--out", *out, "Output FRAME.yml")->required();
  cmd->callback([out] {
    const robot::RobotFrame frame = robot::ThesisRobotFrame();
    robot::SaveRobotFrame(*out, frame);
    PrintFrame(frame);
    std::printf("wrote %s\n", out->c_str());
  });
}

void AddShowFrame(CLI::App* robot_cmd) {
  struct Args {
    std::string frame, world;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = robot_cmd->add_subcommand(
      "show-frame", "Print FRAME.yml; with --world X,Y,Z also where that table point lands in the "
                    "robot frame and whether it is inside the workspace box.");
  cmd->add_option("--frame", args->frame, "FRAME.yml")->required();
  cmd->add_option("--world", args->world, "A world point X,Y,Z (mm) to map");
  cmd->callback([args] {
    const robot::RobotFrame frame = robot::LoadRobotFrame(args->frame);
    PrintFrame(frame);
    if (!args->world.empty()) {
      const Eigen::Vector3d world = ParseVector3(args->world, "--world");
      const Eigen::Vector3d mapped = frame.robot_from_world * world;
      const bool inside = (mapped.array() >= frame.workspace_min.array()).all() &&
                          (mapped.array() <= frame.workspace_max.array()).all();
      std::printf("world (%.2f, %.2f, %.2f) -> robot (%.2f, %.2f, %.2f): %s the workspace\n",
                  world.x(), world.y(), world.z(), mapped.x(), mapped.y(), mapped.z(),
                  inside ? "inside" : "OUTSIDE");
    }
  });
}

void AddSend(CLI::App* robot_cmd) {
  struct Args {
    std::string command;
    RobotLinkFlags link;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = robot_cmd->add_subcommand(
      "send", "Send one cell command through a link: home, open, close or stop (the transports "
              "that cannot carry one say so).");
  cmd->add_option("--command", args->command, "home, open, close or stop (none needs --frame)")
      ->required();
  // No cell command carries a pose: FRAME.yml is optional here.
  args->link.AddTo(cmd, "The link URI (see 'hnnstereo serve --help')", false);
  cmd->callback([args] {
    robot::CellCommand command;
    if (args->command == "home") {
      command = robot::CellCommand::kHome;
    } else if (args->command == "open") {
      command = robot::CellCommand::kOpen;
    } else if (args->command == "close") {
      command = robot::CellCommand::kClose;
    } else if (args->command == "stop") {
      command = robot::CellCommand::kStop;
    } else {
      throw std::invalid_argument("unknown --command '" + args->command +
                                  "' (home, open, close or stop)");
    }
    if (args->link.robot.empty()) throw std::invalid_argument("send needs --robot URI");
    std::unique_ptr<robot::RobotLink> link = args->link.OpenForCellCommands();
    link->SendCellCommand(command);
    std::printf("sent %s to %s\n", robot::CellCommandName(command), link->Describe().c_str());
  });
}

}  // namespace

void AddRobotCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "robot", "Robot-side tools: fit-frame, thesis-frame, show-frame, send (docs/robot.md).");
  cmd->require_subcommand(1);
  AddFitFrame(cmd);
  AddThesisFrame(cmd);
  AddShowFrame(cmd);
  AddSend(cmd);
}

}  // namespace hnnstereo::app
