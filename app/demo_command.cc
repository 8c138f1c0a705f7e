// `hnnstereo demo`: not available yet (placeholder until its issue lands).
#include <stdexcept>

#include "app/commands.h"

namespace hnnstereo::app {

void AddDemoCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("demo", "(not available yet)");
  cmd->callback([] { throw std::runtime_error("demo is not available yet"); });
}

}  // namespace hnnstereo::app
