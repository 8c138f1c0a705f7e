// `hnnstereo bench`: placeholder until the benchmark lands (see below).
#include <stdexcept>

#include "app/commands.h"

namespace hnnstereo::app {

void AddBenchCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("bench", "Throughput of matching");
  cmd->callback([] { throw std::runtime_error("bench is not implemented yet"); });
}

}  // namespace hnnstereo::app
