// `hnnstereo calibrate`: parse options into the calib/ options structs, run the calibration,
// write CAL.yml (+ report and overlays) atomically. See docs/calibration.md.
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/cli_support.h"
#include "app/commands.h"
#include "calib/board_calibration.h"
#include "calib/calibration_report.h"
#include "calib/chessboard.h"
#include "calib/circle_calibration.h"
#include "calib/known_points.h"

namespace hnnstereo::app {
namespace {

constexpr const char* kCalibrateHelp =
    R"(Stereo calibration: writes CAL.yml (OpenCV YAML: P1, P2, F, C1, C2, error figures).

Examples:
  calibrate --dir TARGET_DIR --out CAL.yml [--report CALIB.json]
      The route TARGET_DIR/target.yml names: with `board: chessboard` (as `render` writes), a
      chessboard in several poses plus views of it lying on the table: intrinsics with lens
      distortion (K1 D1 K2 D2), stereo R T, and the world frame = the table (z = 0 on it, z
      up, mm) from the table views' world poses; CAL.yml adds world_frame: table and
      world_from_left_camera. Without `board:`, as --target circles --dir.
  calibrate --target circles --dir TARGET_DIR --out CAL.yml [--report CALIB.json]
      The thesis's circle plate (rows x cols circles, default 3 x 3, 25 mm pitch) photographed by
      both cameras at two or more known heights. TARGET_DIR/target.yml (OpenCV YAML):
        rows: 3
        cols: 3
        pitch_mm: 25
        dark_circles: 1        # 1: black circles on a white plate (default), 0: bright circles
        heights:
          - { left: left_0.png, right: right_0.png, origin_mm: [100, 50, 0], yaw_deg: 0 }
          - { left: left_1.png, right: right_1.png, origin_mm: [100, 50, 40], yaw_deg: 0 }
      origin_mm = world position of the centre of circle (row 0, col 0); yaw_deg = turn of the
      plate's +x (along a row, increasing column) about world +z; or give world_from_target (4x4).
      Circles are found and ordered automatically (no clicks). A symmetric grid's rotation is
      taken from the world poses; when the poses cannot tell (plate moved only vertically), the
      labeling that shows world +X pointing rightward in the image is used.
  calibrate --target chessboard --rows R --cols C --square MM --left L1 L2 ... --right R1 R2 ...
            --out CAL.yml
      R x C inner corners (OpenCV sample board: --rows 6 --cols 9). Intrinsics with distortion,
      stereo calibration; world frame = left camera (mm); writes K1 D1 K2 D2 R T too.
  calibrate --points-left FILE --points-right FILE --out CAL.yml
      Known correspondences, one per line "X Y Z u v" (world mm, pixel), '#' comments; at least
      6 points per camera, not all on one plane. Normalised DLT per camera.

Outputs: CAL.yml; with --report a JSON report; an overlay image per camera (detected = green
rings, reprojected = red crosses) named <CAL stem>_left.png / _right.png beside --report (or
beside --out). A table of reprojection errors (MAE = mean absolute, RMS = root mean square, px)
is printed. Nothing is written when calibration fails.)";

struct CalibrateArguments {
  std::string target;
  std::string dir;
  std::string out;
  std::string report;
  int rows = 0;
  int cols = 0;
  double square_mm = 25.0;
  std::vector<std::string> left_images;
  std::vector<std::string> right_images;
  std::string points_left;
  std::string points_right;
  bool no_refine = false;
  std::string threshold = "otsu";
  double intermeans_offset = 40.0;
  bool per_point = false;
};

// Throws std::invalid_argument (a refused setup, exit 2) with `problem` when it is not empty.
void RefuseIf(const std::string& problem) {
  if (!problem.empty()) throw std::invalid_argument(problem);
}

calib::CalibrationResult CalibrateFromPoints(const CalibrateArguments& args,
                                             const calib::DltOptions& dlt_options) {
  if (args.points_left.empty() || args.points_right.empty()) {
    throw std::invalid_argument("--points-left and --points-right go together");
  }
  if (!args.target.empty()) {
    throw std::invalid_argument("give either --points-left/--points-right or --target, not both");
  }
  const calib::KnownPoints left =
      AsSetupError("--points-left", [&] { return calib::ReadKnownPoints(args.points_left); });
  const calib::KnownPoints right =
      AsSetupError("--points-right", [&] { return calib::ReadKnownPoints(args.points_right); });
  return calib::CalibrateFromKnownPoints(left, right, dlt_options);
}

calib::CalibrationResult CalibrateFromCircles(const CalibrateArguments& args,
                                              const calib::DltOptions& dlt_options) {
  if (args.dir.empty()) throw std::invalid_argument("--target circles needs --dir TARGET_DIR");
  calib::CircleCalibrationOptions options;
  options.dlt = dlt_options;
  options.detection.threshold = args.threshold == "intermeans"
                                    ? calib::CircleDetectionOptions::Threshold::kIntermeans
                                    : calib::CircleDetectionOptions::Threshold::kOtsu;
  options.detection.intermeans_offset = args.intermeans_offset;
  RefuseIf(options.Check());
  const calib::TargetImages images =
      AsSetupError("--dir", [&] { return calib::LoadTargetImages(args.dir); });
  return calib::CalibrateCircleTarget(images, options);
}

// `--dir` alone: the route target.yml names - the board (lens distortion, table frame) when it
// has `board:`, else the circle plate as `--target circles --dir`.
calib::CalibrationResult CalibrateFromTargetDir(const CalibrateArguments& args,
                                               const calib::DltOptions& dlt_options) {
  const std::optional<calib::BoardTarget> board =
      AsSetupError("--dir", [&] { return calib::LoadBoardTarget(args.dir); });
  if (!board) return CalibrateFromCircles(args, dlt_options);
  calib::BoardCalibrationOptions options;
  RefuseIf(options.Check());
  // Every image is read before any detection: a missing or unreadable one is a refused setup.
  AsSetupError("--dir", [&] {
    for (const calib::BoardView& view : board->views) {
      calib::ChessboardOptions paths;
      paths.left_images = {view.left_image};
      paths.right_images = {view.right_image};
      calib::LoadChessboardImages(paths);
    }
  });
  return calib::CalibrateBoardTarget(*board, options);
}

calib::CalibrationResult CalibrateFromChessboard(const CalibrateArguments& args) {
  if (args.rows <= 0 || args.cols <= 0) {
    throw std::invalid_argument("--target chessboard needs --rows and --cols (inner corners)");
  }
  calib::ChessboardOptions options;
  options.rows = args.rows;
  options.cols = args.cols;
  options.square_mm = args.square_mm;
  options.left_images = args.left_images;
  options.right_images = args.right_images;
  RefuseIf(options.Check());
  const calib::ChessboardImages images =
      AsSetupError("--left/--right", [&] { return calib::LoadChessboardImages(options); });
  return calib::CalibrateChessboard(options, images);
}

void RunCalibrate(const CalibrateArguments& args) {
  // The outputs are checked before the (seconds of) detection and calibration, and every input
  // is read before it: a missing or unreadable input is a refused setup (exit 2), a target that
  // is not found or a calibration that fails is a failed run (exit 1).
  CheckOutputsWritable({{"--out", args.out}, {"--report", args.report}});
  calib::DltOptions dlt_options;
  dlt_options.refine_nonlinear = !args.no_refine;
  calib::CalibrationResult result;
  if (!args.points_left.empty() || !args.points_right.empty()) {
    result = CalibrateFromPoints(args, dlt_options);
  } else if (args.target == "circles") {
    result = CalibrateFromCircles(args, dlt_options);
  } else if (args.target == "chessboard") {
    result = CalibrateFromChessboard(args);
  } else if (!args.dir.empty()) {
    result = CalibrateFromTargetDir(args, dlt_options);
  } else {
    throw std::invalid_argument(
        "say what to calibrate from: --dir TARGET_DIR, --target circles|chessboard, or "
        "--points-left/--points-right");
  }
  const std::vector<std::string> written =
      calib::WriteCalibrationOutputs(result, args.out, args.report);
  std::cout << calib::FormatReportTable(result.report, args.per_point);
  for (const std::string& path : written) std::cout << "wrote " << path << "\n";
}

}  // namespace

void AddCalibrateCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("calibrate",
                                     "Stereo calibration (circle target, "
                                     "chessboard or known points) -> CAL.yml");
  cmd->footer(kCalibrateHelp);
  auto args = std::make_shared<CalibrateArguments>();
  cmd->add_option("--target", args->target, "circles | chessboard")
      ->check(CLI::IsMember({"circles", "chessboard"}));
  cmd->add_option("--dir", args->dir, "TARGET_DIR with target.yml and the images (board or circles)");
  cmd->add_option("--out", args->out, "CAL.yml to write (OpenCV YAML)")->required();
  cmd->add_option("--report", args->report, "CALIB.json report to write (optional)");
  cmd->add_option("--rows", args->rows, "chessboard inner corners per column");
  cmd->add_option("--cols", args->cols, "chessboard inner corners per row");
  cmd->add_option("--square", args->square_mm, "chessboard square side (mm)")
      ->capture_default_str();
  cmd->add_option("--left", args->left_images, "left chessboard images L1 L2 ...");
  cmd->add_option("--right", args->right_images, "right chessboard images R1 R2 ...");
  cmd->add_option("--points-left", args->points_left, "left camera points file (X Y Z u v)");
  cmd->add_option("--points-right", args->points_right, "right camera points file (X Y Z u v)");
  cmd->add_flag("--no-refine", args->no_refine,
                "keep the linear DLT (skip the nonlinear reprojection-error refinement)");
  cmd->add_option("--threshold", args->threshold,
                  "circle threshold: otsu (thesis text) | intermeans (thesis code, + offset)")
      ->check(CLI::IsMember({"otsu", "intermeans"}))
      ->capture_default_str();
  cmd->add_option("--intermeans-offset", args->intermeans_offset,
                  "grey levels added to the intermeans threshold")
      ->capture_default_str();
  cmd->add_flag("--per-point", args->per_point, "print the per-point error table too");
  cmd->callback([args] { RunCalibrate(*args); });
}

}  // namespace hnnstereo::app
