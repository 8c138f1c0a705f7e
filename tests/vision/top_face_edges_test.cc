// ExtendTopToImageEdges on a drawn image: a camera 700 mm above the table looks straight down
// at a bright 60 x 30 mm top face 40 mm tall on a dark table.
#include "vision/sensing/top_face_edges.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <opencv2/imgproc.hpp>

namespace hnnstereo::vision {
namespace {

struct DrawnTop {
  Eigen::Matrix<double, 3, 4> P;
  Eigen::Vector3d camera_centre{0.0, 0.0, 700.0};
  cv::Mat image, gradient_x, gradient_y;
  double height = 40.0;
};

// Pinhole camera at (0, 0, 700) looking down -z (x right, y down in the image flipped): f 1000 px.
// `wall_mm` > 0 also draws a mid-grey band that far beyond the face's +x end, as wide as the
// face: a wall seen beside the top, its base edge in line with nothing but the face's sides.
// `camera_x` moves the camera along x (a camera at x > length / 2 sees the +x wall), `camera_y`
// along y.
DrawnTop Draw(double length = 60.0, double width = 30.0, double wall_mm = 0.0, double camera_x = 0.0,
              double camera_y = 0.0) {
  DrawnTop d;
  d.camera_centre.x() = camera_x;
  d.camera_centre.y() = camera_y;
  Eigen::Matrix3d K;
  K << 1000, 0, 320, 0, 1000, 240, 0, 0, 1;
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  Eigen::Matrix<double, 3, 4> Rt;
  Rt.leftCols<3>() = R;
  Rt.col(3) = -R * d.camera_centre;
  d.P = K * Rt;
  d.image = cv::Mat(480, 640, CV_8U, cv::Scalar(40));
  std::vector<cv::Point> corners;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {-length / 2, -width / 2}, {length / 2, -width / 2}, {length / 2, width / 2}, {-length / 2, width / 2}}) {
    const Eigen::Vector3d p = d.P * Eigen::Vector4d(x, y, d.height, 1.0);
    corners.emplace_back(static_cast<int>(std::lround(p.x() / p.z())), static_cast<int>(std::lround(p.y() / p.z())));
  }
  if (wall_mm > 0.0) {
    std::vector<cv::Point> wall;
    for (const auto& [x, y] : std::vector<std::pair<double, double>>{{length / 2, -width / 2},
                                                                    {length / 2 + wall_mm, -width / 2},
                                                                    {length / 2 + wall_mm, width / 2},
                                                                    {length / 2, width / 2}}) {
      const Eigen::Vector3d p = d.P * Eigen::Vector4d(x, y, d.height, 1.0);
      wall.emplace_back(static_cast<int>(std::lround(p.x() / p.z())), static_cast<int>(std::lround(p.y() / p.z())));
    }
    cv::fillConvexPoly(d.image, wall, cv::Scalar(120));
  }
  cv::fillConvexPoly(d.image, corners, cv::Scalar(200));
  cv::GaussianBlur(d.image, d.image, cv::Size(5, 5), 0.8);
  cv::Sobel(d.image, d.gradient_x, CV_32F, 1, 0, 3);
  cv::Sobel(d.image, d.gradient_y, CV_32F, 0, 1, 3);
  return d;
}

// The mask of the world rectangle x0..x1, y0..y1 seen at the top's height.
cv::Mat MaskOf(const DrawnTop& d, double x0, double x1, double y0, double y1) {
  std::vector<cv::Point> corners;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}}) {
    const Eigen::Vector3d p = d.P * Eigen::Vector4d(x, y, d.height, 1.0);
    corners.emplace_back(static_cast<int>(std::lround(p.x() / p.z())), static_cast<int>(std::lround(p.y() / p.z())));
  }
  cv::Mat mask = cv::Mat::zeros(d.image.size(), CV_8U);
  cv::fillConvexPoly(mask, corners, cv::Scalar(255));
  return mask;
}

// Blurs the edited image a little and takes the gradients again.
void Regradient(DrawnTop* d) {
  cv::GaussianBlur(d->image, d->image, cv::Size(3, 3), 0.6);
  cv::Sobel(d->image, d->gradient_x, CV_32F, 1, 0, 3);
  cv::Sobel(d->image, d->gradient_y, CV_32F, 0, 1, 3);
}

// Multiplies the image by `gain` over the world rectangle x0..x1, y0..y1 seen at the top's
// height (a shadow).
void Shade(DrawnTop* d, double x0, double x1, double y0, double y1, double gain) {
  cv::Mat shaded;
  d->image.convertTo(shaded, CV_8U, gain);
  shaded.copyTo(d->image, MaskOf(*d, x0, x1, y0, y1));
  Regradient(d);
}

// Paints that rectangle with `grey` (the ground between two faces).
void Paint(DrawnTop* d, double x0, double x1, double y0, double y1, double grey) {
  d->image.setTo(cv::Scalar(grey), MaskOf(*d, x0, x1, y0, y1));
  Regradient(d);
}

// The pose of the face's points when its -x end was not matched: seen from x = -18 to +30.
ObjectPose CutPose(double height) {
  ObjectPose pose;
  pose.height_mm = height;
  pose.top_rectangle.centre = Eigen::Vector2d(6.0, 0.0);
  pose.top_rectangle.length = 48.0;
  pose.top_rectangle.width = 30.0;
  pose.centroid = Eigen::Vector3d(6.0, 0.0, height);
  return pose;
}

TopFaceEdgeReport Extend(const DrawnTop& d, ObjectPose* pose, const std::vector<Rectangle2D>& others = {},
                         const std::vector<Eigen::Vector3d>& points = {}) {
  return ExtendTopToImageEdges(pose, {d.P,
                                      d.gradient_x,
                                      d.gradient_y,
                                      others,
                                      points,
                                      std::vector<bool>(points.size(), false),
                                      {d.camera_centre},
                                      5.0,
                                      95.0,
                                      true});
}

TEST(TopFaceEdges, ACutEndMovesOutToTheFacesEdge) {
  const DrawnTop d = Draw();
  ObjectPose pose = CutPose(d.height);
  const TopFaceEdgeReport report = Extend(d, &pose);
  EXPECT_NEAR(pose.top_rectangle.length, 60.0, 1.0);
  EXPECT_NEAR(pose.top_rectangle.width, 30.0, 0.5);
  EXPECT_NEAR(pose.centroid.x(), 0.0, 0.5);
  EXPECT_NEAR(pose.centroid.y(), 0.0, 0.5);
  EXPECT_NEAR(report.total_mm(), 12.0, 1.0);
  EXPECT_NEAR(report.extension_mm[1], 12.0, 1.0);
  // The three sides the points found lay at image edges already.
  EXPECT_GE(report.end_support_before[0], 0.7);
  EXPECT_LT(report.end_support_before[1], 0.7);
}

TEST(TopFaceEdges, ASideAtAShadowsEdgeAcrossTheFaceMovesOutToTheFacesEnd) {
  // A neighbour's shadow covers the face's -x end (12 mm) and the ground beyond: the points
  // stopped at the shadow's edge, a strong image edge. The face's sides go on past it, the
  // face still brighter than the shadowed ground, to the face's end.
  DrawnTop d = Draw();
  Shade(&d, -45.0, -18.0, -25.0, 25.0, 0.35);
  ObjectPose pose = CutPose(d.height);
  const TopFaceEdgeReport report = Extend(d, &pose);
  EXPECT_EQ(report.line_on_face, 1);
  EXPECT_NEAR(pose.top_rectangle.length, 60.0, 1.0);
  EXPECT_NEAR(pose.centroid.x(), 0.0, 0.5);
  // Without looking past such lines the side stays at the shadow's edge.
  ObjectPose kept = CutPose(d.height);
  TopFaceEdgeOptions options;
  options.look_past_lines_on_face = false;
  ExtendTopToImageEdges(
      &kept, {d.P, d.gradient_x, d.gradient_y, {}, {}, {}, {d.camera_centre}, 5.0, 95.0, true},
      options);
  EXPECT_DOUBLE_EQ(kept.top_rectangle.length, 48.0);
}

TEST(TopFaceEdges, InAShadowASidesEdgeMayBeItsWallsBase) {
  // A camera at y = 60 mm sees the face's +y wall, 40 / 700 x 45 = 2.6 mm wide in the top's
  // plane: darker than the face in the light. A neighbour's shadow covers the face's -x end
  // (12 mm) and the ground: there face and wall are equally dark (ambient light on both), and
  // the +y side's only edge is the wall's base (default 259055, gap0 239086).
  DrawnTop d = Draw(60.0, 30.0, 0.0, 0.0, 60.0);
  Paint(&d, -18.0, 30.0, 15.0, 17.6, 120.0);
  Shade(&d, -45.0, -18.0, -25.0, 25.0, 0.35);
  Paint(&d, -30.0, -18.0, 15.0, 17.6, 70.0);
  ObjectPose pose = CutPose(d.height);
  const TopFaceEdgeReport report = Extend(d, &pose);
  EXPECT_EQ(report.line_on_face, 1);
  EXPECT_NEAR(pose.top_rectangle.length, 60.0, 1.0);
  EXPECT_NEAR(pose.centroid.x(), 0.0, 0.5);
  EXPECT_EQ(report.unplaced_sides, 0);
  // A face whose end the search does not reach (here: not within 5 mm) is not placed there.
  TopFaceEdgeOptions short_reach;
  short_reach.max_extension_mm = 5.0;
  ObjectPose kept = CutPose(d.height);
  const TopFaceEdgeReport unplaced = ExtendTopToImageEdges(
      &kept, {d.P, d.gradient_x, d.gradient_y, {}, {}, {}, {d.camera_centre}, 5.0, 95.0, true},
      short_reach);
  EXPECT_DOUBLE_EQ(kept.top_rectangle.length, 48.0);
  EXPECT_EQ(unplaced.line_on_face, 1);
  EXPECT_EQ(unplaced.unplaced_sides, 1);
}

TEST(TopFaceEdges, TheFacesOwnShadowBeyondItsEndIsNoPartOfIt) {
  // The whole face found; beyond its -x end its own shadow on the ground, 8 mm long and as wide
  // as the face: the shadow's sides run on in line with the face's, but darker than the ground
  // beside them where the face is brighter, so the end stays (gap0 seed 77067: a 69 x 45 mm
  // top stretched 7.5 mm over its shadow, 4.1 mm off).
  DrawnTop d = Draw();
  Shade(&d, -38.0, -30.0, -15.0, 15.0, 0.4);
  ObjectPose pose = CutPose(d.height);
  pose.top_rectangle.centre.x() = 0.0;
  pose.top_rectangle.length = 60.0;
  pose.centroid.x() = 0.0;
  const TopFaceEdgeReport report = Extend(d, &pose);
  EXPECT_EQ(report.line_on_face, 0);
  EXPECT_DOUBLE_EQ(pose.top_rectangle.length, 60.0);
}

TEST(TopFaceEdges, AWholeTopStaysAsItIs) {
  const DrawnTop d = Draw();
  ObjectPose pose = CutPose(d.height);
  pose.top_rectangle.centre.x() = 0.0;
  pose.top_rectangle.length = 60.0;
  pose.centroid.x() = 0.0;
  EXPECT_EQ(Extend(d, &pose).total_mm(), 0.0);
  EXPECT_DOUBLE_EQ(pose.top_rectangle.length, 60.0);
}

TEST(TopFaceEdges, ATopTurnsToTheFacesEdges) {
  // The points' rectangle turned 4 degrees off the face (outline points scatter, and stop
  // short where the edges run along the epipolar lines): turned back to the drawn face.
  const DrawnTop d = Draw();
  for (const double off : {4.0, -2.5, 7.0}) {
    SCOPED_TRACE(off);
    ObjectPose pose = CutPose(d.height);
    pose.top_rectangle.centre.x() = 0.0;
    pose.top_rectangle.length = 60.0;
    pose.top_rectangle.yaw_deg = off;
    pose.yaw_deg = off;
    const double turn = TurnTopToImageEdges(&pose, d.P, d.gradient_x, d.gradient_y, true);
    EXPECT_NEAR(turn, -off, 0.5);
    EXPECT_NEAR(pose.top_rectangle.yaw_deg, 0.0, 0.5);
    EXPECT_DOUBLE_EQ(pose.yaw_deg, pose.top_rectangle.yaw_deg);
  }
  // On the face already: no turn. Without the turn (0 degrees allowed): none either.
  ObjectPose on = CutPose(d.height);
  on.top_rectangle.centre.x() = 0.0;
  on.top_rectangle.length = 60.0;
  EXPECT_EQ(TurnTopToImageEdges(&on, d.P, d.gradient_x, d.gradient_y, true), 0.0);
  ObjectPose off = on;
  off.top_rectangle.yaw_deg = 4.0;
  TopFaceEdgeOptions no_turn;
  no_turn.max_yaw_turn_deg = 0.0;
  EXPECT_EQ(TurnTopToImageEdges(&off, d.P, d.gradient_x, d.gradient_y, true, no_turn), 0.0);
  EXPECT_EQ(off.top_rectangle.yaw_deg, 4.0);
  // A round top is left alone.
  ObjectPose round = off;
  round.round = true;
  EXPECT_EQ(TurnTopToImageEdges(&round, d.P, d.gradient_x, d.gradient_y, true), 0.0);
}

TEST(TopFaceEdges, TheSideStopsAtTheFacesEdge) {
  // A face of 48 x 30 drawn: the side moves to its edge, not on to anything beyond.
  DrawnTop d = Draw(48.0, 30.0);
  ObjectPose pose = CutPose(d.height);
  pose.top_rectangle.centre.x() = 0.0;
  pose.centroid.x() = 0.0;
  // Cut the rectangle short by 4 mm at +x: the edge is found again 4 mm out, not further.
  pose.top_rectangle.length = 44.0;
  pose.top_rectangle.centre.x() = -2.0;
  Extend(d, &pose);
  EXPECT_NEAR(pose.top_rectangle.length, 48.0, 1.0);
}

// A 60 x 30 mm face's outline points (every 2 mm along its long sides) and two mismatches at
// the top height 3.5 and 4 mm past its +x end; the pose's rectangle runs to them (64 mm long).
struct StretchedPose {
  ObjectPose pose;
  std::vector<Eigen::Vector3d> points;
};
StretchedPose Stretched(double height) {
  StretchedPose s;
  s.pose = CutPose(height);
  s.pose.top_rectangle.centre.x() = 2.0;
  s.pose.top_rectangle.length = 64.0;
  s.pose.centroid.x() = 2.0;
  for (double x = -30.0; x <= 30.0; x += 2.0) {
    s.points.emplace_back(x, -15.0, height);
    s.points.emplace_back(x, 15.0, height);
  }
  s.points.emplace_back(34.0, 0.0, height);
  s.points.emplace_back(33.5, 5.0, height);
  for (int i = 0; i < static_cast<int>(s.points.size()); ++i) s.pose.point_indices.push_back(i);
  return s;
}

TEST(TopFaceEdges, ASideBeyondTheFacesEdgeMovesInToIt) {
  // No image edge under the +x side, the face's edge 4 mm inside it, nothing of the face past
  // that edge in the image, two of the top's points past it.
  const DrawnTop d = Draw();
  StretchedPose s = Stretched(d.height);
  const TopFaceEdgeReport report = Extend(d, &s.pose, {}, s.points);
  EXPECT_EQ(report.edge_inside, 1);
  EXPECT_NEAR(report.extension_mm[0], -4.0, 1.0);
  EXPECT_NEAR(s.pose.top_rectangle.length, 60.0, 1.0);
  EXPECT_NEAR(s.pose.centroid.x(), 0.0, 0.5);
  // Many of the top's points past the inner edge: the side stays (a line across a face is no
  // reason to cut the face's points away).
  StretchedPose many = Stretched(d.height);
  for (double y = -15.0; y <= 15.0; y += 1.0) {
    many.pose.point_indices.push_back(static_cast<int>(many.points.size()));
    many.points.emplace_back(33.0, y, d.height);
  }
  Extend(d, &many.pose, {}, many.points);
  EXPECT_DOUBLE_EQ(many.pose.top_rectangle.length, 64.0);
}

TEST(TopFaceEdges, ASideBeyondTheFacesEdgeIsNotMovedOut) {
  // As above, but a wall seen beside the face's +x end, in line with its sides, 11 mm long:
  // moving the side out would find the wall's base. The face's sides go on past its edge in
  // the image (along the wall), so it does not move in either. The camera stands where it sees
  // that wall 11 mm wide in the plane of the top (40 / 700 x (x - 30) = 11): a line across the
  // face is looked past only beyond such a wall's base.
  const DrawnTop d = Draw(60.0, 30.0, 11.0, 30.0 + 11.0 * 700.0 / 40.0);
  StretchedPose s = Stretched(d.height);
  StretchedPose outward_only = s;
  const TopFaceEdgeReport report = Extend(d, &s.pose, {}, s.points);
  EXPECT_EQ(report.edge_inside, 1);
  EXPECT_EQ(report.moved_mm(), 0.0);
  EXPECT_DOUBLE_EQ(s.pose.top_rectangle.length, 64.0);
  TopFaceEdgeOptions options;
  options.max_inward_mm = 0.0;
  ExtendTopToImageEdges(&outward_only.pose,
                        {d.P,
                         d.gradient_x,
                         d.gradient_y,
                         {},
                         outward_only.points,
                         std::vector<bool>(outward_only.points.size(), false),
                         {d.camera_centre},
                         5.0,
                         95.0,
                         true},
                        options);
  EXPECT_GT(outward_only.pose.top_rectangle.length, 68.0) << "the failure the inward search exists for";
}

TEST(TopFaceEdges, AShadowsFarEdgeIsNoEndOfTheFace) {
  // The face's shadow on the table beyond its +x end, 12 mm long and wider than the face,
  // darker than the table; a line of points matched along the shadow's far edge at the top's
  // height stretched the top to it (gap0 249002). That edge is brighter outward, where the face
  // is darker outward along its sides: it is no end of the face, which moves in to its edge.
  DrawnTop d = Draw();
  Paint(&d, 30.0, 42.0, -25.0, 25.0, 10.0);
  StretchedPose s;
  s.pose = CutPose(d.height);
  s.pose.top_rectangle.centre.x() = 6.0;
  s.pose.top_rectangle.length = 72.0;
  s.pose.centroid.x() = 6.0;
  for (double x = -30.0; x <= 30.0; x += 2.0) {
    s.points.emplace_back(x, -15.0, d.height);
    s.points.emplace_back(x, 15.0, d.height);
  }
  for (double y = -15.0; y <= 15.0; y += 3.0) s.points.emplace_back(42.0, y, d.height);
  for (int i = 0; i < static_cast<int>(s.points.size()); ++i) s.pose.point_indices.push_back(i);
  StretchedPose without = s;
  const TopFaceEdgeReport report = Extend(d, &s.pose, {}, s.points);
  EXPECT_EQ(report.end_edge_reversed, 1);
  EXPECT_NEAR(report.extension_mm[0], -12.0, 1.0);
  EXPECT_NEAR(s.pose.top_rectangle.length, 60.0, 1.0);
  EXPECT_NEAR(s.pose.centroid.x(), 0.0, 0.5);
  TopFaceEdgeOptions options;
  options.end_edge_polarity = false;
  ExtendTopToImageEdges(&without.pose,
                        {d.P,
                         d.gradient_x,
                         d.gradient_y,
                         {},
                         without.points,
                         std::vector<bool>(without.points.size(), false),
                         {d.camera_centre},
                         5.0,
                         95.0,
                         true},
                        options);
  EXPECT_DOUBLE_EQ(without.pose.top_rectangle.length, 72.0) << "the failure the test exists for";
  // The face's own end is an edge of the face's polarity: a whole top keeps its four sides.
  ObjectPose whole = CutPose(d.height);
  whole.top_rectangle.centre.x() = 0.0;
  whole.top_rectangle.length = 60.0;
  const TopFaceEdgeReport kept = Extend(d, &whole);
  EXPECT_EQ(kept.end_edge_reversed, 0);
  EXPECT_EQ(kept.moved_mm(), 0.0);
}

TEST(TopFaceEdges, TheTableSeenThroughTheStripRefusesIt) {
  // Table points (z = 0) seen through the strip the extension would add: the face is not there.
  const DrawnTop d = Draw();
  ObjectPose pose = CutPose(d.height);
  std::vector<Eigen::Vector3d> table;
  for (int i = 0; i < 5; ++i) {
    // Seen from (0, 0, 700) through (-25, 2i, 40): on the table at x = -25 * 700 / 660.
    table.emplace_back(-25.0 * 700.0 / 660.0, 2.0 * i * 700.0 / 660.0, 0.0);
  }
  const TopFaceEdgeReport report = Extend(d, &pose, {}, table);
  EXPECT_EQ(report.total_mm(), 0.0);
  EXPECT_EQ(report.refused_by_points, 1);
  EXPECT_DOUBLE_EQ(pose.top_rectangle.length, 48.0);
}

TEST(TopFaceEdges, NeverIntoAnotherPart) {
  const DrawnTop d = Draw();
  ObjectPose pose = CutPose(d.height);
  Rectangle2D other;  // a part whose rectangle begins 5 mm beyond the seen end
  other.centre = Eigen::Vector2d(-43.0, 0.0);
  other.length = 40.0;
  other.width = 30.0;
  Extend(d, &pose, {other});
  EXPECT_DOUBLE_EQ(pose.top_rectangle.length, 48.0);
}

TEST(TopFaceEdges, RoundTopsAreLeftAlone) {
  const DrawnTop d = Draw();
  ObjectPose pose = CutPose(d.height);
  pose.round = true;
  EXPECT_EQ(Extend(d, &pose).total_mm(), 0.0);
}

// Top-face points on the outline of the world rectangle x0..x1 by y0..y1 (1 mm apart).
std::vector<Eigen::Vector2d> Outline(double x0, double x1, double y0, double y1) {
  std::vector<Eigen::Vector2d> points;
  for (double x = x0; x <= x1; x += 1.0) {
    points.emplace_back(x, y0);
    points.emplace_back(x, y1);
  }
  for (double y = y0 + 1.0; y < y1; y += 1.0) {
    points.emplace_back(x0, y);
    points.emplace_back(x1, y);
  }
  return points;
}

TEST(TopFaceEdges, OneFaceSeenAsItsTwoEndsKeepsItsSidesAcrossTheGap) {
  // The 60 x 30 face's points only at its two ends (strips 4 mm deep): its sides run on, in the
  // image, over the 52 mm between them - also under a neighbour's shadow across its middle -
  // and where the points stop, the face goes on: no edge.
  DrawnTop d = Draw();
  const std::vector<Eigen::Vector2d> a = Outline(-30.0, -26.0, -15.0, 15.0);
  const std::vector<Eigen::Vector2d> b = Outline(26.0, 30.0, -15.0, 15.0);
  std::optional<GapBetweenPieces> gap = LookAcrossGap(a, b, d.height, d.P, d.gradient_x, d.gradient_y);
  ASSERT_TRUE(gap.has_value());
  EXPECT_GE(gap->sides_support, 0.9);
  EXPECT_LE(gap->ends_support, 0.2);
  Shade(&d, -10.0, 10.0, -25.0, 25.0, 0.35);
  gap = LookAcrossGap(a, b, d.height, d.P, d.gradient_x, d.gradient_y);
  ASSERT_TRUE(gap.has_value());
  EXPECT_GE(gap->sides_support, 0.6);
}

TEST(TopFaceEdges, TwoFacesInARowShowTheGroundAcrossTheGap) {
  // Two 25 x 30 faces at one height, 10 mm of ground between them: whole outlines each, as
  // two boxes in a row are seen (default seed 155183). No side runs across the gap, and each
  // face ends at an edge, brighter than the gap.
  DrawnTop d = Draw();
  Paint(&d, -5.0, 5.0, -20.0, 20.0, 40.0);
  const std::vector<Eigen::Vector2d> a = Outline(-30.0, -5.0, -15.0, 15.0);
  const std::vector<Eigen::Vector2d> b = Outline(5.0, 30.0, -15.0, 15.0);
  const std::optional<GapBetweenPieces> gap =
      LookAcrossGap(a, b, d.height, d.P, d.gradient_x, d.gradient_y);
  ASSERT_TRUE(gap.has_value());
  EXPECT_LT(gap->sides_support, 0.2);
  EXPECT_GE(gap->ends_support, 0.9);
  // Pieces that overlap along both axes have no gap to look at.
  EXPECT_FALSE(LookAcrossGap(a, Outline(-10.0, 10.0, -5.0, 5.0), d.height, d.P, d.gradient_x,
                             d.gradient_y)
                   .has_value());
}

TEST(TopFaceEdges, BadOptionsAreRefused) {
  TopFaceEdgeOptions options;
  EXPECT_TRUE(options.Check().empty());
  options.step_mm = 0.0;
  EXPECT_NE(options.Check().find("step_mm"), std::string::npos);
  options = {};
  options.min_end_support = 1.5;
  EXPECT_NE(options.Check().find("min_end_support"), std::string::npos);
  options = {};
  options.max_yaw_turn_deg = -1.0;
  EXPECT_NE(options.Check().find("max_yaw_turn_deg"), std::string::npos);
  options = {};
  options.yaw_step_deg = 0.0;
  EXPECT_NE(options.Check().find("yaw_step_deg"), std::string::npos);
}

}  // namespace
}  // namespace hnnstereo::vision
