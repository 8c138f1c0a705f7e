#pragma once
// Shared pieces of the subcommands: a flat-YAML --config reader for CLI11, matcher options on
// the command line, and the OpenCL runtime with its fallback notice.

#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "api/matcher_settings.h"
#include "host/opencl_runtime.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::app {

/// Expands `--config FILE.yml` (flat YAML: "long-option-name: value" per line, '#' comments,
/// `true`/`false` for flags, lists as [a, b]) into command-line arguments placed after the
/// subcommand; options given on the command line win. Returns `arguments` unchanged when there is
/// no --config. `known_option` (optional) says whether the subcommand has an option "--key": an
/// unknown key is refused naming the file, the line and the key. `origins` (optional) receives,
/// per option taken from the file, "config file 'F' line N, key 'K'" for later messages.
/// Throws std::invalid_argument on an unreadable or malformed file or an unknown key.
std::vector<std::string> ExpandConfigArguments(
    const std::vector<std::string>& arguments,
    const std::function<bool(const std::string&)>& known_option = {},
    std::map<std::string, std::string>* origins = nullptr);

/// Matcher options as command-line flags (features, gating, energy, dynamics, decoding).
struct MatcherFlags {
  vision::MatcherOptions options;
  std::string features = "canny";
  std::string engine = "opencl";
  std::string objective = "geometry-similarity";
  std::string preset = "hnn-default";
  bool no_left_right_check = false;
  vision::RefinementOptions refinement;  ///< from the preset, after Resolve()
  CLI::Option* objective_option = nullptr;
  CLI::Option* network_option = nullptr;
  CLI::Option* data_term_option = nullptr;
  CLI::Option* top_k_option = nullptr;
  CLI::Option* support_radius_option = nullptr;
  CLI::Option* stop_option = nullptr;
  CLI::Option* check_interval_option = nullptr;
  std::string stop_rule = "decisions";
  int check_interval = 2;
  std::string initial_state = "off";
  std::string activation = "continuous";
  std::string decode = "thesis";
  std::string weight_storage = "auto";
  std::string network = "feature";
  std::string data_term = "census";
  std::string zrange;
  double memory_budget_mb = 2048.0;
  std::string device;
  /// Set before AddTo for commands on calibrated, unrectified cells (pick, serve): the help then
  /// shows the defaults that run there (the feature network of hnn-geometry-lr).
  bool unrectified_cell = false;
  api::MatcherSettings settings;  ///< after Resolve(): the library's resolution of the flags
  /// Adds the flags to `cmd`.
  void AddTo(CLI::App* cmd);
  /// Parses the string-valued flags into `options` and applies the preset (its objective unless
  /// --objective was given, its refinements unless --no-lr-check) through
  /// api::ResolveMatcherSettings, as the library facade does; throws std::invalid_argument.
  void Resolve();
  /// The preset's feature-vs-disparity network needs rectified rows: for a calibrated,
  /// unrectified pair fall back to the feature-vs-feature network of preset hnn-geometry-lr
  /// (unless --network was given). Call after Resolve() once the geometry is known.
  void UseFeatureNetworkUnlessRectified(bool rectified);
 private:
  void AddEngineFlags(CLI::App* cmd);  ///< AddTo's engine, device, preset and network flags
  void AddEnergyFlags(CLI::App* cmd);  ///< AddTo's energy, dynamics and decoding flags
  /// The preset whose values --help shows as defaults (the one that runs by default).
  vision::MatcherPreset ShownPreset() const;
};

/// The OpenCL runtime for `engine` == opencl; nullptr for the other engines, or when no OpenCL
/// device exists and none was asked for (the matcher then runs the cpu engine and says so).
/// Throws std::invalid_argument, listing the devices that exist, when `device` (--device) or
/// HNNSTEREO_OPENCL_DEVICE / HNNSTEREO_OPENCL_PLATFORM names a device that does not exist.
std::unique_ptr<ocl::Runtime> OpenRuntimeFor(hnn::EngineKind engine, const std::string& device);

/// Checks, before any work, that every output file can be written: its folder exists and takes
/// a new file (the atomic write's temporary), the path is not a folder, not read-only, and no two
/// outputs are the same file, and none is one of `inputs` (an overlay written over the left
/// image), and image outputs have an extension OpenCV writes. Both hold (option name, path)
/// pairs; empty paths are skipped.
/// Throws std::invalid_argument naming the option and the path.
void CheckOutputsWritable(const std::vector<std::pair<std::string, std::string>>& outputs,
                          const std::vector<std::pair<std::string, std::string>>& inputs = {});

/// Runs `load` (reading the images, the calibration, ...) and turns whatever it throws into
/// std::invalid_argument: an input that cannot be used, found before any work, is a refused
/// setup (exit 2), like a bad option.
template <class Load>
auto AsSetupError(Load&& load) -> decltype(load()) {
  try {
    return load();
  } catch (const std::invalid_argument&) {
    throw;
  } catch (const std::exception& error) {
    throw std::invalid_argument(error.what());
  }
}

/// AsSetupError for the input of `option`: its message names the option ("--dir: ...").
template <class Load>
auto AsSetupError(const std::string& option, Load&& load) -> decltype(load()) {
  try {
    return AsSetupError(std::forward<Load>(load));
  } catch (const std::invalid_argument& error) {
    throw std::invalid_argument(option + ": " + error.what());
  }
}

/// The options whose value is a file the command writes. `--robot dryrun:FILE` writes FILE too.
bool IsOutputOption(const std::string& long_name);

/// The output options that write an image (checked against cv::haveImageWriter before work).
bool IsImageOutputOption(const std::string& option);

/// One guard for every command, run once its command line is parsed and before it works: no
/// output (IsOutputOption, or a dryrun: link's file) may be a file the command reads - the
/// value of any other option that names an existing file, or an existing file directly inside
/// an option's existing folder (calibrate --dir). Paths are compared resolved (`./a` == `a`,
/// links followed). Throws std::invalid_argument naming both options and the path.
void RefuseOutputsOverInputs(const CLI::App& command);

/// Checks that `folder_path` (an output folder the command creates if needed) is not a file and
/// that its nearest existing ancestor is writable. Throws std::invalid_argument naming `option`.
void CheckOutputFolderWritable(const std::string& option, const std::string& folder_path);

}  // namespace hnnstereo::app
