#pragma once
// A box's top face completed from one image's edges. The matched points outline a plain top
// face only where its edges cross the epipolar lines well: an end edge along them gives weak or
// wrong matches and the face's rectangle stops short of it, although the image shows that edge
// plainly. Knowing the face's height, each side of the rectangle is pushed outward, at that
// height, to where the image shows a straight edge across the face with the two neighbouring
// sides continuing up to it - the face's outline, model-based verification in the manner of
// Lowe (1987) "Three-dimensional object recognition from single two-dimensional images" - and
// only where no matched point seen through the extension contradicts it (a solid face hides
// what lies under it). Written by hand: OpenCV fits lines to edge points but has no test of a
// given 3D outline against an image.

#include <Eigen/Core>
#include <cmath>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vision/sensing/object_pose.h"

namespace hnnstereo::vision {

struct TopFaceEdgeOptions {
  /// Longest extension of one side (mm). render's tops lose up to a third of a side's length to
  /// weak end edges; a longer reach meets the neighbours' edges.
  double max_extension_mm = 20.0;
  /// Step of the search and spacing of the samples along a side (mm): about 1 px in the cell.
  double step_mm = 0.5;
  /// An image edge at a sample: the 3 x 3 Sobel gradient's component across the projected side
  /// is at least this (grey levels per pixel x 8; Canny's lower threshold 50 is of the same
  /// scale), within 1 px across the side.
  double min_edge_gradient = 50.0;
  /// A side is at an image edge when at least this fraction of its samples are (a face's
  /// outline is continuous in the image; texture and shadows cross it in places) ...
  double min_end_support = 0.7;
  /// ... and the two sides beside it continue over the extension on at least this fraction of
  /// their samples.
  double min_side_support = 0.6;
  /// Samples within this distance (mm) of a corner are left out: corners blur into both sides.
  double corner_margin_mm = 2.0;
  /// A side with no image edge under it but one parallel to it up to this far (mm) inside lies
  /// beyond the face's edge (points at the top height past it): it moves in to that edge,
  /// never out ...
  double max_inward_mm = 15.0;
  /// ... when at most this fraction of the top's points (within top_layer_mm of its height)
  /// lie more than 1.5 mm beyond the edge: a face's outline points lie on it, stray points
  /// beyond it are few; and when the two neighbouring sides do not go on past the edge in the
  /// image (on less than min_side_support of their samples), else the edge is a line on the
  /// face (a shadow's edge, a mark), not its end.
  double max_cut_fraction = 0.2;
  /// An extension is refused when more than this many strong matched points are seen, by
  /// either camera, through it from below its height (more than 2 top layers below, more than
  /// 1 mm inside the extended rectangle): the table or a lower part seen where the extended
  /// face would hide them.
  int max_contradicting_points = 2;
  /// A side at an image edge, or beyond one that the face's sides go past, moves out too when
  /// the face's two sides go on past that edge in the image (on at least min_side_support of
  /// their samples over 4 mm) with the polarity they show along the face (brighter or darker
  /// than the ground beside it): the edge is a line across the face (a neighbour's shadow's
  /// edge, a mark), and the face's end is the next edge out that they reach, under the tests
  /// above, at least 3 mm past the base edge of a wall the camera would see on that line. Past
  /// such a line each side's line may lie out to the wall the camera sees beside that side
  /// (plus 1 mm): in a shadow the face and that wall can be equally dark. An edge found on the
  /// way out is looked past in the same way, and a side at such a line whose end is not found
  /// counts in TopFaceEdgeReport::unplaced_sides. ASideAtAShadowsEdgeAcrossTheFaceMovesOutToTheFacesEnd,
  /// InAShadowASidesEdgeMayBeItsWallsBase (tests/vision/top_face_edges_test.cc).
  bool look_past_lines_on_face = true;
  /// A side counts as at an image edge only when that edge has the polarity the face's outline
  /// shows along its two neighbouring sides (where they agree): the face brighter than what
  /// lies around it, or darker. An edge of the opposite polarity under a side is another
  /// outline (a shadow's far edge on the ground, matched at the top's height), and the side lies
  /// beyond the face's edge. AShadowsFarEdgeIsNoEndOfTheFace.
  bool end_edge_polarity = true;
  /// When the sides move, test them all again from where they now lie: each side's test reads
  /// its neighbouring sides' lines, which may move after it. ABoxTopsSidesAreTestedAgainWhereTheyMoved
  /// (tests/vision/position_sensing_test.cc).
  bool second_pass = true;
  /// A side at a line across the face whose end the search does not find counts as unplaced
  /// only when the face's sides go on past the wall the camera sees beyond it (by 3 mm, over
  /// 4 mm): where they stop there, what went on in line with them was the face's own end
  /// wall, and the side is the face's end. ABoxTopsEndBesideItsOwnWallIsPlaced.
  bool end_at_own_wall = true;
  /// TurnTopToImageEdges: the largest turn tried (degrees either way; 0 disables), its step,
  /// and the gain in gradient along the outline a turn needs over the unturned rectangle.
  double max_yaw_turn_deg = 8.0;
  double yaw_step_deg = 0.25;
  double min_yaw_turn_gain = 0.1;
  std::string Check() const;
};

/// The moves of one top's sides: per side (+length, -length, +width, -width) the distance (mm)
/// it moved outward (negative: inward), 0 where it already lay at an image edge or found none.
struct TopFaceEdgeReport {
  double extension_mm[4] = {0.0, 0.0, 0.0, 0.0};
  double end_support_before[4] = {0.0, 0.0, 0.0, 0.0};  ///< image-edge fraction of each side
  int refused_by_points = 0;  ///< sides whose extension matched points contradicted
  int edge_inside = 0;        ///< sides beyond the face's edge (moved in, or kept when too
                              ///< many of the top's points, or the face's sides, go past it)
  /// Sides with no image edge under them that stayed where the points put them: nothing in
  /// the image confirms where the face ends there.
  int unplaced_sides = 0;
  int line_on_face = 0;  ///< sides at an image edge the face's sides go on past
  int end_edge_reversed = 0;  ///< sides at an edge of the opposite polarity (no face's end)
  bool swapped_sides_refused = false;  ///< no move: they would make the short side the long one
  /// Outward moves summed (inward ones count negative).
  double total_mm() const { return extension_mm[0] + extension_mm[1] + extension_mm[2] + extension_mm[3]; }
  /// Moves summed by size, in or out.
  double moved_mm() const {
    return std::abs(extension_mm[0]) + std::abs(extension_mm[1]) + std::abs(extension_mm[2]) +
           std::abs(extension_mm[3]);
  }
};

/// Turns `pose`'s top rectangle (not round poses) about its centre to where its outline runs
/// along the face's edges in one image: the turn, in steps of yaw_step_deg up to
/// max_yaw_turn_deg either way, with the most gradient along the four sides (each at its best
/// offset within 1.5 mm, weighted by its length), kept when that beats the unturned rectangle
/// by min_yaw_turn_gain. The points' minimum-area rectangle takes its yaw from the outline
/// points, which scatter and stop short where the edges run along the epipolar lines. Updates
/// the rectangle's yaw and, when `yaw_from_rectangle`, the pose's; returns the turn (degrees).
double TurnTopToImageEdges(ObjectPose* pose, const Eigen::Matrix<double, 3, 4>& P,
                           const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                           bool yaw_from_rectangle, const TopFaceEdgeOptions& options = {});

/// What ExtendTopToImageEdges reads besides the pose: one image, the other parts' tops and the
/// triangulated points (for the occlusion test), and the limits of the top.
struct TopFaceEdgeInputs {
  const Eigen::Matrix<double, 3, 4>& P;  ///< the image's 3 x 4 projection (world mm -> px)
  const cv::Mat& gradient_x;  ///< the image's 3 x 3 Sobel gradient in x (CV_32F)
  const cv::Mat& gradient_y;  ///< ... and in y
  /// The other parts' tops (table plane; a round one as its circle's square): no side enters
  /// one (1 mm apart).
  const std::vector<Rectangle2D>& others;
  /// All triangulated points (world mm) and which are weak; the pose's point_indices index them.
  const std::vector<Eigen::Vector3d>& points;
  const std::vector<bool>& weak;
  /// The centres (world mm) of the cameras that saw the points, P's camera first: a point seen
  /// through an extension from below the top contradicts it.
  const std::vector<Eigen::Vector3d>& camera_centres;
  double top_layer_mm;  ///< ObjectPoseOptions::top_layer_mm: points this near the top are on it
  double max_length_mm;  ///< no top grows longer than this (mm; the longest part)
  bool centroid_from_rectangle;  ///< move the pose's centroid x, y with the rectangle
};

/// Moves the sides of `pose`'s top rectangle (not round poses) in or out to the face's edges in
/// one image (see TopFaceEdgeOptions and TopFaceEdgeInputs). Updates the rectangle and, when
/// `centroid_from_rectangle`, the centroid's x, y; the yaw does not change here
/// (TurnTopToImageEdges turns it; moves that would make the short side the long one are all
/// undone). Covered by tests/vision/top_face_edges_test.cc.
TopFaceEdgeReport ExtendTopToImageEdges(ObjectPose* pose, const TopFaceEdgeInputs& inputs,
                                        const TopFaceEdgeOptions& options = {});

/// What one image shows between two pieces of top-face points at one height that lie apart
/// along an axis of their joint minimum-area rectangle (LookAcrossGap).
struct GapBetweenPieces {
  /// The joint rectangle's sides that run across the gap (sampled over the gap less the corner
  /// margin at each end, each at its best offset within 2 mm): the higher of the two sides'
  /// fractions of samples with the polarity that side shows on the whole (brighter or darker
  /// than the ground beside it; PolarSupport, min_edge_gradient). One plain face seen as its
  /// two strong ends keeps its sides across the gap; a shadow across it dims but does not hide
  /// them (ambient light).
  double sides_support = 0.0;
  /// The pieces' ends facing each other: the side of each piece's own minimum-area rectangle
  /// that faces the other piece (less the corner margins, at its best offset within 2 mm):
  /// the lower of the two ends' fractions of samples that are edges with both faces brighter
  /// than the gap (or both darker). Two parts side by side, whatever their yaws, each end at
  /// an edge before the ground, their walls and shadows; the pieces of one face that its
  /// points left apart show no edge where the points stop.
  double ends_support = 0.0;
};

/// Looks, in one image seen through `P` (`gradient_x`, `gradient_y` its 3 x 3 Sobel gradients),
/// at the gap between two pieces of top-face points (table plane, mm) at `height_mm`; nullopt
/// when they do not lie apart along an axis of their joint rectangle by more than twice the
/// corner margin. Two boxes apart in a row show sides across the gap near 0 and ends near 1
/// (TwoBoxesThatTheImageShowsApartStayTwo).
std::optional<GapBetweenPieces> LookAcrossGap(const std::vector<Eigen::Vector2d>& piece_a,
                                              const std::vector<Eigen::Vector2d>& piece_b,
                                              double height_mm, const Eigen::Matrix<double, 3, 4>& P,
                                              const cv::Mat& gradient_x, const cv::Mat& gradient_y,
                                              const TopFaceEdgeOptions& options = {});

}  // namespace hnnstereo::vision
