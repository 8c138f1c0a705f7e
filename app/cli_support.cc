#include "app/cli_support.h"

#include "api/match_pipeline.h"
#include "common/input_limits.h"

#include <opencv2/imgcodecs.hpp>

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <iostream>
#include <sstream>
#include <stdexcept>

namespace hnnstereo::app {
namespace {

std::string Trim(const std::string& text) {
  const auto first = text.find_first_not_of(" \t\r\"'");
  if (first == std::string::npos) return {};
  const auto last = text.find_last_not_of(" \t\r\"'");
  return text.substr(first, last - first + 1);
}

// A number as the help shows it: 12, 0.5.
std::string FormatDefault(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

}  // namespace

std::vector<std::string> ExpandConfigArguments(
    const std::vector<std::string>& arguments,
    const std::function<bool(const std::string&)>& known_option,
    std::map<std::string, std::string>* origins) {
  std::vector<std::string> rest;
  std::string config_path;
  for (std::size_t t = 0; t < arguments.size(); ++t) {
    if (arguments[t] == "--config" && t + 1 < arguments.size()) {
      config_path = arguments[++t];
    } else if (arguments[t].rfind("--config=", 0) == 0) {
      config_path = arguments[t].substr(9);
    } else {
      rest.push_back(arguments[t]);
    }
  }
  if (config_path.empty()) return arguments;
  if (!std::ifstream(config_path)) {
    throw std::invalid_argument("--config file '" + config_path + "' cannot be read");
  }
  std::istringstream input;
  try {
    input.str(calib::ReadTextFileWithin(config_path, "--config file"));
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());  // a refused --config is a usage error (exit 2)
  }
  auto given = [&](const std::string& option) {
    for (const std::string& argument : rest) {
      if (argument == option || argument.rfind(option + "=", 0) == 0) return true;
    }
    return false;
  };
  // Options from the file go right after the subcommand; the command line wins on conflicts.
  std::vector<std::string> from_file;
  std::string line;
  int number = 0;
  while (std::getline(input, line)) {
    ++number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed == "---" || trimmed.rfind("%YAML", 0) == 0) continue;
    const auto colon = trimmed.find(':');
    if (colon == std::string::npos) {
      throw std::invalid_argument("config file '" + config_path + "' line " +
                                  std::to_string(number) + " is not 'key: value'");
    }
    std::string key = Trim(trimmed.substr(0, colon));
    for (char& c : key) {
      if (c == '_') c = '-';
    }
    const std::string option = "--" + key;
    const std::string where =
        "config file '" + config_path + "' line " + std::to_string(number) + ", key '" + key + "'";
    if (key.empty() || key == "config" || (known_option && !known_option(option))) {
      throw std::invalid_argument(where + ": not an option of this command");
    }
    if (origins) (*origins)[option] = where;
    std::string value = Trim(trimmed.substr(colon + 1));
    const std::string negated = "--no-" + key;  // a --x/--no-x pair's off switch
    if (given(option) || given(negated)) continue;
    if (value == "true" || value == "yes" || value == "on") {
      from_file.push_back(option);
    } else if (value == "false" || value == "no" || value == "off") {
      if (known_option && known_option(negated)) from_file.push_back(negated);
    } else {
      if (!value.empty() && value.front() == '[' && value.back() == ']') {
        value = value.substr(1, value.size() - 2);
      }
      from_file.push_back(option);
      from_file.push_back(Trim(value));
    }
  }
  std::vector<std::string> expanded;
  const std::size_t head = std::min<std::size_t>(2, rest.size());  // program, subcommand
  expanded.insert(expanded.end(), rest.begin(), rest.begin() + static_cast<long>(head));
  expanded.insert(expanded.end(), from_file.begin(), from_file.end());
  expanded.insert(expanded.end(), rest.begin() + static_cast<long>(head), rest.end());
  // The command still sees its --config, so the output guard counts the file as an input.
  if (!known_option || known_option("--config")) {
    expanded.push_back("--config");
    expanded.push_back(config_path);
  }
  return expanded;
}

std::string SwitchFormatter::make_option_name(const CLI::Option* option, bool is_positional) const {
  std::string name = CLI::Formatter::make_option_name(option, is_positional);
  for (const char* flag_value : {"{false}", "{true}"}) {
    for (auto at = name.find(flag_value); at != std::string::npos; at = name.find(flag_value)) {
      name.erase(at, std::string(flag_value).size());
    }
  }
  return name;
}

CLI::Option* AddSwitch(CLI::App* cmd, const std::string& name, bool* value, const std::string& help) {
  return cmd->add_flag("--" + name + ",!--no-" + name, *value, help)
      ->option_text(*value ? "(default: on)" : "(default: off)");
}

vision::MatcherPreset MatcherFlags::ShownPreset() const {
  // The defaults shown are the ones that run: the library's resolution of no flag at all, over
  // the base options (tests/app/docs_defaults_test.cc checks them against REPORT.json).
  // Calibrated cells (pick, serve) run hnn-default's feature-network fallback.
  const api::MatcherSettings shown = unrectified_cell
                                         ? api::ResolvePickCellSettings({}, options)
                                         : api::ResolveMatcherSettings(preset, {}, options);
  return {shown.preset, shown.matcher, shown.refinement};
}

CLI::Option* MatcherFlags::AddText(CLI::App* cmd, const std::string& name, std::string_view shown,
                                   const std::string& help) {
  texts_[name] = std::string(shown);
  CLI::Option* option = cmd->add_option("--" + name, texts_[name], help);
  if (!shown.empty()) option->default_str(std::string(shown));
  added_.push_back(option);
  return option;
}

void MatcherFlags::AddOnOff(CLI::App* cmd, const std::string& name, bool shown,
                            const std::string& help) {
  switches_[name] = shown;
  added_.push_back(AddSwitch(cmd, name, &switches_[name], help));
}

void MatcherFlags::AddTo(CLI::App* cmd, bool with_preset) {
  if (with_preset) {
    cmd->add_option("--preset", preset,
                    "Named settings: hnn-default (geometry x similarity compatibility, the census "
                    "data term on rectified pairs and a left-right check; measured best, "
                    "docs/accuracy.md) or hnn-thesis (the thesis's eq. 6.7 additive "
                    "compatibility, ZNCC, no check)")
        ->capture_default_str();
  }
  const vision::MatcherPreset shown = ShownPreset();
  bound_ = shown.matcher;
  refinement_shown_ = shown.refinement;
  AddGatingFlags(cmd);
  AddEngineFlags(cmd);
  AddEnergyFlags(cmd);
  AddDecodingFlags(cmd);
}

void MatcherFlags::AddGatingFlags(CLI::App* cmd) {
  auto& o = bound_;
  AddText(cmd, "features", vision::FeatureDetectorName(o.features.detector),
          "Feature detector on both images: canny, susan-edge, susan-corner, moravec, sobel");
  AddNumber(cmd, "--max-features", o.features.max_features,
            "Cap on features per image, kept spread over the image (0 = no cap)");
  AddNumber(cmd, "--canny-low", o.features.canny_low, "Canny low threshold");
  AddNumber(cmd, "--canny-high", o.features.canny_high, "Canny high threshold");
  AddNumber(cmd, "--min-disparity", o.candidates.min_disparity,
            "Rectified pairs: smallest disparity x_left - x_right (px)");
  AddNumber(cmd, "--max-disparity", o.candidates.max_disparity,
            "Rectified pairs: largest disparity x_left - x_right (px)");
  std::string zrange;
  if (o.candidates.z_range_mm) {
    zrange = FormatDefault(o.candidates.z_range_mm->first) + "," +
             FormatDefault(o.candidates.z_range_mm->second);
  }
  AddText(cmd, "zrange", zrange,
          "Calibrated pairs: ZMIN,ZMAX (mm) - a candidate whose triangulated point falls outside "
          "is not a neuron");
  AddNumber(cmd, "--coarse-to-fine-mp", o.coarse_to_fine.min_megapixels,
            "Rectified pairs of more megapixels than this: match at half size first, then each "
            "feature searches a band of disparities around the half-size answer (0 = never; "
            "docs/matching.md)");
  AddNumber(cmd, "--max-epipolar", o.candidates.max_epipolar_distance_px,
            "Largest distance (px) of a candidate from its epipolar line");
  AddNumber(cmd, "--top-k", o.candidates.top_k,
            "Keep the K best-correlated candidates per left feature (0 = all; default: the "
            "preset's)");
  AddNumber(cmd, "--min-correlation", o.candidates.min_correlation,
            "Drop candidates whose similarity is below this (-1 keeps all)");
  AddOnOff(
      cmd, "dense", o.candidates.dense,
      "The thesis's all-pairs network: every left x right pair is a neuron and every neuron is "
      "connected to every other (O((N_L N_R)^2) memory)");
  AddText(cmd, "network", hnn::NetworkKindName(o.candidates.kind),
          "feature (rows = left features, columns = right features) or disparity (columns = "
          "disparity levels at the similarity peaks of the row; rectified pairs). Default: the "
          "preset's; hnn-default falls back to feature on calibrated, unrectified pairs");
  AddOnOff(cmd, "zncc-peaks", o.candidates.zncc_peaks,
           "Disparity network: candidates only at the similarity peaks along the row (the "
           "preset's)");
  AddOnOff(cmd, "subpixel-peaks", o.candidates.subpixel_peaks,
           "Disparity network: parabola sub-pixel candidate disparities (the preset's)");
  AddText(cmd, "data-term", vision::DataTermKindName(o.data_term.kind),
          "The similarity of windows: census (census transform, Hamming costs summed over "
          "--aggregation-window with adaptive support weights; hnn-default on rectified pairs) "
          "or zncc (thesis eq. 6.9 over --zncc-window; the feature network's). Default: the "
          "preset's");
  AddNumber(cmd, "--census-window", o.data_term.census_window,
            "Census data term: census transform side, 3 or 5");
  AddNumber(cmd, "--aggregation-window", o.data_term.aggregation_window,
            "Census data term: side of the square the Hamming costs are summed over, odd 1..31");
  AddNumber(cmd, "--support-gamma", o.data_term.support_gamma,
            "Census data term: adaptive support weight exp(-|dI| / gamma), grey levels; 0 = box");
  AddNumber(cmd, "--zncc-window", o.zncc_window, "ZNCC window side (odd; thesis 7 or 5)");
}

void MatcherFlags::AddEngineFlags(CLI::App* cmd) {
  AddText(cmd, "engine", vision::EngineName(bound_.engine),
          "opencl (falls back to cpu with a notice when no OpenCL device exists), cpu (C++ "
          "reference of the parallel dynamics) or thesis (serial asynchronous updates on dense "
          "weights)");
  AddText(cmd, "device", "",
          "OpenCL device: index or name substring (else HNNSTEREO_OPENCL_DEVICE, else the first "
          "GPU, else the first device)");
  AddText(cmd, "objective", hnn::ObjectiveName(bound_.energy.objective),
          "Compatibility (default: the preset's; hnn-thesis: thesis): thesis (eq. 6.6-6.8), "
          "printed0, printed1, printed2, geometry-similarity");
  // Pick cells refine with their own options (PositionSensingOptions::refinement: --subpixel),
  // so they take neither the left-right check nor the preset's refinements.
  if (!unrectified_cell) {
    AddOnOff(cmd, "lr-check", refinement_shown_.left_right_check,
             "The preset's left-right consistency check: keep a match only when the search back "
             "from its right point lands on its left point");
    AddRefinementFlags(cmd);
  }
  AddNumber(cmd, "--support-radius", bound_.energy.support_radius_px,
            "Sparse networks: connect neurons whose left features are within this many px "
            "(default: the preset's)");
}

void MatcherFlags::AddRefinementFlags(CLI::App* cmd) {
  vision::RefinementOptions& r = refinement_shown_;
  AddNumber(cmd, "--lr-tolerance", r.left_right_tolerance_px,
            "Left-right check: largest distance (px) of the point found back from the left point");
  AddOnOff(cmd, "subpixel", r.subpixel,
           "Rectified pairs: parabola sub-pixel fit of the similarity");
  AddNumber(cmd, "--subpixel-min-offset", r.subpixel_min_offset_px,
            "The sub-pixel fit leaves a match whose vertex lies closer than this (px) to its whole "
            "pixel");
  AddOnOff(cmd, "epipolar-snap", r.epipolar_snap,
           "Unrectified pairs: move right points onto the left point's epipolar line");
  AddOnOff(cmd, "epipolar-subpixel", r.epipolar_subpixel,
           "Unrectified pairs: parabola sub-pixel fit along the epipolar line");
  AddOnOff(cmd, "second-chance", r.second_chance.enabled,
           "Rectified pairs, disparity network: a second network over the features left "
           "unmatched, its candidates from the matched neighbours' disparities");
}

void MatcherFlags::AddEnergyFlags(CLI::App* cmd) {
  auto& o = bound_;
  AddNumber(cmd, "--A", o.energy.A, "Energy weight of compatibility (eq. 6.5)");
  AddNumber(cmd, "--B", o.energy.B, "Energy weight of row uniqueness");
  AddNumber(cmd, "--C", o.energy.C, "Energy weight of column uniqueness");
  AddNumber(cmd, "--D", o.energy.D, "Energy weight of the epipolar distance");
  AddNumber(cmd, "--T", o.energy.T,
            "Disparity-gradient scale of the compatibility, g = 2 exp(-DG / T) - 1 (eq. 6.8)");
  AddNumber(cmd, "--lambda", o.energy.lambda, "eq. 6.6 slope");
  AddNumber(cmd, "--theta", o.energy.theta, "eq. 6.6 centre");
  AddOnOff(cmd, "distance-attenuation", o.energy.distance_attenuation,
           "Printed-code attenuation of weights between far-apart left features");
  AddText(cmd, "activation", hnn::ActivationName(o.dynamics.activation), "continuous or discrete");
  AddNumber(cmd, "--alpha", o.dynamics.alpha, "Activation gain: V = (1 + tanh(u / alpha)) / 2");
  AddText(cmd, "init", hnn::InitialStateName(o.dynamics.initial_state),
          "Initial state: off, on, random-binary, random, constant, constant-noise, correlation");
  AddNumber(cmd, "--seed", o.dynamics.seed, "Seed of random initial states and update order");
  AddNumber(cmd, "--dt", o.dynamics.time_step, "Euler time step (units of tau)");
  AddText(cmd, "stop", hnn::StopRuleName(o.dynamics.stop_rule),
          "What ends the parallel engines' run: energy (|dE| below the tolerance, the thesis's "
          "rule) or decisions (every row's winner settled); the default shown is what this "
          "command runs");
  AddNumber(cmd, "--check-interval", o.dynamics.energy_interval,
            "Steps between convergence checks (energy and decisions); the default shown is what "
            "this command runs");
  AddNumber(cmd, "--max-steps", o.dynamics.max_steps, "Step limit of the parallel engines");
  AddNumber(cmd, "--max-updates", o.dynamics.max_updates,
            "Update limit of the thesis engine (thesis: 20000)");
}

void MatcherFlags::AddDecodingFlags(CLI::App* cmd) {
  auto& o = bound_;
  AddText(cmd, "decode", hnn::DecodeMethodName(o.decode.method),
          "thesis (row max, column max, threshold) or one-to-one");
  AddText(cmd, "weights", hnn::WeightStorageName(o.opencl.storage),
          "opencl engine weight storage: " + hnn::WeightStorageNames() +
              " (auto: half row blocks when rows are short, else csr; docs/engine.md)");
  AddNumber(cmd, "--min-confidence", o.min_confidence,
            "Keep only matches whose confidence (0-1, MATCHES.csv last column) is at least this: "
            "fewer, surer matches");
  AddNumber(cmd, "--threshold", o.decode.threshold, "Minimum activation of an accepted match");
  memory_budget_mb_ =
      static_cast<double>(o.memory_budget_bytes) / static_cast<double>(hnn::kBytesPerMegabyte);
  AddNumber(cmd, "--memory-budget-mb", memory_budget_mb_,
            "Memory for the network (MB): see --fit-memory-budget");
  AddOnOff(cmd, "fit-memory-budget", o.fit_memory_budget,
           "A sparse network over the memory budget matches an evenly spread share of the left "
           "features that fits (REPORT.json memory_fit); off: refuse the pair");
}

api::Overrides MatcherFlags::GivenOverrides() const {
  api::Overrides overrides;
  for (const CLI::Option* option : added_) {
    if (option->count() == 0) continue;
    const std::string& name = option->get_lnames().front();
    if (auto on = switches_.find(name); on != switches_.end()) {
      overrides[name] = on->second ? "true" : "false";
    } else {
      overrides[name] = option->results().back();
    }
  }
  return overrides;
}

void MatcherFlags::Resolve() {
  // The library resolves preset + overrides (api/matcher_settings.h), for the CLI, the facade
  // and Python alike: the base options, the preset, then the flags given.
  settings = api::ResolveMatcherSettings(preset, GivenOverrides(), options);
  options = settings.matcher;
  refinement = settings.refinement;
  device = settings.device;
}

void MatcherFlags::UseFeatureNetworkUnlessRectified(bool rectified) {
  settings.matcher = options;  // with what the command set since Resolve (e.g. rectified)
  api::UseFeatureNetworkUnlessRectified(rectified, &settings);
  options = settings.matcher;
}

std::unique_ptr<ocl::Runtime> OpenRuntimeFor(hnn::EngineKind engine, const std::string& device) {
  std::string notice;  // the matcher's report names the cpu fallback
  return api::OpenRuntime(engine, device, &notice);
}

bool IsOutputOption(const std::string& long_name) {
  static const std::set<std::string> kOutputs = {"out",       "report",     "overlay",
                                                 "ply",       "histogram",  "energy-plot",
                                                 "plot",      "markdown",   "save-network",
                                                 "disparity"};
  return kOutputs.count(long_name) > 0;
}

bool IsImageOutputOption(const std::string& option) {
  return option == "--overlay" || option == "--histogram" || option == "--energy-plot" ||
         option == "--plot" || option == "--disparity";
}

void RefuseOutputsOverInputs(const CLI::App& command) {
  namespace fs = std::filesystem;
  std::vector<std::pair<std::string, std::string>> outputs, inputs;
  for (const CLI::Option* option : command.get_options()) {
    if (option->get_lnames().empty() || option->get_expected_max() == 0) continue;  // flags
    const std::string name = option->get_lnames().front();
    for (const std::string& value : option->results()) {
      if (value.empty()) continue;
      if (IsOutputOption(name)) {
        outputs.emplace_back("--" + name, value);
      } else if (name == "robot" && value.rfind("dryrun:", 0) == 0) {
        outputs.emplace_back("--robot", value.substr(7));
      } else {
        inputs.emplace_back("--" + name, value);
      }
    }
  }
  std::error_code error;
  auto resolved = [&](const std::string& path) { return fs::weakly_canonical(path, error); };
  for (const auto& [option, path] : outputs) {
    const fs::path target = resolved(path);
    if (error || !fs::exists(target, error)) continue;  // a new file overwrites nothing
    for (const auto& [input_option, input_path] : inputs) {
      if (!fs::exists(input_path, error)) continue;
      const fs::path input = resolved(input_path);
      if (input == target) {
        throw std::invalid_argument(option + " '" + path + "' would overwrite the input " +
                                    input_option);
      }
      if (fs::is_directory(input, error) && target.parent_path() == input) {
        throw std::invalid_argument(option + " '" + path + "' would overwrite a file of the input "
                                    "folder " + input_option + " '" + input_path + "'");
      }
    }
  }
}

void CheckOutputsWritable(const std::vector<std::pair<std::string, std::string>>& outputs,
                          const std::vector<std::pair<std::string, std::string>>& inputs) {
  namespace fs = std::filesystem;
  std::set<fs::path> seen;
  for (const auto& [option, path] : outputs) {
    if (path.empty()) continue;
    const fs::path target = fs::absolute(path).lexically_normal();
    if (!seen.insert(target).second) {
      throw std::invalid_argument(option + " '" + path + "' is also another output of this command");
    }
    std::error_code error;
    for (const auto& [input_option, input_path] : inputs) {
      if (input_path.empty()) continue;
      if (fs::absolute(input_path).lexically_normal() == target ||
          fs::equivalent(input_path, target, error)) {
        throw std::invalid_argument(option + " '" + path + "' would overwrite the input " +
                                    input_option);
      }
    }
    if (fs::is_directory(target, error)) {
      throw std::invalid_argument(option + " '" + path + "' is a folder, not a file");
    }
    if (IsImageOutputOption(option) && !cv::haveImageWriter(path)) {
      throw std::invalid_argument(option + " '" + path + "': no image format has the extension '" +
                                  target.extension().string() + "' (use .png)");
    }
    if (option == "--disparity" && target.extension() != ".pfm" && target.extension() != ".png") {
      throw std::invalid_argument(option + " '" + path + "': use .pfm (float) or .png (16-bit, "
                                  "KITTI scaling)");
    }
    const fs::path folder = target.parent_path();
    if (!fs::is_directory(folder, error)) {
      throw std::invalid_argument(option + " '" + path + "': folder '" + folder.string() +
                                  "' does not exist");
    }
    // Try what the atomic write will do: create a temporary file beside the target.
    const fs::path probe =
        folder / (".hnnstereo-write-test-" + std::to_string(static_cast<long>(::getpid())));
    {
      std::ofstream out(probe);
      if (!out) {
        throw std::invalid_argument(option + " '" + path + "': folder '" + folder.string() +
                                    "' is not writable");
      }
    }
    fs::remove(probe, error);
    if (fs::exists(target, error) && ::access(target.c_str(), W_OK) != 0) {
      throw std::invalid_argument(option + " '" + path + "' exists and is not writable");
    }
  }
}

void CheckOutputFolderWritable(const std::string& option, const std::string& folder_path) {
  namespace fs = std::filesystem;
  if (folder_path.empty()) return;
  std::error_code error;
  fs::path folder = fs::absolute(folder_path).lexically_normal();
  if (fs::exists(folder, error) && !fs::is_directory(folder, error)) {
    throw std::invalid_argument(option + " '" + folder_path + "' is a file, not a folder");
  }
  // The nearest existing ancestor must be writable (the command creates the rest).
  while (!fs::exists(folder, error) && folder.has_parent_path() && folder != folder.parent_path()) {
    folder = folder.parent_path();
  }
  // Try what the command will do (access() says yes to root on /proc and read-only mounts).
  const fs::path probe =
      folder / (".hnnstereo-write-test-" + std::to_string(static_cast<long>(::getpid())));
  if (!fs::is_directory(folder, error) || !fs::create_directory(probe, error)) {
    throw std::invalid_argument(option + " '" + folder_path + "': folder '" + folder.string() +
                                "' is not writable");
  }
  fs::remove(probe, error);
}

}  // namespace hnnstereo::app
