#pragma once
// A part's pick pose from its cluster of world points (THESIS.md section 4, thesis 6.2.11):
// the height of its top face above the table, the centre of the top face (where a gripper
// goes), and its orientation in the table plane - from central moments (thesis,
// phi = 0.5 atan2(2 mu11, mu20 - mu02)) and from the top face's minimum-area rectangle.
// Pure geometry over Eigen: no I/O.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <string_view>
#include <optional>
#include <vector>

namespace hnnstereo::vision {

enum class YawMethod {
  kMinAreaRectangle,  ///< long side of the top face's minimum-area rectangle (default)
  kCentralMoments,    ///< thesis: principal axis of the cluster's points in the table plane
};
std::string_view YawMethodName(YawMethod method);  ///< "rectangle" or "moments"
std::optional<YawMethod> ParseYawMethod(std::string_view name);

struct ObjectPoseOptions {
  /// The top face: points within this distance (mm) below/above the top height. About twice the
  /// depth error of one pixel of disparity in the default cell (2.7 mm).
  double top_layer_mm = 5.0;
  /// First guess of the top height: the densest slab of this many times top_layer_mm in Z (the
  /// top face's outline and marks pile up at one height; side edges spread over all heights,
  /// mismatches scatter); the height is then the median Z of the top layer around it.
  /// TopFaceHeightAndCentreIgnoreSidesAndStrayPoints.
  double densest_slab_factor = 1.0;
  /// Centroid: true = centre of the top face's minimum-area rectangle; false = the thesis's mean
  /// of all the cluster's points (x, y), at the top height.
  bool centroid_from_rectangle = true;
  YawMethod yaw_method = YawMethod::kMinAreaRectangle;
  /// The top face's outline (rectangle, hull, circle) ignores top-layer points in groups
  /// (linked within top_group_link_mm) of fewer than this many: a few mismatches at the top
  /// height stretch the rectangle, where a face's outline is one dense chain and its marks
  /// blobs inside it. 0 or 1 keeps every point. ALoneTopPointDoesNotStretchTheRectangle.
  int min_top_group_points = 4;
  double top_group_link_mm = 5.0;
  /// ... or of fewer than this fraction of the largest group's points: a chain at the top
  /// height beyond the face (a neighbour's side edge) is no piece of a face whose outline is
  /// one long chain; a split face's pieces are of one size. 0 keeps them.
  /// ASmallChainBeyondTheFaceDoesNotStretchTheRectangle.
  double min_top_group_fraction = 0.1;
  /// ... unless leaving them out turns the rectangle by more than this (degrees): mismatches
  /// stretch it, but a small nearly square top's own corners orient it.
  /// ASmallTopKeepsTheCornersThatOrientIt.
  double max_trim_yaw_change_deg = 10.0;
  /// ... and a left-out group comes back when most of its points lie within this distance (mm)
  /// of the line of one of the kept rectangle's sides, beyond its end, and the opposite side's
  /// line holds such a group beyond the same end: the face's two far corners, cut off where a
  /// plain top's outline breaks. 0 never restores. AFaceEndCutOffWithTheSmallGroupsComesBack.
  double face_end_line_mm = 1.5;
  /// Round tops: a circle fitted to the top's convex hull vertices with an RMS radial residual
  /// below this fraction of its radius (a rectangle's corners and sides are 10 % or more off
  /// any circle) makes the part round and, with centroid_from_rectangle, its centroid the
  /// circle's centre, which stays put where a neighbour hides part of the disc. Needs 12 hull
  /// vertices and 60 top points. 0 disables the fit. RoundTopCentreFromCircleFitWhenPartlyHidden.
  double max_circle_residual = 0.02;
  /// Partly seen round tops: the hull closes a hidden arc with a chord and keeps a few vertices
  /// inside the circle, yet most still lie on the rim, which FitCircleRobust finds: round when
  /// at least this fraction of the hull vertices lie in one circle's band (0 disables this
  /// second test) ... PartlySeenRoundTopWithPointsInsideItsRimIsRound.
  double min_circle_inlier_fraction = 0.7;
  /// ... the band being this fraction of half the hull's diameter, at least circle_band_min_mm
  /// (the rim's points scatter about 0.5 mm; a band relative to the radius would let a huge
  /// circle pass through any piece of edge) ...
  double circle_band_fraction = 0.03;
  double circle_band_min_mm = 0.5;
  /// ... the top points within that band cover at least this fraction of the rim (10 degree
  /// bins): a rectangle's corners lie on its circumscribed circle, but only short pieces of its
  /// outline do. The whole-hull fit of max_circle_residual must pass this too.
  /// AStripWhoseHullFitsACircleIsNotRound.
  double min_rim_coverage = 1.0 / 3.0;
  /// ... and at most this fraction of the top points lie beyond the band outside the circle:
  /// a disc hides nothing outside its rim, where a disc joined with a neighbour does.
  double max_outside_circle_fraction = 0.02;
  /// Neither fit makes a top round whose hull fills more than this fraction of its minimum-area
  /// rectangle: a disc fills pi / 4 of its square and a disc cut by a chord at most about 0.85
  /// of its rectangle, a rectangle 0.95-0.99. ABoxTopThatFillsItsRectangleIsNoDisc.
  double max_round_top_fill = 0.93;
  /// MergeTopFaceIslands joins two pieces of one split top face when their outlines are at
  /// most this far apart (mm): the featureless middle of a textured top face. Further apart,
  /// they join only when they outline one face together (PiecesOutlineOneFace): a plain top face
  /// shows only its outline, whatever its size.
  double max_top_face_gap_mm = 30.0;
  /// Join same-height pieces further apart than max_top_face_gap_mm when PiecesOutlineOneFace
  /// says they outline one face (false: gap-only joins, for comparison).
  bool join_face_outlines = true;
  /// PiecesOutlineOneFace: a point is on the joint face's outline when it lies within this
  /// fraction of the joint rectangle's width (circle: of its radius), at least top_layer_mm, of
  /// it ...
  double outline_band_fraction = 0.2;
  /// ... and each piece needs this fraction of its top points on the outline ...
  double min_outline_fraction = 0.9;
  /// ... and must be a stretch of it, at least this fraction of the joint rectangle's width
  /// long: a speck of a few points lies on the outline of any rectangle it spans.
  /// SpecksAndLineEndsOutlineNoFaceAndFaceNoEdge.
  double min_outline_piece_fraction = 0.25;
  /// Near pieces (within max_top_face_gap_mm) stay apart when each has an edge facing the other
  /// (PiecesFaceEachOtherWithEdges): points within this distance (mm) of the facing side ...
  double facing_edge_band_mm = 2.0;
  /// ... covering at least this fraction of its length (1 mm bins): two tall boxes may hide the
  /// table between them. TwoTallPartsHidingTheTableBetweenThemStayTwo.
  double min_facing_edge_coverage = 0.6;
  /// ... on a facing side at least this long (mm) when the other piece is a line or a speck
  /// too (at most max_thin_piece_width_mm wide): a thin piece seen end-on, or a speck, faces
  /// another such with no edge; a line pointing end-on at a whole face is no piece of it and
  /// still faces it. SpecksAndLineEndsOutlineNoFaceAndFaceNoEdge.
  double min_facing_side_mm = 5.0;
  double max_thin_piece_width_mm = 6.0;
  /// Two edge strips - pieces at least this many times as long as wide - that are opposite ends
  /// of one face (PiecesAreOppositeEndsOfOneFace) and outline it together join even though they
  /// face each other with full sides: a plain top face under noise and blur often shows only
  /// its two strong edges. No part's top is such a strip (render draws them at most 3:1), and a
  /// joint rectangle that is one outlines no face (pieces in line). 0 disables both.
  /// TwoEdgeStripsOfOnePlainFaceJoinTwoFacesDoNot, PiecesInLineOutlineNoFaceAndTheBaseEdgeIsNotHidden.
  double min_edge_strip_aspect = 6.0;
  /// PiecesAreOppositeEndsOfOneFace: the pieces' rectangles are parallel within this (degrees)
  /// ...
  double max_end_yaw_difference_deg = 5.0;
  /// ... their lengths differ by at most this fraction, and they are shifted along their long
  /// axis by at most this fraction of it. ATopFaceSeenAsItsTwoEndsIsOnePart.
  double max_end_length_difference = 0.15;
  /// ... and when their top heights differ by at most this (mm): the pieces of one face agree to
  /// a millimetre, two parts may differ by anything.
  double max_split_height_difference_mm = 2.0;
  /// ... and when the points at other heights inside their joint top face (mismatches on the
  /// face's texture) are at most this fraction of their points: a gap between two parts shows
  /// the dusty table, dense with points. SplitTopFaceJoinsUnlessTheTableShowsBetween.
  double max_hidden_fraction = 0.08;
  /// ... counting no point within this distance (mm) of their joint outline: the part's own
  /// sides and base edge lie under its top face's outline (up to a few mm inside it through
  /// the calibration) and are not hidden by the face. 0 counts them all.
  /// PiecesInLineOutlineNoFaceAndTheBaseEdgeIsNotHidden.
  double hidden_margin_mm = 3.0;
  /// ... and when at most this many points are seen in the gap between the two pieces (inside
  /// their joint top face, outside both pieces' own tops, more than 2 top layers off its
  /// height): a count, not a fraction, since the table seen between two parts does not grow
  /// with the parts. SplitTopFaceStaysApartWhenAFewPointsShowInTheGap.
  int max_gap_points = 3;
  /// ... counting no point within this distance (mm) of the joint outline (a part's sides and
  /// base edge lie under its top face's outline).
  double gap_margin_mm = 3.0;
  /// SplitTopLevels: a cluster whose top layer holds two heights is two touching parts the
  /// clustering joined. The layer's heights split in two (Otsu) whose means differ by at least
  /// this (mm); one face's points agree to about a millimetre. 0 disables the split.
  /// SplitTopLevelsSeparatesTouchingPartsOfUnequalHeight.
  double min_top_level_difference_mm = 3.0;
  /// ... each level holding at least this fraction of the layer's points (a part's upper sides
  /// in the layer are a few) ...
  double min_top_level_fraction = 0.2;
  /// ... and the two levels' centres (table plane) at least this fraction of the top face's
  /// longest side apart: noise on one face puts its high and low points all over it, two parts
  /// put them side by side.
  double min_top_level_separation = 0.3;
  std::string Check() const;
};

/// A rectangle in the table plane.
struct Rectangle2D {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double length = 0.0;   ///< long side (mm)
  double width = 0.0;    ///< short side (mm)
  double yaw_deg = 0.0;  ///< angle of the long side from +x towards +y, in (-90, 90]
};

struct ObjectPose {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  ///< top-face centre; z = height (mm)
  double height_mm = 0.0;        ///< top face above the table
  double yaw_deg = 0.0;          ///< by options.yaw_method, in (-90, 90]
  double yaw_moments_deg = 0.0;  ///< thesis central moments, in (-90, 90]
  Rectangle2D top_rectangle;     ///< minimum-area rectangle of the top face's points
  /// The top face's hull fits a circle (see max_circle_residual), or most of it does
  /// (see min_circle_inlier_fraction).
  bool round = false;
  /// Area of the top face's convex hull over its rectangle's area (1 for a full rectangle, about
  /// 0.79 for a disc's points in their square): low for the union of two touching faces.
  double top_fill = 0.0;
  /// RMS residual of a circle fitted to the top face's hull vertices over its radius (1 when
  /// fewer than 5): a disc's points, even too few to call it round, stay below a few percent.
  double top_roundness = 1.0;
  Eigen::Vector2d circle_centre = Eigen::Vector2d::Zero();  ///< when round
  double circle_radius = 0.0;    ///< when round (mm)
  /// Touching parts of about equal height that could not be separated, or a top face seen only
  /// in part (a sliver of it, or cut by the image border): the pose may lie between parts or
  /// off the part's centre (OBJECTS.json "merged": true; the robot's safety gate refuses it).
  bool merged = false;
  /// The top face's outline reaches the border of either image (set by SensePositions,
  /// PositionSensingOptions::image_border_px): part of it may be out of view. Implies merged.
  bool at_image_border = false;
  /// A line of points at this top's height beside it was dropped as too narrow to be a part
  /// (set by SensePositions, PositionSensingOptions::left_out_piece_reach_mm): it may be a
  /// piece of this top. Implies merged.
  bool piece_left_out = false;
  /// Points of other parts within PositionSensingOptions::touch_reach_mm of this top face's
  /// rectangle in the table plane (set by SensePositions): a part touching another
  /// (`--min-gap 0`) whose pose the neighbour may have pulled or joined.
  int touching_points = 0;
  /// Strong points of this part's own cluster more than 5 mm above its top (set by
  /// SensePositions): a taller part the clustering joined to it, whose top is not this one.
  int points_above_top = 0;
  /// Strong points of other parts within PositionSensingOptions::touch_reach_mm of this top
  /// face's rectangle in the table plane and more than top_layer_mm above its top (set by
  /// SensePositions): a taller part touching this one.
  int taller_touching_points = 0;
  /// How far (mm, summed over its four sides, in or out) SensePositions moved this top's
  /// rectangle's sides to the left image's edges
  /// (PositionSensingOptions::extend_tops_to_image_edges); 0 = the rectangle of the points.
  double image_edge_moved_mm = 0.0;
  /// Sides of this box's top with no edge under them in the left image that the image-edge
  /// fit could not place either (TopFaceEdgeReport::unplaced_sides; set by SensePositions).
  int unplaced_sides = 0;
  /// Width (mm) of the widest empty strip between a side of this box's top and a taller part
  /// beyond it (set by SensePositions, PositionSensingOptions::shadow_strip_reach_mm): no matched
  /// point at any height lies there, so nothing shows that the top ends at that side; the
  /// taller part's shadow may hide the rest of it. Implies merged. 0 = none.
  double shadow_strip_mm = 0.0;
  int points = 0;                ///< points of the cluster
  int top_points = 0;            ///< of which on the top face
  std::vector<int> point_indices;  ///< into the input points
};

/// Orientation of the principal axis of `points` in (-90, 90] degrees:
/// phi = 0.5 atan2(2 mu11, mu20 - mu02) (thesis 6.2.11). 0 for fewer than two points.
double YawFromCentralMoments(const std::vector<Eigen::Vector2d>& points);

/// Convex hull (Andrew's monotone chain), counter-clockwise, no collinear points.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> points);

/// Minimum-area enclosing rectangle (rotating calipers over the hull: one side of the optimal
/// rectangle lies on a hull edge; Freeman & Shapira 1975). Empty input gives a zero rectangle.
Rectangle2D MinAreaRectangle(const std::vector<Eigen::Vector2d>& points);

/// Distance (mm) from `p` to the outline of `rectangle`, inside or outside it.
double DistanceToRectangleOutline(const Rectangle2D& rectangle, const Eigen::Vector2d& p);

/// Least-squares circle (Kasa: algebraic fit) through `points`; nullopt for fewer than three
/// points or collinear ones. `rms_residual` gets the RMS of |p - centre| - radius.
struct Circle2D {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double radius = 0.0;
  double rms_residual = 0.0;
};
std::optional<Circle2D> FitCircle(const std::vector<Eigen::Vector2d>& points);

/// Circle through most of `points` despite outliers (a disc's hull whose missing arc is closed
/// by a chord): the three-point circle that has the most points within `band` (mm) of its rim,
/// over triples of up to 40 evenly spaced points and no larger than `max_radius`, refined by
/// FitCircle on those points. `inliers` gets their count. nullopt for fewer than three points
/// or when no triple gives a circle.
std::optional<Circle2D> FitCircleRobust(const std::vector<Eigen::Vector2d>& points, double band,
                                        double max_radius, int* inliers);

/// Maps an angle (degrees) to (-90, 90] (an axis, not a direction).
double NormaliseAxisAngle(double angle_deg);

/// The pose of one cluster (`indices` into `points_in_world`). Throws std::invalid_argument on
/// bad options or an empty cluster.
ObjectPose EstimateObjectPose(const std::vector<Eigen::Vector3d>& points_in_world,
                              const std::vector<int>& indices, const ObjectPoseOptions& options = {});

/// Engraved marks and texture inside a large top face are matched, but can lie further from its
/// outline than the clustering's reach and form islands. An island whose top height is within
/// options.top_layer_mm of a larger cluster's and whose top-face centre lies inside that
/// cluster's top-face hull joins it. Returns the merged clusters (largest first) and counts the
/// merges in `merges` when given.
///
/// A top face can also split in two (its texture is sparse across the middle, beyond the
/// clustering's reach). Two clusters whose top heights are within
/// options.max_split_height_difference_mm and
/// whose top faces are at most options.max_top_face_gap_mm apart join when the convex hull of
/// their joint top face is consistent with one solid face: it occludes everything under it and
/// nothing stands on it, so no other point (not `weak`, when given) lies inside that hull more
/// than 2 * top_layer_mm below or above it and more than hidden_margin_mm inside its outline
/// (up to options.max_hidden_fraction of their points: mismatches), and, when the larger one is
/// round, the other lies
/// on its circle (within top_layer_mm). Two parts standing apart show the table, their sides or
/// other parts in the gap between them.
///
/// `seen_apart` (optional) vetoes the join of two pieces that lie apart (neither's centre in the
/// other's hull) when it returns true for their top points (table plane, mm) at their mean top
/// height: the image shows them as two faces (see LookAcrossGap in top_face_edges.h).
using PiecesSeenApart = std::function<bool(const std::vector<Eigen::Vector2d>& piece_a,
                                           const std::vector<Eigen::Vector2d>& piece_b,
                                           double height_mm)>;
std::vector<std::vector<int>> MergeTopFaceIslands(const std::vector<Eigen::Vector3d>& points_in_world,
                                                  std::vector<std::vector<int>> clusters,
                                                  const ObjectPoseOptions& options = {},
                                                  int* merges = nullptr,
                                                  const std::vector<bool>* weak = nullptr,
                                                  const PiecesSeenApart& seen_apart = nullptr);

/// Splits each cluster whose top layer holds two heights side by side (touching parts of unequal
/// height that the clustering joined; see ObjectPoseOptions::min_top_level_difference_mm) into
/// two: its top points by level (each point then taking the level of most of its neighbours
/// within top_group_link_mm, so the noise tails of one level follow their face), its other
/// points to the level of their nearest top point in the table plane. `splits` (optional) gets
/// the number of splits.
std::vector<std::vector<int>> SplitTopLevels(const std::vector<Eigen::Vector3d>& points_in_world,
                                             std::vector<std::vector<int>> clusters,
                                             const ObjectPoseOptions& options = {},
                                             int* splits = nullptr);

/// Whether two same-height pieces of top-face points (table plane, mm) are together the outline
/// of one face: a plain top face shows only its outline, and its edges along the epipolar lines
/// are weak, so it falls apart into parallel edges a face's width apart. True when the joint
/// points' hull fits one circle and min_outline_fraction of them lie on it, or when
/// min_outline_fraction of each piece's points lie within outline_band_fraction of the joint
/// minimum-area rectangle's width from its outline (two parts standing apart put their inner
/// sides deep inside the joint rectangle) and each piece is at least min_outline_piece_fraction
/// of that width long (a speck lies on any outline), unless the joint rectangle is a strip
/// (min_edge_strip_aspect: pieces in line lie on any thin rectangle's outline).
bool PiecesOutlineOneFace(const std::vector<Eigen::Vector2d>& first,
                          const std::vector<Eigen::Vector2d>& second,
                          const ObjectPoseOptions& options = {});

/// Whether two same-height pieces (table plane, mm) are the two strong ends of one face: their
/// minimum-area rectangles parallel (max_end_yaw_difference_deg), of about one length and side
/// by side across it (max_end_length_difference).
bool PiecesAreOppositeEndsOfOneFace(const std::vector<Eigen::Vector2d>& first,
                                    const std::vector<Eigen::Vector2d>& second,
                                    const ObjectPoseOptions& options = {});

/// Whether each piece (table plane, mm) has a dense straight edge - its own minimum-area
/// rectangle's side, at least min_facing_side_mm long where the other is a line or a speck -
/// facing the other: two parts standing apart, not the pieces of one face (the cut across a
/// split textured face is no straight edge).
bool PiecesFaceEachOtherWithEdges(const std::vector<Eigen::Vector2d>& first,
                                  const std::vector<Eigen::Vector2d>& second,
                                  const ObjectPoseOptions& options = {});

/// Poses of all clusters, tallest first (the thesis's pick order).
std::vector<ObjectPose> EstimateObjectPoses(const std::vector<Eigen::Vector3d>& points_in_world,
                                            const std::vector<std::vector<int>>& clusters,
                                            const ObjectPoseOptions& options = {});

}  // namespace hnnstereo::vision
