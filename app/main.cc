// hnnstereo: close-range 3D position sensing with a Hopfield-network stereo matcher.
// Keep main thin: every subcommand is a library call (ARCHITECTURE.md).

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "app/cli_support.h"
#include "app/commands.h"

int main(int argc, char** argv) {
  CLI::App app{
      "hnnstereo - stereo matching with a continuous Hopfield network (OpenCL), calibration and "
      "3D position sensing for robot pick cells.\n"
      "Run 'hnnstereo <command> --help' for the options of a command."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "hnnstereo 0.1.0");
  hnnstereo::app::AddMatchCommand(app);
  hnnstereo::app::AddCalibrateCommand(app);
  hnnstereo::app::AddBenchCommand(app);
  hnnstereo::app::AddEvalCommand(app);
  hnnstereo::app::AddRenderCommand(app);
  hnnstereo::app::AddPickCommand(app);
  hnnstereo::app::AddServeCommand(app);
  hnnstereo::app::AddRobotCommand(app);
  hnnstereo::app::AddViewCommand(app);
  hnnstereo::app::AddDemoCommand(app);
  hnnstereo::app::AddProbeCommand(app);
  try {
    std::vector<std::string> arguments(argv, argv + argc);
    arguments = hnnstereo::app::ExpandConfigArguments(arguments);
    // CLI11 parses a reversed vector without the program name.
    std::vector<std::string> reversed(arguments.rbegin(), arguments.rend() - 1);
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "hnnstereo: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
