// `hnnstereo eval`: not available yet (placeholder until its issue lands).
#include <stdexcept>

#include "app/commands.h"

namespace hnnstereo::app {

void AddEvalCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("eval", "(not available yet)");
  cmd->callback([] { throw std::runtime_error("eval is not available yet"); });
}

}  // namespace hnnstereo::app
