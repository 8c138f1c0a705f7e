#pragma once
// The pick pipeline (THESIS.md section 4): stereo matches -> linear triangulation from both P
// -> rejection (behind a camera, large reprojection residual) -> clustering -> part poses,
// tallest first. One call shared by `pick`, `demo` and the acceptance harness.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "calib/calibration.h"
#include "host/opencl_runtime.h"
#include "vision/sensing/clustering.h"
#include "vision/stereo/matcher_presets.h"
#include "vision/sensing/object_pose.h"
#include "vision/sensing/top_face_edges.h"
#include "vision/stereo/stereo_matcher.h"

namespace hnnstereo::vision {

/// Matcher settings measured to work in the pick cell: calibrated, unrectified pair gated by F
/// (2 px), by the height of the triangulated candidate (-5 to 200 mm above the table), the 8
/// best-correlated candidates per left feature, Canny features, the geometry x similarity
/// objective. These are what `pick` and `serve` run when no matcher flag is given.
MatcherOptions PickCellMatcherOptions();

/// The refinements `pick` and `serve` run on the matches: the right point snapped onto the left
/// point's epipolar line and moved along it to the parabola vertex of ZNCC (sub-pixel).
RefinementOptions PickCellRefinementOptions();

struct PositionSensingOptions {
  MatcherOptions matcher = PickCellMatcherOptions();
  /// Points whose RMS reprojection residual (px, both images) exceeds this are rejected: the two
  /// rays miss each other, so the match is wrong (or F is).
  double max_reprojection_error_px = 2.0;
  /// Points on edges within this angle (degrees) of their epipolar line are weak: along such an
  /// edge every position correlates alike, so the depth is a guess (their x, y are nearly
  /// right). They help the clustering join a part's edges but never decide its height or pose.
  /// In the thesis cell the baseline runs along world y, so part edges along y are weak.
  /// 0 makes every point strong.
  double min_edge_epipolar_angle_deg = 20.0;
  ClusteringMethod clustering = ClusteringMethod::kGrid;
  GridClusteringOptions grid;
  LeaderClusteringOptions leader;
  ObjectPoseOptions pose;
  /// Grid clustering: join islands of points inside a larger part's top face at its height
  /// (engraved marks far from the outline); see MergeTopFaceIslands.
  bool merge_top_face_islands = true;
  /// ... unless the left image shows the two pieces as two faces (vision/top_face_edges.h,
  /// LookAcrossGap): the joint top's sides that would run across the gap between them keep
  /// their face's polarity on less than top_edges.min_side_support of it, and each piece ends
  /// at an edge - the side of its own minimum-area rectangle that faces the other - both faces
  /// brighter than the gap (or both darker), on at least top_edges.min_end_support of it. Two
  /// parts side by side at one height show the ground, their walls and shadows between them
  /// (default seeds 155183: two boxes 17 mm apart in a row, 17139: two at yaws 37 degrees
  /// apart, each pair joined into one flagged top, both missed); the pieces of one plain face
  /// show its sides across the gap, and no edge where its points stop.
  bool join_islands_seen_as_one_face = true;
  /// Two pieces whose joint top (minimum-area rectangle of their top points) would be longer
  /// than max_whole_top_length_mm are not joined: the joint part would be flagged as parts
  /// joined (below), where each piece may be a whole part (default 419163: two 11 mm boxes
  /// 58 and 59 mm long, 72 mm apart centre to centre; 419168: two 130 mm boxes; all four
  /// lost as one flagged false part).
  bool keep_apart_longer_than_any_part = true;
  /// Parts with fewer strong points (after island merging) are dropped: occlusion and shadow
  /// boundaries give small, view-dependent clusters. Measured on seeds 100-119: false parts had
  /// 20-50 strong points, true ones well over 100.
  int min_strong_points = 60;
  /// ... except that a part with at least this many strong points (and fewer than
  /// min_strong_points) is kept when nothing flags it: after every check below (fill, width,
  /// touching, image fit, shadow strip...) it is a whole top face, neither merged nor cut. A
  /// small box whose long sides run along the epipolar lines keeps only its short sides' points
  /// strong (default seed 155008: a 54 x 29 x 25 mm box with 51 strong points, its top a full
  /// 54.2 x 28.4 mm rectangle); the false parts of shadow and occlusion boundaries under 60
  /// points (default 135000-135199, 155000-155199: 20-57 points) are all slivers or partial
  /// outlines that the checks flag. Half of min_strong_points, set once; 0 or anything >=
  /// min_strong_points turns the exception off.
  int min_strong_points_whole_top = 30;
  /// Parts whose top layer (ObjectPoseOptions::top_layer_mm) holds fewer than this fraction of
  /// their strong points are dropped: a cluster spread over heights is a vertical structure (a
  /// part's side seen against its shadow), not a top face. Seeds 100-119: true parts 0.89-1.0,
  /// the one such false part 0.26. 0 keeps all.
  double min_top_fraction = 0.5;
  /// Parts whose top face's minimum-area rectangle is narrower than this (mm) are dropped: a
  /// line of points at one height - an edge across a tall part's side face - is not a top face,
  /// and no gripper takes a part that thin. Seed 11 with 4 objects: a 52.5 x 0.56 mm "part" at
  /// 67.7 mm on the side of a 143 mm box; the narrowest true top face in seeds 100-119 is far
  /// wider (the renderer's smallest side is SceneRenderOptions::min_side_mm, 25 mm). 0 keeps all.
  double min_top_width_mm = 5.0;
  /// A part whose top face is not round and fills less than this fraction of its minimum-area
  /// rectangle (ObjectPose::top_fill) is touching parts the clustering could not separate: it is
  /// reported with `merged` set (OBJECTS.json "merged": true), and the robot's safety gate
  /// refuses it, since its pose may lie between two parts. Tops whose hull fits a circle to
  /// max_round_top_roundness of its radius (ObjectPose::top_roundness: a disc fills only pi / 4
  /// of its square) are not flagged by this rule. 0 flags none.
  double min_top_fill = 0.8;
  /// ... that circle's RMS residual over its radius: a disc's rim scatters about 0.5 mm, 1-2 %
  /// of its radius. It was 0.06: on the default and gap0 stress logs of 13000, 35000, 39000 and
  /// 99000 every top it exempted was a box (0.037-0.057; gap0 99051: a 73 x 34 mm box seen as
  /// 60 x 34, fill 0.76, roundness 0.041, reported unflagged 7.1 mm off).
  double max_round_top_roundness = 0.03;
  /// ... unless they fill less than this fraction of their rectangle: any piece of a disc (a
  /// circular segment) fills at least 2/3 of its rectangle, while a few hull vertices of a
  /// partial outline fit some circle by chance (`--min-gap 0`, seed 9029: a 72 x 27 mm piece
  /// of a box's outline, fill 0.52, roundness 0.023, its pose 4.9 mm off and unflagged).
  double min_round_top_fill = 0.6;
  /// A part counts as touching another when at least touch_min_points of the other parts'
  /// points (strong, 5 mm or more above the table) lie within this distance (mm) of its top
  /// face's rectangle in the table plane, or, for points 5 mm or more above its top, when their
  /// ray from either camera meets the plane of its top that near the rectangle: a taller
  /// neighbour that hides part of the top from a camera cuts the rectangle there
  /// (ObjectPose::touching_points). render's parts stand at least 15 mm apart unless
  /// `--min-gap` says otherwise. In a cell that picks tallest first and senses again after
  /// each pick, a part refused for a taller neighbour's shadow is seen whole once that
  /// neighbour is gone.
  double touch_reach_mm = 12.0;
  int touch_min_points = 3;
  /// A part whose own cluster holds at least this many strong points more than 5 mm above its
  /// top (ObjectPose::points_above_top) is touching a taller part the clustering joined to it
  /// and did not report: the lower top is the densest, the taller part's walls stretch its
  /// rectangle (`--min-gap 0`, seeds 59044 and 59096: 159 and 130 such points, centres 13 and
  /// 18 mm off; good poses beside a taller part hold up to hundreds too, but fill their
  /// rectangle). 0 disables it.
  int min_points_above_top = 10;
  /// A touching part that is not round is flagged merged when its top fills less than this
  /// fraction of its rectangle: beside a neighbour, a top that is not a full rectangle was
  /// either cut by the neighbour (hidden corners, the rectangle shifted) or stretched by it (a
  /// neighbour's edge in line) or joined with it, and its centre may be several mm off.
  /// `--min-gap 0`, seeds 19007, 19027, 39002, 39036, 39042, 39062, 39076, 59044, 59096:
  /// fills 0.73-0.90, centres 4.4-34 mm off, unflagged under min_top_fill alone. 0 disables
  /// the rule.
  double min_touching_top_fill = 0.9;
  /// A part that is not round with at least this many strong points of taller parts (more than
  /// top_layer_mm above its top) within touch_reach_mm of its rectangle in the table plane
  /// (ObjectPose::taller_touching_points) is flagged merged: the taller neighbour's walls hide
  /// a strip of its top from the camera on that side, and a straight strip leaves a full
  /// rectangle that min_touching_top_fill passes (`--min-gap 0`, seeds 39001 and 119031: 67 x
  /// 47 and 68 x 43 mm tops seen as 58 x 48 and 57 x 26, fills 0.96 and 0.92, 4.6 and 9.2 mm
  /// off, 13 and 16 such points). It costs picks only out of order: the tallest part of a
  /// touching group has no taller neighbour, so a cell that picks tallest first and senses
  /// again after each pick is never refused its next pick by this rule. On gap0 39000-39099 it
  /// flagged 37 of 460 good poses (8 %), on default 13000-13199 none. 0 disables.
  int min_taller_touching_points = 10;
  /// A part whose top face's rectangle is narrower than this (mm), yet at least
  /// min_top_width_mm, is a piece of a face, not a face: flagged merged. render's narrowest side
  /// is 25 mm (SceneRenderOptions::min_side_mm) and every part found within 4 mm of its centre
  /// on the stress seeds measured at least 20 mm wide; `--min-gap 0`, seed 29020: a 68 mm round
  /// top seen as a 27 x 8 mm piece, its pose 5.6 mm off. Lower it for thinner parts; 0 disables.
  double min_whole_top_width_mm = 18.0;
  /// A part whose top face's rectangle is longer than this (mm) is two parts or more that the
  /// clustering joined: flagged merged. render's longest side is 75 mm
  /// (SceneRenderOptions::max_side_mm) and every part found within 4 mm of its centre on the
  /// stress seeds measured at most 81.5 mm long; `--min-gap 0`, seed 79045: two touching parts
  /// of equal height joined into a 119 x 66 mm top that filled 0.80 of its rectangle, reported
  /// unflagged 27 mm from either. Raise it for longer parts; 0 disables.
  /// A cluster whose top is both longer than this and narrower than min_whole_top_width_mm is
  /// no part and no union of parts (each is at least that wide) but a line across parts, and
  /// is dropped like one narrower than min_top_width_mm (default seeds 55091 and 55141: 203 x 6
  /// and 221 x 10 mm strips at 107 and 45 mm, false parts; no such top on the stress logs was
  /// within 25 mm of a true centre).
  double max_whole_top_length_mm = 95.0;
  /// A part whose top face's outline (its rectangle's corners, or its circle when round) at
  /// its height projects within this many pixels of either image's border, or beyond it, may be
  /// cut by the field of view: its pose is the centre of the piece in view. Flagged merged and
  /// ObjectPose::at_image_border. `--min-gap 0`, seed 69062: a 73 x 61 mm box's top cut by the
  /// bottom border of both images, seen as 61 x 47 mm, its pose 13.8 mm off. 0 disables.
  double image_border_px = 4.0;
  /// A part beside a line of points at its top's height (within top_layer_mm) that was dropped
  /// as narrower than min_top_width_mm, at most this far (mm) from its top's rectangle, may be
  /// missing that piece of its top: a plain top's far edge the island merge did not join
  /// (`--min-gap 0`, seed 69062: a 73 x 61 mm top's far edge, 84 points 27 mm away, left out;
  /// the pose 13.8 mm off). Flagged merged and ObjectPose::piece_left_out. 0 disables.
  double left_out_piece_reach_mm = 30.0;
  /// The same for a sliver reported as a part: a top beside a part narrower than
  /// min_whole_top_width_mm (itself flagged) at its height (within the 2 mm that the pieces
  /// of one face agree to, ObjectPoseOptions::max_split_height_difference_mm), within
  /// left_out_piece_reach_mm, may be the rest of that face, and its pose the centre of a piece
  /// (default seed 289060: a 67 x 51 mm top, 146 mm tall, seen as a 60 x 16 mm strip and a
  /// 67 x 37 mm rest that fitted a partly seen disc, sent 13.3 mm off). Flagged merged and
  /// ObjectPose::piece_left_out.
  bool flag_tops_beside_slivers = true;
  /// A box whose top has an empty strip (at most max_shadow_strip_points strong points at any
  /// height) between one of its sides and a taller part up to this far (mm) beyond it, along
  /// at least half that side, is flagged merged (ObjectPose::shadow_strip_mm): nothing shows
  /// that the top ends at that side, and the taller part's shadow can hide the rest of it
  /// where the face's outline has no contrast left (`--min-gap 0`, seed 179050: a 75 x 50 mm
  /// top whose far 7 mm lie in a 115 mm neighbour's shadow, as dark as the ground around, seen
  /// 68 mm long, 4.0 mm off). Checked after the image-edge fit below. 0 disables.
  double shadow_strip_reach_mm = 20.0;
  int max_shadow_strip_points = 2;
  /// A box whose top keeps a side with no edge under it in the left image, which the
  /// image-edge fit below could place neither in nor out (ObjectPose::unplaced_sides), is
  /// flagged merged: nothing in the image confirms where its face ends on that side, and the
  /// points alone put it there (default 145009: a 69 x 56 mm top stretched 13 mm by points
  /// beyond it, 5.5 mm off and turned 90 degrees; gap0 189079: a 68 x 48 mm top whose end
  /// edge the matches missed, beside a taller cylinder that blocks the fit, 4.9 mm off).
  /// Needs extend_tops_to_image_edges.
  bool flag_unplaced_sides = true;
  /// Box tops fitted to the left image's edges (vision/top_face_edges.h): each side of a top's
  /// rectangle with no image edge under it moves, at the top's height, out to a straight image
  /// edge that its two neighbouring sides reach, when no matched point seen through the added
  /// strip contradicts a face there (default seed 85011: a 67 x 36 mm top whose end edges lie
  /// along the epipolar lines seen 58 mm long, its centre 4.2 mm off), or in to such an edge
  /// inside it when few of the top's points lie beyond (default seed 85156: a 43 x 36 mm top
  /// stretched 9.7 mm by a taller neighbour's points, 4.6 mm off). The flags above are set from
  /// the points before it; ObjectPose::image_edge_moved_mm says how far it moved the sides.
  bool extend_tops_to_image_edges = true;
  TopFaceEdgeOptions top_edges;
  /// The matches' refinements before triangulation (vision/matcher_presets.h):
  /// PickCellRefinementOptions(), the epipolar snap and the parabola sub-pixel fit of ZNCC
  /// along the epipolar line (docs/position_sensing.md, "Refinements": height p99 0.56 ->
  /// 0.21 mm on default 65000-65199); the left-right check stays off.
  RefinementOptions refinement = PickCellRefinementOptions();
  std::string Check() const;
};

/// What triangulation kept and why it rejected the rest.
struct TriangulationCounts {
  int accepted = 0;
  int behind_camera = 0;      ///< the point is behind either camera
  int large_residual = 0;     ///< reprojection residual above the limit
  int degenerate = 0;         ///< parallel rays
  int edge_along_epipolar = 0;  ///< accepted but weak: edge nearly along its epipolar line
  double mean_residual_px = 0.0;  ///< over the accepted points
};

struct PositionSensingTiming {
  /// ms; `refine` = the matches' refinements (PositionSensingOptions::refinement), apart from
  /// `match`.
  double match = 0, refine = 0, triangulate = 0, cluster = 0, pose = 0, total = 0;
};

struct PositionSensingReport {
  MatchReport match;
  std::vector<Eigen::Vector3d> points_in_world;  ///< accepted triangulated points (mm)
  std::vector<int> match_of_point;               ///< index into match.matches per point
  std::vector<double> reprojection_error_px;     ///< per point
  std::vector<bool> weak;                        ///< per point: edge along the epipolar line
  TriangulationCounts triangulation;
  ClusteringReport clustering;                   ///< labels index points_in_world
  int island_merges = 0;                         ///< top-face islands joined to their part
  int top_level_splits = 0;                      ///< clusters split by SplitTopLevels
  int without_top_face = 0;                      ///< clusters dropped by min_top_fraction
  int narrow_top_face = 0;                       ///< clusters dropped by min_top_width_mm
  int small_flagged = 0;  ///< small parts dropped as flagged (min_strong_points_whole_top)
  int merged = 0;                                ///< parts flagged merged (min_top_fill)
  std::vector<ObjectPose> objects;               ///< tallest first
  PositionSensingTiming timing_ms;
};

/// Matches, triangulates, clusters and estimates poses. `calibration` is required (P1, P2, F).
/// Throws std::invalid_argument on bad options / calibration or when the pair is one image twice
/// (CheckDistinctViews), std::runtime_error when matching fails (no features...).
PositionSensingReport SensePositions(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                     const calib::StereoCalibration& calibration,
                                     const PositionSensingOptions& options, ocl::Runtime* runtime);

/// The same pipeline after matching (tests, and matches from elsewhere). `left_grey` (the left
/// image) is needed for the edge-angle test; empty skips it.
PositionSensingReport SensePositionsFromMatches(MatchReport match,
                                                const calib::StereoCalibration& calibration,
                                                const PositionSensingOptions& options,
                                                const cv::Mat& left_grey = cv::Mat());

/// OBJECTS.json (ARCHITECTURE.md): units, objects {id, centroid, height, yaw_deg, points} tallest
/// first, plus per object yaw_moments_deg and top_rectangle, and a summary of the run.
nlohmann::json ObjectsJson(const PositionSensingReport& report, const PositionSensingOptions& options);

/// The thesis's selective point matching (debug tool): one left point, its epipolar line in the
/// right image cut to the heights z_range_mm, a ZNCC search along it, the best match refined to
/// sub-pixel by a parabola, then triangulated.
struct ProbeOptions {
  int zncc_window = 7;                                ///< odd window side (thesis 7)
  std::pair<double, double> z_range_mm{-5.0, 200.0};  ///< heights searched (mm)
  std::string Check() const;
};

struct ProbeReport {
  Eigen::Vector2d left_point = Eigen::Vector2d::Zero();
  Eigen::Vector2d search_start = Eigen::Vector2d::Zero();  ///< right image, at z_range.first
  Eigen::Vector2d search_end = Eigen::Vector2d::Zero();    ///< right image, at z_range.second
  int positions_tested = 0;          ///< 1-px steps inside the right image
  bool found = false;                ///< a positive correlation peak exists
  Eigen::Vector2d right_point = Eigen::Vector2d::Zero();
  double zncc = 0.0;                 ///< at the best position
  double second_zncc = -1.0;         ///< best elsewhere on the line (beyond one window)
  double epipolar_distance_px = 0.0; ///< of right_point from F x_left
  std::optional<Eigen::Vector3d> point_in_world;
  double reprojection_error_px = 0.0;
};

/// Throws std::invalid_argument when the point is outside the left image or options are bad.
ProbeReport ProbePoint(const cv::Mat& left_grey, const cv::Mat& right_grey,
                       const calib::StereoCalibration& calibration,
                       const Eigen::Vector2d& left_point, const ProbeOptions& options = {});

}  // namespace hnnstereo::vision
