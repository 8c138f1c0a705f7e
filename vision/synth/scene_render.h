#pragma once
// The synthetic pick cell (THESIS.md section 4, ARCHITECTURE.md "render DIR"): the thesis's two
// non-coplanar cameras about 720 mm above a dark, dusty, textured table, metal-like boxes and
// cylinders of varied size, height and yaw, ray cast with diffuse and specular shading, shadows,
// slight blur and sensor noise; plus the circle calibration target rendered at several heights
// (calib/circle_target_render.h) so that the cameras can be calibrated from images instead of
// being taken from the truth. Seeded: the same options give the same pixels.
//
// World frame = the table: z = 0 on the table, z up, millimetres. Textures are functions of the
// surface point in the world (or the object's frame), so both cameras see the same marks.

#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <string_view>
#include <vector>

#include "calib/board_calibration.h"
#include "calib/calibration.h"
#include "calib/circle_calibration.h"

namespace hnnstereo::vision {

/// One part on the table.
struct SceneObject {
  enum class Shape { kBox, kCylinder };
  Shape shape = Shape::kBox;
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  ///< centre of the footprint (table plane)
  /// Box: length along its own x (>= width), width, height. Cylinder: diameter, diameter, height.
  Eigen::Vector3d size_mm = Eigen::Vector3d(40, 30, 20);
  /// Box: angle of its length axis from world +x towards +y, in (-90, 90]. Cylinder: 0.
  double yaw_deg = 0.0;
  double albedo = 0.6;                 ///< grey albedo of the metal in [0, 1]
  std::uint64_t texture_seed = 1;      ///< seeds the brushing and the engraved marks

  double height_mm() const { return size_mm.z(); }
  std::string ShapeName() const { return shape == Shape::kBox ? "box" : "cylinder"; }
  /// The footprint outline (counter-clockwise) in the table plane; 4 corners or a 32-gon.
  std::vector<Eigen::Vector2d> Footprint() const;
};

/// The cameras of the default cell: thesis centres C1 = (86.4, 479.7, 719.9) mm and
/// C2 = (81.1, 291.5, 711.9) mm (188 mm apart, 8 mm height difference: not coplanar), both
/// looking at the work centre with world +x to the right in the image.
struct PickCellCameraOptions {
  int image_width = 640;                                     ///< px
  int image_height = 480;                                    ///< px
  double focal_px = 1100.0;                                  ///< left camera focal length (px)
  /// The right camera's principal point less the image centre (px): its sensor sits off-axis.
  Eigen::Vector2d right_principal_offset_px{4.0, -3.0};
  Eigen::Vector3d left_centre_mm{86.4, 479.7, 719.9};        ///< thesis C1
  Eigen::Vector3d right_centre_mm{81.1, 291.5, 711.9};       ///< thesis C2
  Eigen::Vector3d work_centre_mm{100.0, 385.0, 0.0};         ///< where both cameras look
  /// Brown-Conrady lens distortion of both cameras, OpenCV order k1, k2, p1, p2 [, k3]
  /// (`render --distortion`; vision/synth/lens_model.h); empty = ideal pinhole cameras.
  std::vector<double> distortion;
  std::string Check() const;
  /// The same cameras on sensors of `width` x `height` px: the focal length and the principal
  /// offset scale with the width (the same horizontal field of view; a sensor of another aspect
  /// sees more or less along y). Throws std::invalid_argument outside 64-8192 px.
  void SetResolution(int width, int height);
};

/// "WxH" (e.g. 1280x1024) -> (W, H); throws std::invalid_argument naming `option`.
std::pair<int, int> ParseResolution(const std::string& option, const std::string& text);

/// How the top faces are drawn.
enum class TopTexture {
  kRandom,  ///< brushed metal with 4-8 engraved marks at random places (the default)
  kPlain,   ///< uniform metal: a top face shows only its outline (the hard case for matching)
};
std::string_view TopTextureName(TopTexture texture);  ///< "random" or "plain"
std::optional<TopTexture> ParseTopTexture(std::string_view name);

/// How a scene is drawn.
struct SceneRenderOptions {
  std::uint64_t seed = 1;               ///< everything random derives from this
  int num_objects = 0;                  ///< parts on the table; 0 = drawn from [1, 9] by the seed
                                        ///< (as many of them as fit the work area)
  PickCellCameraOptions cameras;
  double work_half_width_mm = 130.0;    ///< parts lie within work_centre +- this along x (mm)
  double work_half_depth_mm = 100.0;    ///< ... and +- this along y (mm)
  double min_height_mm = 10.0;          ///< part heights drawn uniformly in [min, max] (mm)
  double max_height_mm = 150.0;
  /// Top-face sizes (mm, `render --size-range`): a box's width is drawn in
  /// [min_side, max_side / min_aspect], then its length in [min_aspect * width, max_side]; a
  /// cylinder's diameter in [min_side, max_side]. So the longest side of every top face lies in
  /// [min_side, max_side].
  double min_side_mm = 25.0;
  double max_side_mm = 75.0;
  double min_aspect = 1.2;              ///< box length / width >= this: the yaw is defined
  double cylinder_fraction = 0.25;      ///< probability that a part is a cylinder
  /// Smallest gap between footprints (mm); 0 lets parts touch. 15 mm: the default grid
  /// clustering keeps parts of similar height apart when they stand more than 12.7 mm apart.
  double min_gap_mm = 15.0;
  /// true: an asked-for num_objects that does not fit at these top-face sizes and gap is placed
  /// with the sides and the gap scaled down (x0.85 per try, down to 0.27; size_scale in
  /// RenderedScene), so that every count of `render --objects` (1-30) renders at the default
  /// sizes; a scene that fits as asked is never changed. false: such a count is refused.
  bool shrink_to_fit = false;
  /// Every part's top face must be seen unoccluded by both cameras at this fraction of samples.
  double min_top_visibility = 0.9;
  int image_margin_px = 8;              ///< every part lies this far inside both images
  int supersampling = 2;                ///< rays per pixel along each axis (anti-aliasing)
  double blur_sigma_px = 0.6;           ///< Gaussian blur (optics), px
  double noise_sigma_grey = 2.0;        ///< additive Gaussian sensor noise, grey levels
  TopTexture top_texture = TopTexture::kRandom;  ///< `render --texture`
  /// Per-scene illumination gain (`render --brightness`), drawn uniformly in [min, max] from the
  /// seed (its own random stream: the parts are the same whatever the range); both images and
  /// the whole scene get the same gain, before the sensor noise. 1, 1 = as lit by default.
  double min_brightness = 1.0;
  double max_brightness = 1.0;
  double table_albedo = 0.16;           ///< mean albedo of the dark table
  // The calibration target (target/): a rows x cols circle grid at several heights.
  calib::CircleGridGeometry target_grid{4, 5, 35.0, 8.0};
  /// Heights of the target placements (mm); each also gets its own offset and yaw.
  std::vector<double> target_heights_mm{0.0, 40.0, 80.0, 120.0, 150.0};
  /// The chessboard of target/'s board views (BoardViewPoses), for `calibrate --dir`.
  calib::ChessboardGeometry board;
  std::string Check() const;
};

/// A rendered scene with its truth.
struct RenderedScene {
  cv::Mat left, right;                    ///< 8-bit grey
  calib::StereoCalibration cameras;       ///< the true cameras (P1, P2, F, C1, C2)
  std::vector<SceneObject> objects;       ///< tallest first
  std::uint64_t seed = 0;
  /// Top-face sides and gap as drawn / as asked: below 1 when shrink_to_fit made room.
  double size_scale = 1.0;
};

/// The illumination gain of scene `options.seed` in [min_brightness, max_brightness].
double SceneBrightness(const SceneRenderOptions& options);

/// The parts of scene `options.seed` (tallest first), placed as RenderScene places them but not
/// drawn: cheap, for choosing seeds and splitting results by the parts' sizes. Throws as
/// RenderScene does.
std::vector<SceneObject> PlaceSceneObjects(const SceneRenderOptions& options);

/// The true cameras of the cell (P = K [R | -R C]; with distortion also K1 D1 K2 D2 R T, P then
/// applying to undistorted pixels).
calib::StereoCalibration PickCellCameras(const PickCellCameraOptions& options);

/// Draws the parts (seeded), then ray casts both images. Throws std::invalid_argument on bad
/// options or when the parts cannot be placed (too many for the work area).
RenderedScene RenderScene(const SceneRenderOptions& options);

/// Renders one image of `objects` through `P` (exposed for tests: same world, any camera).
cv::Mat RenderView(const calib::ProjectionMatrix& P, const std::vector<SceneObject>& objects,
                   const SceneRenderOptions& options, std::uint64_t noise_seed);

/// The circle target at options.target_heights_mm seen by both cameras: images and target.yml
/// content (image names "left_<h>.png", "right_<h>.png"). Throws when a placement is not fully
/// visible in both images.
/// Also the chessboard in BoardViewPoses (images "board_left_<i>.png", "board_right_<i>.png").
struct RenderedTarget {
  calib::TargetDescription description;
  std::vector<cv::Mat> left_images, right_images;
  calib::BoardTarget board;
  std::vector<cv::Mat> board_left_images, board_right_images;
};

/// The board's world poses in target/: the first lies on the table (it fixes the world frame),
/// 11 are lifted 40-150 mm and tilted 14-28 deg, 8 lie 30 mm up near the images' corners (some
/// seen whole by one camera only: they calibrate its lens)
/// (RenderTargetPlacements refuses a view that neither camera sees whole).
std::vector<calib::BoardView> BoardViewPoses(const SceneRenderOptions& options);

RenderedTarget RenderTargetPlacements(const calib::StereoCalibration& cameras,
                                      const SceneRenderOptions& options);

/// truth.json: OBJECTS.json's schema (units, objects {id, centroid = top-face centre, height,
/// yaw_deg, points = 0}) plus `shape` and `size`, and the seed.
nlohmann::json TruthJson(const RenderedScene& scene);

/// Reads the objects of a truth.json back (the renderer's parts). Throws std::runtime_error.
std::vector<SceneObject> LoadTruthObjects(const std::string& truth_json_path);

/// Writes a render DIR: left.png, right.png, calib.yml (true cameras), truth.json and target/
/// (images + target.yml). Everything is rendered before anything is written; every file is
/// written atomically. Throws std::runtime_error naming the path on failure.
void WriteSceneDirectory(const RenderedScene& scene, const RenderedTarget& target,
                         const std::string& dir);

}  // namespace hnnstereo::vision
