// `hnnstereo pick`: not available yet (placeholder until its issue lands).
#include <stdexcept>

#include "app/commands.h"

namespace hnnstereo::app {

void AddPickCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("pick", "(not available yet)");
  cmd->callback([] { throw std::runtime_error("pick is not available yet"); });
}

}  // namespace hnnstereo::app
