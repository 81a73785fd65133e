/// @brief Sweeps of a closed outline into a sculpture (extrude, revolve; add, subtract) and slice
/// contours by marching squares.
#include "sculpt/levelset/sweep.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sculpt/levelset/slice.h"

namespace sculpt::levelset {
namespace {

constexpr double kPi = 3.14159265358979323846;

Sculpture Ball() {
  SculptureOptions o;
  o.voxel_size = 0.25;
  auto s = Sculpture::MakeSphere(o, {0, 0, 0}, 8);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move(s).value();
}

std::vector<PlanePoint> Square(double x0, double y0, double side) {
  return {{x0, y0}, {x0 + side, y0}, {x0 + side, y0 + side}, {x0, y0 + side}};
}

TEST(SweepTest, PolygonSignedDistanceIsNegativeInside) {
  const auto sq = Square(0, 0, 2);
  EXPECT_NEAR(PolygonSignedDistance(sq, {1, 1}), -1, 1e-12);
  EXPECT_NEAR(PolygonSignedDistance(sq, {3, 1}), 1, 1e-12);
  EXPECT_NEAR(PolygonSignedDistance(sq, {3, 3}), std::sqrt(2.0), 1e-12);
}

TEST(SweepTest, RevolveAddsPappusVolume) {
  Sculpture s = Ball();
  const double before = s.volume();
  SweepRequest r;
  r.mode = SweepRequest::Mode::kRevolve;
  r.plane.origin = {0, 0, 0};
  // A 4 x 4 square 12..16 from the axis (x = 0 line of the plane, world y): a ring around the
  // ball, disjoint from it. Pappus: V = 2 pi R_centroid A = 2 pi 14 16. The smoothed volume
  // (eps = 1.5 voxels) adds a little at the ring's sharp edges: 3% allows for it.
  r.outline = Square(12, -2, 4);
  r.axis_point = {0, 0};
  r.axis_dir = {0, 1};
  auto res = ApplySweep(s, r);
  ASSERT_TRUE(res.ok()) << res.status();
  const double expected = 2 * kPi * 14 * 16;
  EXPECT_NEAR(s.volume() - before, expected, 0.03 * expected);
  EXPECT_NEAR(s.ComputeVolume(), s.volume(), 0.01 * s.volume());
  EXPECT_NEAR(s.reference_volume(), s.volume(), 1e-9 * s.volume());
  EXPECT_TRUE(s.CheckLevelSet().ok());
}

TEST(SweepTest, ExtrudeSubtractCutsAPrism) {
  Sculpture s = Ball();
  const double before = s.volume();
  SweepRequest r;
  r.add = false;
  r.plane.origin = {0, 0, -3};
  r.outline = Square(-3, -3, 6);
  r.depth = 6;
  auto res = ApplySweep(s, r);
  ASSERT_TRUE(res.ok()) << res.status();
  EXPECT_NEAR(before - s.volume(), 216.0, 0.03 * 216);
  EXPECT_GT(s.SampleWorld({0, 0, 0}), 0);  // the centre is cut out
  EXPECT_LT(s.SampleWorld({0, 0, 6}), 0);  // above the prism is still inside the ball
}

TEST(SweepTest, RejectsBadPlaneAndOutline) {
  Sculpture s = Ball();
  SweepRequest r;
  r.outline = Square(0, 0, 2);
  r.plane.u = {1, 1, 0};
  auto a = ApplySweep(s, r);
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("sweep.plane.u="), std::string::npos) << a.status();
  r.plane.u = {1, 0, 0};
  r.outline.resize(2);
  EXPECT_NE(ApplySweep(s, r).status().message().find("sweep.outline.size=2"), std::string::npos);
  r.outline = Square(0, 0, 2);
  r.outline[1].x = std::nan("");
  EXPECT_NE(ApplySweep(s, r).status().message().find("is not finite"), std::string::npos);
  r.outline = Square(0, 0, 2);
  r.depth = 1e9;
  EXPECT_NE(ApplySweep(s, r).status().message().find("sweep.depth="), std::string::npos);
}

TEST(SliceTest, EquatorOfASphereIsOneClosedCircle) {
  Sculpture s = Ball();
  SliceRequest q;
  q.half_extent = 10;
  q.step = 0.25;
  auto lines = SliceContours(s, q);
  ASSERT_TRUE(lines.ok()) << lines.status();
  ASSERT_EQ(lines->size(), 1u);
  const auto& l = lines->front();
  EXPECT_GT(l.size(), 100u);
  EXPECT_DOUBLE_EQ(l.front().x, l.back().x);
  EXPECT_DOUBLE_EQ(l.front().y, l.back().y);
  for (const PlanePoint& p : l) EXPECT_NEAR(std::hypot(p.x, p.y), 8.0, 0.05);
}

TEST(SliceTest, MarchingSquaresSplitsASaddleByTheCentre) {
  // 2 x 2 samples, diagonal corners inside: centre average decides.
  const std::vector<float> inside_centre{-1, 0.5f, 0.5f, -1};
  EXPECT_EQ(MarchingSquares(inside_centre, 2, 2, {0, 0}, 1).size(), 2u);
  const std::vector<float> open{-1, 1, -1, 1};  // a vertical line through the square
  const auto lines = MarchingSquares(open, 2, 2, {0, 0}, 1);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_DOUBLE_EQ(lines[0].front().x, 0.5);
  EXPECT_DOUBLE_EQ(lines[0].back().x, 0.5);
}

TEST(SliceTest, RejectsTooManySamples) {
  Sculpture s = Ball();
  SliceRequest q;
  q.half_extent = 1000;
  q.step = 0.1;
  auto lines = SliceContours(s, q);
  ASSERT_FALSE(lines.ok());
  EXPECT_NE(lines.status().message().find("slice.half_extent=1000 outside"), std::string::npos);
}

}  // namespace
}  // namespace sculpt::levelset
