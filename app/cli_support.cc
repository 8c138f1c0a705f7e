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
    if (given(option)) continue;
    if (value == "true" || value == "yes" || value == "on") {
      from_file.push_back(option);
    } else if (value == "false" || value == "no" || value == "off") {
      continue;
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

vision::MatcherPreset MatcherFlags::ShownPreset() const {
  // The defaults shown are the ones that run: those of the default preset (hnn-default), which
  // --preset replaces (tests/app/docs_defaults_test.cc checks them against REPORT.json).
  // Calibrated cells (pick, serve) run hnn-default's feature-network fallback, hnn-geometry-lr.
  return unrectified_cell ? vision::FindPreset("hnn-geometry-lr").value()
                          : vision::AccurateDefaultPreset();
}

void MatcherFlags::AddTo(CLI::App* cmd) {
  auto& o = options;
  cmd->add_option("--features", features,
                  "Feature detector on both images: canny (default), susan-edge, susan-corner, "
                  "moravec, sobel")
      ->capture_default_str();
  cmd->add_option("--max-features", o.features.max_features,
                  "Cap on features per image, kept spread over the image (0 = no cap)")
      ->capture_default_str();
  cmd->add_option("--canny-low", o.features.canny_low, "Canny low threshold")->capture_default_str();
  cmd->add_option("--canny-high", o.features.canny_high, "Canny high threshold")->capture_default_str();
  cmd->add_option("--min-disparity", o.candidates.min_disparity,
                  "Rectified pairs: smallest disparity x_left - x_right (px)")
      ->capture_default_str();
  cmd->add_option("--max-disparity", o.candidates.max_disparity,
                  "Rectified pairs: largest disparity x_left - x_right (px)")
      ->capture_default_str();
  cmd->add_option("--zrange", zrange,
                  "Calibrated pairs: ZMIN,ZMAX (mm) - a candidate whose triangulated point falls "
                  "outside is not a neuron");
  cmd->add_option("--max-epipolar", o.candidates.max_epipolar_distance_px,
                  "Largest distance (px) of a candidate from its epipolar line")
      ->capture_default_str();
  const vision::MatcherPreset shown = ShownPreset();
  top_k_option = cmd->add_option("--top-k", o.candidates.top_k,
                                 "Keep the K best-correlated candidates per left feature (0 = all; "
                                 "default: the preset's)")
                     ->default_str(std::to_string(shown.matcher.candidates.top_k));
  cmd->add_flag("--dense", o.candidates.dense,
                "The thesis's all-pairs network: every left x right pair is a neuron and every "
                "neuron is connected to every other (O((N_L N_R)^2) memory)");
  network_option = cmd->add_option(
      "--network", network,
      "feature (rows = left features, columns = right features) or disparity (columns = "
      "disparity levels at the ZNCC peaks of the row; rectified pairs). Default: the preset's; "
      "hnn-default falls back to feature on calibrated, unrectified pairs")
      ->default_str(shown.matcher.candidates.kind == hnn::NetworkKind::kFeatureVsDisparity
                        ? "disparity"
                        : "feature");
  data_term_option =
      cmd->add_option("--data-term", data_term,
                      "The similarity of windows: census (5 x 5 census, Hamming costs summed over "
                      "13 x 13 with adaptive support weights; hnn-default on rectified pairs) or "
                      "zncc (thesis eq. 6.9 over --zncc-window; the feature network's). Default: "
                      "the preset's")
          ->default_str(shown.matcher.data_term.kind == vision::DataTermOptions::Kind::kCensus
                            ? "census"
                            : "zncc");
  cmd->add_option("--zncc-window", o.zncc_window, "ZNCC window side (odd; thesis 7 or 5)")
      ->capture_default_str();
  AddEngineFlags(cmd);
}

void MatcherFlags::AddEngineFlags(CLI::App* cmd) {
  auto& o = options;
  const vision::MatcherPreset shown = ShownPreset();
  cmd->add_option("--engine", engine,
                  "opencl (default; falls back to cpu with a notice when no OpenCL device "
                  "exists), cpu (C++ reference of the parallel dynamics) or thesis (serial "
                  "asynchronous updates on dense weights)")
      ->capture_default_str();
  cmd->add_option("--device", device,
                  "OpenCL device: index or name substring (else HNNSTEREO_OPENCL_DEVICE, else the "
                  "first GPU, else the first device)");
  cmd->add_option("--preset", preset,
                  "Named settings: hnn-default (geometry x similarity compatibility, the census "
                  "data term on rectified pairs and a left-right check; measured best, "
                  "docs/accuracy.md) or hnn-thesis (the thesis's eq. 6.7 additive compatibility, "
                  "ZNCC, no check)")
      ->capture_default_str();
  objective_option =
      cmd->add_option("--objective", objective,
                      "Compatibility (overrides the preset's: hnn-default geometry-similarity, "
                      "hnn-thesis thesis): thesis (eq. 6.6-6.8), printed0, printed1, printed2, "
                      "geometry-similarity")
          ->default_str(std::string(hnn::ObjectiveName(shown.matcher.energy.objective)));
  cmd->add_flag("--no-lr-check,!--lr-check", no_left_right_check,
                "--no-lr-check skips the preset's left-right consistency check; --lr-check keeps "
                "it (the presets' default)");
  support_radius_option = cmd->add_option(
      "--support-radius", o.energy.support_radius_px,
      "Sparse networks: connect neurons whose left features are within this many px (default: "
      "the preset's)")
      ->default_str(FormatDefault(shown.matcher.energy.support_radius_px));
  AddEnergyFlags(cmd);
}

void MatcherFlags::AddEnergyFlags(CLI::App* cmd) {
  auto& o = options;
  cmd->add_option("--A", o.energy.A, "Energy weight of compatibility (eq. 6.5)")->capture_default_str();
  cmd->add_option("--B", o.energy.B, "Energy weight of row uniqueness")->capture_default_str();
  cmd->add_option("--C", o.energy.C, "Energy weight of column uniqueness")->capture_default_str();
  cmd->add_option("--D", o.energy.D, "Energy weight of the epipolar distance")->capture_default_str();
  cmd->add_option("--lambda", o.energy.lambda, "eq. 6.6 slope")->capture_default_str();
  cmd->add_option("--theta", o.energy.theta, "eq. 6.6 centre")->capture_default_str();
  cmd->add_flag("--distance-attenuation", o.energy.distance_attenuation,
                "Printed-code attenuation of weights between far-apart left features");
  cmd->add_option("--activation", activation, "continuous (default) or discrete")
      ->capture_default_str();
  cmd->add_option("--alpha", o.dynamics.alpha, "Activation gain: V = (1 + tanh(u / alpha)) / 2")
      ->capture_default_str();
  cmd->add_option("--init", initial_state,
                  "Initial state: off, on, random-binary, random, constant, constant-noise, "
                  "correlation")
      ->capture_default_str();
  cmd->add_option("--seed", o.dynamics.seed, "Seed of random initial states and update order")
      ->capture_default_str();
  cmd->add_option("--dt", o.dynamics.time_step, "Euler time step (units of tau)")->capture_default_str();
  stop_option = cmd->add_option(
      "--stop", stop_rule,
      "What ends the parallel engines' run: energy (|dE| below the tolerance, the thesis's rule) "
      "or decisions (every row's winner settled); the default shown is what this command runs")
      ->capture_default_str();
  check_interval_option = cmd->add_option(
      "--check-interval", check_interval,
      "Steps between convergence checks (energy and decisions); the default shown is what "
      "this command runs")
      ->capture_default_str();
  cmd->add_option("--max-steps", o.dynamics.max_steps, "Step limit of the parallel engines")
      ->capture_default_str();
  cmd->add_option("--max-updates", o.dynamics.max_updates,
                  "Update limit of the thesis engine (thesis: 20000)")
      ->capture_default_str();
  cmd->add_option("--decode", decode, "thesis (row max, column max, threshold) or one-to-one")
      ->capture_default_str();
  cmd->add_option("--weights", weight_storage,
                  "opencl engine weight storage: " + hnn::WeightStorageNames() +
                      " (auto: half row blocks when rows are short, else csr; docs/engine.md)")
      ->capture_default_str();
  cmd->add_option("--min-confidence", o.min_confidence,
                  "Keep only matches whose confidence (0-1, MATCHES.csv last column) is at least "
                  "this: fewer, surer matches")
      ->capture_default_str();
  cmd->add_option("--threshold", o.decode.threshold, "Minimum activation of an accepted match")
      ->capture_default_str();
  cmd->add_option("--memory-budget-mb", memory_budget_mb,
                  "Refuse networks that need more memory than this (MB)")
      ->capture_default_str();
}

void MatcherFlags::Resolve() {
  // The library resolves preset + overrides (api/matcher_settings.h), for the CLI, the facade
  // and Python alike: the values CLI11 bound are the base; the string flags, and the flags the
  // preset yields to when given, are the overrides.
  const auto given = [](const CLI::Option* option) { return option && option->count() > 0; };
  // The library allows 0 steps (sizing a network); from the command line it would solve nothing.
  if (options.dynamics.max_steps < 1) {
    throw std::invalid_argument("--max-steps must be >= 1 (0 steps leave every neuron where it "
                                "started: no match)");
  }
  char budget[64];
  std::snprintf(budget, sizeof(budget), "%.17g", memory_budget_mb);
  api::Overrides overrides = {{"features", features},   {"engine", engine},
                              {"init", initial_state},  {"activation", activation},
                              {"decode", decode},       {"memory-budget-mb", budget},
                              {"no-lr-check", no_left_right_check ? "true" : "false"}};
  if (!zrange.empty()) overrides["zrange"] = zrange;
  if (!device.empty()) overrides["device"] = device;
  if (given(objective_option)) overrides["objective"] = objective;
  if (given(network_option)) overrides["network"] = network;
  if (given(data_term_option)) overrides["data-term"] = data_term;
  if (given(top_k_option)) overrides["top-k"] = top_k_option->results().back();
  if (given(support_radius_option)) overrides["support-radius"] = support_radius_option->results().back();
  if (given(stop_option)) overrides["stop"] = stop_rule;
  if (given(check_interval_option)) overrides["check-interval"] = std::to_string(check_interval);
  overrides["weights"] = weight_storage;
  settings = api::ResolveMatcherSettings(preset, overrides, options);
  options = settings.matcher;
  refinement = settings.refinement;
  objective = std::string(hnn::ObjectiveName(options.energy.objective));
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
