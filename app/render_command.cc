// `hnnstereo render`: a seeded synthetic pick-cell scene with its truth and calibration target.
#include <chrono>
#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "app/cli_support.h"
#include "app/commands.h"
#include "vision/synth/lens_model.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::app {
namespace {

struct RenderArgs {
  vision::SceneRenderOptions options;
  std::string out;
  std::string size_range, height_range, brightness, texture = "random", resolution, distortion;
  bool min_gap_given = false;
  bool quiet = false;
};

// "MIN,MAX" -> (MIN, MAX) with MIN <= MAX; throws std::invalid_argument naming the flag.
std::pair<double, double> ParseRange(const std::string& flag, const std::string& text) {
  double low = 0.0, high = 0.0;
  char comma = 0;
  std::istringstream in(text);
  if (!(in >> low >> comma >> high) || comma != ',' || !(in >> std::ws).eof() || !(low <= high)) {
    throw std::invalid_argument(flag + " must be MIN,MAX with MIN <= MAX (got '" + text + "')");
  }
  return {low, high};
}

// "k1,k2,p1,p2[,k3]" -> the coefficients; throws std::invalid_argument naming --distortion.
std::vector<double> ParseDistortion(const std::string& text) {
  std::vector<double> coefficients;
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::size_t used = 0;
    double value = 0.0;
    try {
      value = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size()) {
      throw std::invalid_argument("--distortion must be k1,k2,p1,p2[,k3] (got '" + text + "')");
    }
    coefficients.push_back(value);
  }
  if (const std::string problem = vision::CheckDistortion(coefficients); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  return coefficients;
}

void ResolveRenderArgs(RenderArgs& args) {
  vision::SceneRenderOptions& o = args.options;
  if (!args.size_range.empty()) {
    std::tie(o.min_side_mm, o.max_side_mm) = ParseRange("--size-range", args.size_range);
  }
  if (!args.height_range.empty()) {
    std::tie(o.min_height_mm, o.max_height_mm) = ParseRange("--height-range", args.height_range);
  }
  if (!args.brightness.empty()) {
    std::tie(o.min_brightness, o.max_brightness) = ParseRange("--brightness", args.brightness);
  }
  if (!args.resolution.empty()) {
    const auto [width, height] = vision::ParseResolution("--resolution", args.resolution);
    try {
      o.cameras.SetResolution(width, height);
    } catch (const std::invalid_argument& error) {
      throw std::invalid_argument(std::string("--resolution: ") + error.what());
    }
  }
  if (!args.distortion.empty()) o.cameras.distortion = ParseDistortion(args.distortion);
  if (const auto texture = vision::ParseTopTexture(args.texture)) {
    o.top_texture = *texture;
  } else {
    throw std::invalid_argument("unknown --texture '" + args.texture + "' (plain or random)");
  }
  // Sizes and a gap the caller chose are kept (a count that does not fit them is refused); at
  // the defaults, many parts get smaller ones so that every --objects value renders.
  o.shrink_to_fit = args.size_range.empty() && !args.min_gap_given;
  if (const std::string problem = o.Check(); !problem.empty()) throw std::invalid_argument(problem);
}

void RunRender(RenderArgs& args) {
  ResolveRenderArgs(args);
  const auto start = std::chrono::steady_clock::now();
  CheckOutputFolderWritable("--out", args.out);  // before the seconds of ray casting
  vision::PlaceSceneObjects(args.options);  // parts that do not fit: refused before any drawing
  // Everything is rendered before anything is written; progress goes to stderr (seconds).
  if (!args.quiet) std::fprintf(stderr, "rendering the scene (both cameras)...\n");
  const vision::RenderedScene scene = vision::RenderScene(args.options);
  if (!args.quiet) {
    std::fprintf(stderr, "rendering the calibration target at %zu heights...\n",
                 args.options.target_heights_mm.size());
  }
  const vision::RenderedTarget target = vision::RenderTargetPlacements(scene.cameras, args.options);
  vision::WriteSceneDirectory(scene, target, args.out);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (args.quiet) return;
  std::printf("scene seed %llu: %zu parts, %dx%d px, brightness %.2f, target at %zu heights, "
              "%.2f s\n",
              static_cast<unsigned long long>(scene.seed), scene.objects.size(),
              scene.cameras.image_width, scene.cameras.image_height,
              vision::SceneBrightness(args.options), target.description.placements.size(),
              seconds);
  if (scene.size_scale < 1.0) {
    std::printf("%zu parts fit with top faces and gap scaled by %.2f (sides %.0f-%.0f mm, gap "
                "%.1f mm)\n",
                scene.objects.size(), scene.size_scale, args.options.min_side_mm * scene.size_scale,
                args.options.max_side_mm * scene.size_scale,
                args.options.min_gap_mm * scene.size_scale);
  }
  std::printf("%3s %-8s %8s %8s %8s %8s  %s\n", "id", "shape", "x", "y", "height", "yaw", "size");
  int id = 1;
  for (const vision::SceneObject& object : scene.objects) {
    std::printf("%3d %-8s %8.1f %8.1f %8.1f %8.1f  %.0f x %.0f x %.0f\n", id++,
                object.ShapeName().c_str(), object.centre_mm.x(), object.centre_mm.y(),
                object.height_mm(), object.yaw_deg, object.size_mm.x(), object.size_mm.y(),
                object.size_mm.z());
  }
  std::printf("wrote %s/{left.png, right.png, calib.yml, truth.json, target/}\n", args.out.c_str());
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand(
      "render",
      "Render a synthetic pick-cell scene: two cameras about 720 mm above a dark, dusty table "
      "(thesis geometry), metal boxes and cylinders 10-150 mm tall, and the circle calibration "
      "target at several heights.\n"
      "Example:\n"
      "  hnnstereo render --seed 7 --objects 5 --out scene7\n"
      "  hnnstereo calibrate --target circles --dir scene7/target --out scene7/calibrated.yml\n"
      "  hnnstereo pick --left scene7/left.png --right scene7/right.png \\\n"
      "      --calib scene7/calibrated.yml --out scene7/objects.json\n"
      "Writes DIR/left.png, right.png, calib.yml (the true cameras), truth.json (OBJECTS.json "
      "schema plus shape and size; tallest first) and target/ (circle plate and chessboard "
      "images + target.yml: `calibrate --dir DIR/target` or `--target circles --dir`).");
  cmd->add_option("--seed", args->options.seed, "Seed: the same seed gives the same scene")
      ->check(CLI::Validator(
          [](std::string& value) {
            return value.rfind('-', 0) == 0 ? "must be a number >= 0" : std::string();
          },
          "SEED >= 0"))
      ->required();
  cmd->add_option("--objects", args->options.num_objects,
                  "Number of parts (1-30; default: 1-9 drawn from the seed, as many as fit the "
                  "work area). More than fit at the default sizes get smaller top faces and gap "
                  "(render says by how much); with --size-range or --min-gap they are refused")
      ->check(CLI::Range(1, 30));
  cmd->add_option("--out", args->out, "Output folder (created)")->required();
  cmd->add_option("--min-gap", args->options.min_gap_mm,
                  "Smallest gap between parts (mm); 0 lets them touch")
      ->capture_default_str()
      ->each([args](const std::string&) { args->min_gap_given = true; });
  cmd->add_option("--noise", args->options.noise_sigma_grey, "Sensor noise sigma (grey levels)")
      ->capture_default_str();
  cmd->add_option("--blur", args->options.blur_sigma_px, "Gaussian optical blur sigma (px)")
      ->capture_default_str();
  cmd->add_option("--texture", args->texture,
                  "Top faces: random (brushed metal with engraved marks at random places) or "
                  "plain (uniform: only the outline shows)")
      ->capture_default_str();
  cmd->add_option("--size-range", args->size_range,
                  "MIN,MAX (mm): the longest side of every top face lies in [MIN, MAX]; box "
                  "length >= 1.2 x width (default 25,75)");
  cmd->add_option("--height-range", args->height_range,
                  "MIN,MAX (mm): part heights drawn uniformly in [MIN, MAX] (default 10,150)");
  cmd->add_option("--brightness", args->brightness,
                  "LOW,HIGH: per-scene illumination gain drawn uniformly from the seed (default "
                  "1,1)");
  cmd->add_option("--resolution", args->resolution,
                  "WxH: both cameras' image size (px; e.g. 1280x1024, 2048x1536, 2448x2048), "
                  "their focal lengths scaled with the width (default 640x480)");
  cmd->add_option("--distortion", args->distortion,
                  "k1,k2,p1,p2[,k3]: Brown-Conrady lens distortion of both cameras (OpenCV "
                  "order; default none). calib.yml then carries K1 D1 K2 D2 R T; calibrate "
                  "--dir DIR/target models it from the board images");
  cmd->add_flag("--quiet", args->quiet, "Print nothing on success");
  cmd->callback([args] { RunRender(*args); });
}

}  // namespace hnnstereo::app
