#pragma once
// Each subcommand registers itself on the CLI11 app; the work is done by library calls.

#include <CLI/CLI.hpp>

namespace hnnstereo::app {

void AddMatchCommand(CLI::App& app);
void AddViewCommand(CLI::App& app);
void AddBenchCommand(CLI::App& app);
void AddCalibrateCommand(CLI::App& app);
void AddRenderCommand(CLI::App& app);
void AddPickCommand(CLI::App& app);
void AddDemoCommand(CLI::App& app);
void AddProbeCommand(CLI::App& app);
void AddEvalCommand(CLI::App& app);
void AddServeCommand(CLI::App& app);
void AddRobotCommand(CLI::App& app);
void AddDevicesCommand(CLI::App& app);

}  // namespace hnnstereo::app
