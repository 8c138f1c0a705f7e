#pragma once
// Shared pieces of the subcommands: a flat-YAML --config reader for CLI11, matcher options on
// the command line, and the OpenCL runtime with its fallback notice.

#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "api/matcher_settings.h"
#include "host/opencl_runtime.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::app {

/// Expands `--config FILE.yml` (flat YAML: "long-option-name: value" per line, '#' comments,
/// `true`/`false` for flags - `x: false` gives a pair's `--no-x` - lists as [a, b]) into
/// command-line arguments placed after the subcommand; options given on the command line win.
/// Returns `arguments` unchanged when there is no --config. `known_option` (optional) says whether
/// the subcommand has an option "--key": an unknown key is refused naming the file, the line and
/// the key. `origins` (optional) receives, per option taken from the file, "config file 'F' line N,
/// key 'K'" for later messages. Throws std::invalid_argument on an unreadable or malformed file or
/// an unknown key.
std::vector<std::string> ExpandConfigArguments(
    const std::vector<std::string>& arguments,
    const std::function<bool(const std::string&)>& known_option = {},
    std::map<std::string, std::string>* origins = nullptr);

/// Help that shows a boolean pair `--x,!--no-x` as "--x,--no-x (default: on)" (AddSwitch) instead
/// of CLI11's "--x,--no-x{false}", which reads as if the default were off. Set on the root app
/// before the subcommands are added (they inherit it).
class SwitchFormatter : public CLI::Formatter {
 public:
  std::string make_option_name(const CLI::Option* option, bool is_positional) const override;
};

/// Adds the boolean pair `--name` / `--no-name` bound to `value`, its help showing `*value` (the
/// default that runs) as "(default: on)" or "(default: off)".
CLI::Option* AddSwitch(CLI::App* cmd, const std::string& name, bool* value, const std::string& help);

/// Matcher options as command-line flags (features, gating, energy, dynamics, decoding,
/// refinements), named as api::ResolveMatcherSettings names them: the flags given become its
/// overrides, and --help shows the library's defaults (the base options and the shown preset).
struct MatcherFlags {
  /// Before AddTo: the base the preset and the flags apply to (MatcherOptions{}; pick and serve:
  /// PickCellMatcherOptions()). After Resolve(): the resolved options.
  vision::MatcherOptions options;
  std::string preset = "hnn-default";
  vision::RefinementOptions refinement;  ///< from the preset and the flags, after Resolve()
  std::string device;                    ///< --device, after Resolve()
  /// Set before AddTo for commands on calibrated, unrectified cells (pick, serve): the help then
  /// shows the defaults that run there (the feature network of hnn-geometry-lr).
  bool unrectified_cell = false;
  api::MatcherSettings settings;  ///< after Resolve(): the library's resolution of the flags
  /// Adds the flags to `cmd`; `with_preset` false leaves --preset to the command (eval's
  /// --presets).
  void AddTo(CLI::App* cmd, bool with_preset = true);
  /// The matcher flags given on the command line (or by --config), as resolver overrides.
  api::Overrides GivenOverrides() const;
  /// api::ResolveMatcherSettings(preset, GivenOverrides(), the base options), as the library
  /// facade resolves its overrides; throws std::invalid_argument.
  void Resolve();
  /// The preset's feature-vs-disparity network needs rectified rows: for a calibrated,
  /// unrectified pair fall back to the feature-vs-feature network of preset hnn-geometry-lr
  /// (unless --network was given). Call after Resolve() once the geometry is known.
  void UseFeatureNetworkUnlessRectified(bool rectified);

 private:
  void AddGatingFlags(CLI::App* cmd);      ///< features, candidates and data term
  void AddEngineFlags(CLI::App* cmd);      ///< engine, device, objective and refinements
  void AddRefinementFlags(CLI::App* cmd);  ///< lr-tolerance, sub-pixel and epipolar snap
  void AddEnergyFlags(CLI::App* cmd);      ///< energy and dynamics
  void AddDecodingFlags(CLI::App* cmd);    ///< decoding, confidence and memory
  /// A string-valued flag whose value the resolver parses; `shown` is the default in --help.
  CLI::Option* AddText(CLI::App* cmd, const std::string& name, std::string_view shown,
                       const std::string& help);
  /// A numeric flag bound to `field` (its value the default shown) for CLI11's type check.
  template <class T>
  void AddNumber(CLI::App* cmd, const char* name, T& field, const std::string& help) {
    added_.push_back(cmd->add_option(name, field, help)->capture_default_str());
  }
  /// A `--name` / `--no-name` pair whose default shown is `shown`.
  void AddOnOff(CLI::App* cmd, const std::string& name, bool shown, const std::string& help);
  /// The preset whose values --help shows as defaults (the one that runs by default).
  vision::MatcherPreset ShownPreset() const;
  vision::MatcherOptions bound_;  ///< CLI11's targets for the numeric flags (type checks, help)
  std::map<std::string, std::string> texts_;    ///< CLI11's targets for the string flags
  std::map<std::string, bool> switches_;        ///< CLI11's targets for the boolean flags
  vision::RefinementOptions refinement_shown_;  ///< the shown preset's; targets of its numbers
  double memory_budget_mb_ = 0.0;
  std::vector<CLI::Option*> added_;  ///< every matcher flag, named as the resolver names it
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
