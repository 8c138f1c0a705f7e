// hnnstereo: close-range 3D position sensing with a Hopfield-network stereo matcher.
// Keep main thin: every subcommand is a library call (ARCHITECTURE.md).
//
// One CLI style: every error is one line "hnnstereo: error: ..." on stderr; exit status 0 on
// success, 1 when the work failed (I/O, no features, a link that broke...), 2 when the command
// line, a --config file or the setup is refused before any work (README.md, "Exit status").

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(__SANITIZE_THREAD__)
#include <opencv2/core/utility.hpp>
#endif

#include "app/cli_support.h"
#include "app/commands.h"

namespace {

constexpr int kRuntimeError = 1;
constexpr int kUsageError = 2;

// One line: CLI11 messages may span lines.
std::string OneLine(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

// `--quiet` on every subcommand: those without their own send stdout to /dev/null (errors
// still reach stderr).
void AddQuietEverywhere(CLI::App* app) {
  for (CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) {
    if (sub->get_subcommands([](CLI::App*) { return true; }).empty() &&
        sub->get_option_no_throw("--quiet") == nullptr) {
      sub->add_flag_callback(
          "--quiet",
          [] {
            std::fflush(stdout);
            if (std::freopen("/dev/null", "w", stdout) == nullptr) return;
          },
          "Print nothing on success (errors still go to stderr)");
    }
    AddQuietEverywhere(sub);
  }
}

// Every command refuses, before it works, an output that would overwrite one of its inputs
// (app/cli_support.h, RefuseOutputsOverInputs): one guard, run when the command line is parsed.
void GuardOutputsEverywhere(CLI::App* app) {
  for (CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) {
    sub->parse_complete_callback([sub] { hnnstereo::app::RefuseOutputsOverInputs(*sub); });
    GuardOutputsEverywhere(sub);
  }
}

constexpr const char* kVersion = "hnnstereo 0.1.0";

// `--version` on every command, not only before it.
void VersionEverywhere(CLI::App* app) {
  for (CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) {
    sub->set_version_flag("--version", kVersion);
    VersionEverywhere(sub);
  }
}

// Help laid out the same way everywhere: description, usage, options, then the examples. A
// description that carries its examples ("...\nExample...") gives them to the footer.
void ExamplesAfterOptions(CLI::App* app) {
  for (CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) {
    const std::string description = sub->get_description();
    const auto example = description.find("\nExample");
    if (example != std::string::npos) {
      const std::string footer = sub->get_footer();
      sub->description(description.substr(0, example));
      sub->footer(description.substr(example + 1) + (footer.empty() ? "" : "\n" + footer));
    }
    ExamplesAfterOptions(sub);
  }
}

// The direct subcommand of `app` called `name`, or nullptr.
CLI::App* FindSubcommand(CLI::App& app, const std::string& name) {
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  return nullptr;
}

}  // namespace

int main(int argc, char** argv) {
#if defined(__SANITIZE_THREAD__)
  // ThreadSanitizer builds only (scripts/test.sh --sanitize thread): cv::parallel_for_ runs on
  // Debian's TBB, which is not instrumented, so TSan cannot see its workers' join and reports
  // OpenCV's own loop hand-back (the body's std::function freed after the loop) as a race. The
  // numerics' loops run on the calling thread; the project's own threads (robot links, the serve
  // loop, the web page's workers) are what a TSan run checks.
  cv::setNumThreads(0);
#endif
  CLI::App app{
      "hnnstereo - stereo matching with a continuous Hopfield network (OpenCL), calibration and "
      "3D position sensing for robot pick cells.\n"
      "Run 'hnnstereo <command> --help' for the options of a command. Exit status: 0 ok, 1 the "
      "work failed, 2 usage error (bad option, --config file or refused setup).",
      "hnnstereo"};
  app.require_subcommand(1);
  app.formatter(std::make_shared<hnnstereo::app::SwitchFormatter>());  // before the subcommands
  app.set_version_flag("--version", kVersion);
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
  hnnstereo::app::AddDevicesCommand(app);
  AddQuietEverywhere(&app);
  GuardOutputsEverywhere(&app);
  VersionEverywhere(&app);
  ExamplesAfterOptions(&app);

  std::vector<std::string> arguments(argv, argv + argc);
  if (arguments.size() == 1) {
    // No command: the command list, as a usage error.
    std::cout << app.help();
    return kUsageError;
  }
  std::map<std::string, std::string> config_origins;  // option -> "config file 'F' line N"
  try {
    arguments = hnnstereo::app::ExpandConfigArguments(
        arguments,
        [&](const std::string& option) {
          const CLI::App* sub = FindSubcommand(app, arguments[1]);
          return sub != nullptr && sub->get_option_no_throw(option) != nullptr;
        },
        &config_origins);
    // CLI11 parses a reversed vector without the program name.
    std::vector<std::string> reversed(arguments.rbegin(), arguments.rend() - 1);
    app.parse(reversed);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);
    const std::string& first = arguments.size() > 1 ? arguments[1] : std::string();
    if (FindSubcommand(app, first) == nullptr) {
      std::cerr << "hnnstereo: error: unknown command '" << first << "'\n" << app.help();
      return kUsageError;
    }
    std::string message = OneLine(e.what());
    // A bad value from the --config file: name the file, the line and the key.
    for (const auto& [option, origin] : config_origins) {
      if (message.find(option) != std::string::npos) {
        message += " (" + origin + ")";
        break;
      }
    }
    std::cerr << "hnnstereo: error: " << message << " (see 'hnnstereo " << first << " --help')\n";
    return kUsageError;
  } catch (const std::invalid_argument& e) {
    std::cerr << "hnnstereo: error: " << OneLine(e.what()) << "\n";
    return kUsageError;
  } catch (const std::exception& e) {
    std::cerr << "hnnstereo: error: " << OneLine(e.what()) << "\n";
    return kRuntimeError;
  }
  return 0;
}
