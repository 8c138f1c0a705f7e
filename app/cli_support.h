#pragma once
// Shared pieces of the subcommands: a flat-YAML --config reader for CLI11, matcher options on
// the command line, and the OpenCL runtime with its fallback notice.

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "host/opencl_runtime.h"
#include "vision/stereo_matcher.h"

namespace hnnstereo::app {

/// Reads "key: value" lines (flat YAML; '#' comments; lists as [a, b]) as CLI11 config items,
/// so that `--config FILE.yml` can hold any long option of a subcommand.
class FlatYamlConfig : public CLI::Config {
 public:
  std::string to_config(const CLI::App* app, bool default_also, bool write_description,
                        std::string prefix) const override;
  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override;
};

/// Matcher options as command-line flags (features, gating, energy, dynamics, decoding).
struct MatcherFlags {
  vision::MatcherOptions options;
  std::string features = "canny";
  std::string engine = "opencl";
  std::string objective = "thesis";
  std::string initial_state = "correlation";
  std::string activation = "continuous";
  std::string decode = "thesis";
  std::string network = "feature";
  std::string zrange;
  double memory_budget_mb = 2048.0;
  std::string device;
  /// Adds the flags to `cmd`.
  void AddTo(CLI::App* cmd);
  /// Parses the string-valued flags into `options`; throws std::invalid_argument.
  void Resolve();
};

/// The OpenCL runtime for `engine` == opencl (nullptr otherwise or when none exists, with a
/// notice on stderr).
std::unique_ptr<ocl::Runtime> OpenRuntimeFor(hnn::EngineKind engine, const std::string& device);

}  // namespace hnnstereo::app
