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
#include "vision/stereo/lens_distortion.h"
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

/// The pick pipeline's settings. Each flag below sets ObjectPose::merged (the robot's safety
/// gate refuses a merged part: its pose may lie between parts or at the centre of a piece of a
/// face); the thresholds are tuned on render's scenes (docs/sensing.md) and each is
/// covered by the PositionSensing test named beside it (tests/vision/position_sensing_test.cc).
struct PositionSensingOptions {
  MatcherOptions matcher = PickCellMatcherOptions();
  /// Points whose RMS reprojection residual (px, both images) exceeds this are rejected: the two
  /// rays miss each other, so the match (or F) is wrong. TriangulationRejectsBehindCameraAndLargeResiduals.
  double max_reprojection_error_px = 2.0;
  /// Points on edges within this angle (degrees) of their epipolar line are weak: along such an
  /// edge every position correlates alike, so the depth is a guess (their x, y are nearly
  /// right). They help the clustering join a part's edges but never decide its height or pose.
  /// 0 makes every point strong.
  double min_edge_epipolar_angle_deg = 20.0;
  ClusteringMethod clustering = ClusteringMethod::kGrid;
  GridClusteringOptions grid;
  LeaderClusteringOptions leader;
  ObjectPoseOptions pose;
  /// Grid clustering: join islands of points inside a larger part's top face at its height
  /// (MergeTopFaceIslands). APlainTopFaceSeenOnlyOnItsOutlineIsOnePart.
  bool merge_top_face_islands = true;
  /// ... unless the left image shows the two pieces as two faces (LookAcrossGap: the joint
  /// top's sides across the gap keep their polarity on less than top_edges.min_side_support,
  /// and both pieces end at an edge on at least top_edges.min_end_support).
  /// TwoBoxesThatTheImageShowsApartStayTwo.
  bool join_islands_seen_as_one_face = true;
  /// ... and unless their joint top would be longer than max_whole_top_length_mm (it would be
  /// flagged as parts joined, where each piece may be a whole part). TwoPiecesLongerThanAnyPartStayTwo.
  bool keep_apart_longer_than_any_part = true;
  /// Parts with fewer strong points (after island merging) are dropped: occlusion and shadow
  /// boundaries give small, view-dependent clusters. AcceptanceOnSeededScenes.
  int min_strong_points = 60;
  /// ... except that a part with at least this many (and fewer than min_strong_points) is kept
  /// when no check flags it: a whole top face, neither merged nor cut (a small box whose long
  /// sides run along the epipolar lines keeps few strong points). 0, or anything >=
  /// min_strong_points, turns the exception off. ASmallBoxWithWeakLongSidesIsKeptWhenNothingFlagsIt.
  int min_strong_points_whole_top = 30;
  /// Parts whose top layer (ObjectPoseOptions::top_layer_mm) holds less than this fraction of
  /// their strong points are dropped: a cluster spread over heights is a vertical structure (a
  /// side seen against its shadow), not a top face. 0 keeps all.
  double min_top_fraction = 0.5;
  /// Parts whose top face's minimum-area rectangle is narrower than this (mm) are dropped: a
  /// line of points at one height (an edge across a tall part's side) is no top face, and no
  /// gripper takes a part that thin. 0 keeps all. ALineOfPointsOnATallPartsSideIsNotAPart.
  double min_top_width_mm = 5.0;
  /// A top that is not round and fills less than this fraction of its minimum-area rectangle
  /// (ObjectPose::top_fill) is touching parts the clustering could not separate: flagged.
  /// 0 flags none. TwoTouchingPartsJoinedIntoOneAreFlagged.
  double min_top_fill = 0.8;
  /// ... unless its hull fits a circle to this RMS residual over the radius
  /// (ObjectPose::top_roundness; a disc's rim scatters 1-2 % of its radius, and a disc fills
  /// only pi / 4 of its square). ABoxTopWhoseHullFitsACircleLooselyIsFlagged.
  double max_round_top_roundness = 0.03;
  /// ... and fills at least this fraction: any piece of a disc (a circular segment) fills at
  /// least 2/3 of its rectangle, while a few hull vertices of a partial outline fit some circle
  /// by chance. APieceOfAnOutlineThatFitsACircleByChanceIsFlagged.
  double min_round_top_fill = 0.6;
  /// A part touches another when at least touch_min_points of the other parts' strong points
  /// (5 mm or more above the table) lie within this distance (mm) of its top's rectangle in the
  /// table plane, or, standing above its top, are seen by either camera through its top's plane
  /// that near the rectangle (ObjectPose::touching_points). TouchingPartsGiveNoUnflaggedPoseBetweenThem.
  double touch_reach_mm = 12.0;
  int touch_min_points = 3;
  /// A part whose own cluster holds at least this many strong points more than 5 mm above its
  /// top (ObjectPose::points_above_top) touches a taller part the clustering joined to it and
  /// did not report. 0 disables. APartJoinedWithATallerUnreportedPartIsFlagged.
  int min_points_above_top = 10;
  /// A touching part that is not round is flagged when its top fills less than this fraction
  /// of its rectangle: the neighbour cut, stretched or joined it, and its centre may be several
  /// mm off. 0 disables. TouchingPartsGiveNoUnflaggedPoseBetweenThem.
  double min_touching_top_fill = 0.9;
  /// A part that is not round with at least this many strong points of taller parts within
  /// touch_reach_mm (ObjectPose::taller_touching_points) is flagged: the taller walls hide a
  /// straight strip of its top, which leaves a full rectangle. A cell that picks tallest first
  /// and senses again is never refused its next pick by it. 0 disables.
  /// ABoxTopCutStraightByATallerNeighbourIsFlagged.
  int min_taller_touching_points = 10;
  /// A part (not round) whose top is narrower than this (mm), yet at least min_top_width_mm, is
  /// a piece of a face: flagged. render's narrowest side is 25 mm
  /// (SceneRenderOptions::min_side_mm); lower it for thinner parts; 0 disables.
  /// ASliverOfATopFaceIsFlagged.
  double min_whole_top_width_mm = 18.0;
  /// A part whose top is longer than this (mm) is parts the clustering joined: flagged. A
  /// cluster both longer than this and narrower than min_whole_top_width_mm is a line across
  /// parts and is dropped. render's longest side is 75 mm (SceneRenderOptions::max_side_mm);
  /// raise it for longer parts; 0 disables. ATopLongerThanAnyPartIsFlagged,
  /// AStripLongerAndNarrowerThanAnyPartIsNoPart.
  double max_whole_top_length_mm = 95.0;
  /// A part whose top's outline at its height projects within this many pixels of either
  /// image's border (or beyond) may be cut by the field of view: flagged and
  /// ObjectPose::at_image_border. 0 disables. ATopCutByTheImageBorderIsFlagged.
  double image_border_px = 4.0;
  /// A part beside a line of points at its top's height (within top_layer_mm), dropped as
  /// narrower than min_top_width_mm, at most this far (mm) from its rectangle, may miss that
  /// piece of its top: flagged and ObjectPose::piece_left_out. 0 disables.
  /// APartBesideAPieceOfItsTopLeftOutIsFlagged.
  double left_out_piece_reach_mm = 30.0;
  /// The same for a sliver reported as a part (narrower than min_whole_top_width_mm, within
  /// ObjectPoseOptions::max_split_height_difference_mm of the top's height, within
  /// left_out_piece_reach_mm). APartBesideASliverOfItsTopIsFlagged.
  bool flag_tops_beside_slivers = true;
  /// A box whose top has an empty strip (at most max_shadow_strip_points strong points at any
  /// height) between a side and a taller part up to this far (mm) beyond it, along at least
  /// half that side, is flagged (ObjectPose::shadow_strip_mm): the taller part's shadow may
  /// hide the rest of its top. Checked after the image-edge fit. 0 disables.
  /// ABoxTopWithAnEmptyStripToATallerPartIsFlagged.
  double shadow_strip_reach_mm = 20.0;
  int max_shadow_strip_points = 2;
  /// A box whose top keeps a side that the image-edge fit could place neither in nor out
  /// (ObjectPose::unplaced_sides) is flagged: only the points put that side there. Needs
  /// extend_tops_to_image_edges. ABoxTopWithASideTheImageDoesNotPlaceIsFlagged.
  bool flag_unplaced_sides = true;
  /// Box tops fitted to the left image's edges (ExtendTopToImageEdges, TurnTopToImageEdges;
  /// vision/top_face_edges.h): a side with no image edge under it moves out to the face's edge,
  /// or in to one inside it. The flags above are set from the points before the fit;
  /// ObjectPose::image_edge_moved_mm says how far it moved the sides.
  /// ABoxTopWhoseEndEdgesAreWeakIsCompletedFromTheImage, ABoxTopStretchedPastItsEdgeMovesInToTheImageEdge.
  bool extend_tops_to_image_edges = true;
  TopFaceEdgeOptions top_edges;
  /// The matches' refinements before triangulation (vision/matcher_presets.h):
  /// PickCellRefinementOptions(), the epipolar snap and the parabola sub-pixel fit of ZNCC along
  /// the epipolar line; the left-right check stays off. SubPixelMatchesTightenTheHeights.
  RefinementOptions refinement = PickCellRefinementOptions();
  /// A calibration with lens distortion (D1, D2): features undistorted as points, windows and
  /// gradients read from the captured images (kPoints), or both images resampled first
  /// (kImages). docs/decisions.md gives the figures behind the default.
  /// PointRouteSensesADistortedCellAsTheImageRouteDoes.
  LensRoute lens_route = LensRoute::kPoints;
  /// The image width (px) that the pixel-unit settings above and the matcher's feature cap are
  /// given for: render's 640 x 480 cell, where they were tuned. SensePositions runs
  /// ScaledForImage(the pair's size); 0 runs every setting as given.
  /// ImagesWiderThanTheReferenceAreSensedWithScaledSettings.
  int reference_image_width_px = 640;
  /// The feature cap grows as s^this (ScaledForImage). The cap keeps features spread over the
  /// image (grid bucketing) and a wider image has s times the edge pixels, so with the cap as
  /// given the features along an edge lie s times further apart and few stay within the 8 px
  /// support radius: tops come apart in pieces, small parts are lost. Chosen on render's scenes
  /// at s = 3.2 (2.5x the features): a smaller exponent leaves some tops in pieces, a larger one
  /// adds match time (docs/sensing.md).
  double feature_cap_exponent = 0.8;
  /// These options for images `size` wide, with s = size.width / reference_image_width_px (the
  /// focal length in px grows with the width at a given field of view, so one px of the
  /// reference spans s px): image_border_px (a margin of the field of view) times s, the
  /// matcher's max_features times s^feature_cap_exponent, and the part-size counts
  /// min_strong_points and min_strong_points_whole_top by the square root of that, as a part's
  /// points grow (with the counts as given, slivers of sides pass as parts). Support radius,
  /// epipolar gate, correlation window and Canny thresholds stay: they describe the image's
  /// sampling, not the scene. No cap (0): the border alone. s <= 1 or reference 0: unchanged.
  PositionSensingOptions ScaledForImage(const cv::Size& size) const;
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
  /// s of PositionSensingOptions::ScaledForImage: the images' width over the reference width
  /// (1 when the settings ran as given).
  double image_scale = 1.0;
  int max_features = 0;                          ///< the feature cap the matcher ran (0: none)
  PositionSensingTiming timing_ms;
};

/// Matches, triangulates, clusters and estimates poses. `calibration` is required (P1, P2, F);
/// the images are as captured: with distortion in the calibration (D1, D2) they are sensed
/// through the lens (options.lens_route), and the report's matches, points and poses are in
/// undistorted pixels (P's) and world mm.
/// Throws std::invalid_argument on bad options / calibration or when the pair is one image twice
/// (CheckDistinctViews), std::runtime_error when matching fails (no features...).
PositionSensingReport SensePositions(const cv::Mat& left_grey, const cv::Mat& right_grey,
                                     const calib::StereoCalibration& calibration,
                                     const PositionSensingOptions& options, ocl::Runtime* runtime);

/// The same pipeline after matching (tests, and matches from elsewhere). `left_grey` (the left
/// image, in the matches' pixels: P's, undistorted when the calibration has distortion) is
/// needed for the edge-angle test; empty skips it. The options are scaled to its size
/// (ScaledForImage) as SensePositions scales them.
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
