// The --config file of the CLI (flat YAML, app/cli_support.h) as `hnnstereo match` takes it:
// ExpandConfigArguments, CLI11 parsing into the match command's options (MatcherFlags and the
// command's own), MatcherFlags::Resolve and the matcher options' Check. Accepted: options that
// pass Check(); refused: CLI::ParseError or a std::exception (main turns both into one line).
// Nothing runs the match itself.
#include <CLI/CLI.hpp>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>
#include <vector>

#include "app/cli_support.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = hnnstereo::fuzz::WriteScratch("options.yml", data, size);
  CLI::App app("hnnstereo");
  CLI::App* cmd = app.add_subcommand("match", "match");
  std::string left, right, calib, out, report, overlay, config;
  bool rectified = false, quiet = false;
  hnnstereo::app::MatcherFlags flags;
  cmd->add_option("--left", left)->required();
  cmd->add_option("--right", right)->required();
  auto* calib_option = cmd->add_option("--calib", calib);
  auto* rectified_option = cmd->add_flag("--rectified", rectified);
  calib_option->excludes(rectified_option);
  cmd->add_option("--out", out)->required();
  cmd->add_option("--report", report);
  cmd->add_option("--overlay", overlay);
  cmd->add_flag("--quiet", quiet);
  flags.AddTo(cmd);
  cmd->add_option("--config", config);
  std::vector<std::string> arguments = {"hnnstereo", "match",  "--left", "l.png", "--right",
                                        "r.png",     "--out",  "m.csv",  "--config", path};
  try {
    arguments = hnnstereo::app::ExpandConfigArguments(arguments, [&](const std::string& option) {
      return cmd->get_option_no_throw(option) != nullptr;
    });
    std::vector<std::string> reversed(arguments.rbegin(), arguments.rend() - 1);
    app.parse(reversed);
    flags.Resolve();
    if (!calib.empty()) flags.options.candidates.rectified = true;
    if (rectified) flags.options.candidates.rectified = true;
    flags.UseFeatureNetworkUnlessRectified(flags.options.candidates.rectified);
    (void)flags.options.Check();  // a non-empty reason is the CLI's one-line refusal
  } catch (const CLI::ParseError&) {  // main: one line, exit 2
  } catch (const std::exception&) {   // main: one line, exit 1 or 2
  }
  return 0;
}
