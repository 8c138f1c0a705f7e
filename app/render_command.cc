// `hnnstereo render`: not available yet (placeholder until its issue lands).
#include <stdexcept>

#include "app/commands.h"

namespace hnnstereo::app {

void AddRenderCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("render", "(not available yet)");
  cmd->callback([] { throw std::runtime_error("render is not available yet"); });
}

}  // namespace hnnstereo::app
