// `hnnstereo probe`: not available yet (placeholder until its issue lands).
#include <stdexcept>

#include "app/commands.h"

namespace hnnstereo::app {

void AddProbeCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("probe", "(not available yet)");
  cmd->callback([] { throw std::runtime_error("probe is not available yet"); });
}

}  // namespace hnnstereo::app
