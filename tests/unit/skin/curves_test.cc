#include "sculpt/skin/curves.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace sculpt::skin {
namespace {

constexpr double kDeg = std::numbers::pi / 180;
constexpr double kPi = std::numbers::pi;

// Barycentric coordinates of p in the triangle (a, b, c).
std::array<double, 3> Bary(Vec2 p, Vec2 a, Vec2 b, Vec2 c) {
  const double area = (b - a).Cross(c - a);
  return {(b - p).Cross(c - p) / area, (c - p).Cross(a - p) / area, (a - p).Cross(b - p) / area};
}

// Digest §7 claims 3-4.
TEST(HermiteMotherTest, InterpolatesCentresAndDirections) {
  const OrientedBall b0{{1, 2}, 1, 20 * kDeg}, b1{{5, 3}, 0.5, -35 * kDeg};
  const HermiteMother m = HermiteMother::FromBalls(b0, b1);
  EXPECT_NEAR((m.P(0) - b0.c).Length(), 0, 1e-14);
  EXPECT_NEAR((m.P(1) - b1.c).Length(), 0, 1e-14);
  EXPECT_NEAR((m.D1(0) / m.length - b0.t()).Length(), 0, 1e-14);
  EXPECT_NEAR((m.D1(1) / m.length - b1.t()).Length(), 0, 1e-14);
  const DistanceFn d{b0.r, b1.r};
  EXPECT_EQ(d.D(0), 1.0);
  EXPECT_EQ(d.D(1), 0.5);
  EXPECT_EQ(d.D1(0), 0.0);
  EXPECT_EQ(d.D1(1), 0.0);
  for (int i = 0; i <= 1000; ++i) {
    const double v = d.D(i / 1000.0);
    EXPECT_GE(v, 0.5 - 1e-15);
    EXPECT_LE(v, 1.0 + 1e-15);
  }
}

// Digest §5.2 example 4: the S-shape's inflection is at tau = 0.5, on (2, 0).
TEST(HermiteMotherTest, SShapeInflectionAtMidpoint) {
  const HermiteMother m = HermiteMother::FromBalls({{0, 0}, 1, 30 * kDeg}, {{4, 0}, 1, 30 * kDeg});
  std::array<double, 2> roots{};
  ASSERT_EQ(m.Inflections(roots), 1);
  EXPECT_NEAR(roots[0], 0.5, 1e-12);
  EXPECT_NEAR(m.Curvature(roots[0]), 0, 1e-12);
  EXPECT_LT(m.Curvature(0.25) * m.Curvature(0.75), 0);
}

// Digest §7 claims 5-6: offset end points and tangency, and the derivative identity.
TEST(OffsetTest, EndPointsTangencyAndDerivative) {
  const OrientedBall b0{{0, 0}, 1.0, 40 * kDeg}, b1{{4, 0}, 0.6, -40 * kDeg};
  const HermiteMother m = HermiteMother::FromBalls(b0, b1);
  const DistanceFn d{b0.r, b1.r};
  for (int side : {1, -1}) {
    const Offset off{&m, &d, side};
    EXPECT_NEAR((off.P(0) - b0.Contact(side)).Length(), 0, 1e-14);
    EXPECT_NEAR((off.P(1) - b1.Contact(side)).Length(), 0, 1e-14);
    EXPECT_NEAR(off.D1(0).Normalized().Cross(b0.t()), 0, 1e-14);
    EXPECT_NEAR(off.D1(1).Normalized().Cross(b1.t()), 0, 1e-14);
    for (double tau : {0.1, 0.37, 0.8}) {
      const double h = 1e-6;
      const Vec2 fd = (off.P(tau + h) - off.P(tau - h)) / (2 * h);
      EXPECT_NEAR((fd - off.D1(tau)).Length() / off.D1(tau).Length(), 0, 1e-6);
    }
  }
}

TEST(ASplineTest, DefaultDeltaMatchesDigestFixture) {
  // Digest §5.2 example 2: the + side of the moderate right bend has delta = 1.532.
  const OrientedBall b0{{0, 0}, 1.0, 40 * kDeg}, b1{{4, 0}, 0.6, -40 * kDeg};
  std::string why;
  auto s = ASpline::Make(b0.Contact(1), b0.t(), 0.3, b1.Contact(1), b1.t(), 0.3, 0, &why);
  ASSERT_TRUE(s) << why;
  EXPECT_NEAR(s->delta, 1.532, 5e-4);
}

// Digest §7 claims 11, 13, 15: the arc is on f = 0, interpolates the nodes, stays in the
// control triangle; the shoulder point is on the curve for every delta.
TEST(ASplineTest, SamplesLieOnTheCorrectedCubic) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> k(0, 3), dl(0.05, 20);
  for (int trial = 0; trial < 200; ++trial) {
    std::string why;
    auto s = ASpline::Make({0, 0}, {1, 0.2}, k(rng), {3, 0.5}, {0.6, -1}, k(rng), dl(rng), &why);
    ASSERT_TRUE(s) << why;
    EXPECT_NEAR(s->F(1, 0, 0), 0, 1e-15);
    EXPECT_NEAR(s->F(0, 0, 1), 0, 1e-15);
    const double dd = s->delta;
    EXPECT_NEAR(s->F(1 / (2 + dd), dd / (2 + dd), 1 / (2 + dd)), 0,
                1e-12 * std::pow(dd, 4) + 1e-12);
    EXPECT_NEAR((s->AtPhi(0) - s->p2).Length(), 0, 1e-12);
    EXPECT_NEAR((s->AtPhi(kPi / 2) - s->p0).Length(), 0, 1e-9);
    for (int i = 1; i < 20; ++i) {
      const Vec2 p = s->AtPhi(kPi / 2 * i / 20);
      const auto b = Bary(p, s->p0, s->p1, s->p2);
      EXPECT_GE(b[0], -1e-12);
      EXPECT_GE(b[1], -1e-12);
      EXPECT_GE(b[2], -1e-12);
      const double scale = std::max({1.0, std::pow(dd, 4) * (1 + s->k0 + s->k2)});
      EXPECT_NEAR(s->F(b[0], b[1], b[2]), 0, 1e-10 * scale);
    }
  }
}

// Digest §7 claim 14: circle data with delta = 2 cos(theta) reproduce the arc.
TEST(ASplineTest, ReproducesCircleArc) {
  const double R = 2.5;
  for (double theta : {kPi / 6, kPi / 4, kPi / 3, 0.3, 1.2}) {
    // Arc of the circle centred at the origin from angle -theta to +theta (through (R, 0)),
    // travelling counter-clockwise: the chord-tangent angle is theta.
    const Vec2 p0{R * std::cos(-theta), R * std::sin(-theta)};
    const Vec2 p2{R * std::cos(theta), R * std::sin(theta)};
    const Vec2 t0{std::sin(theta), std::cos(theta)}, t2{-std::sin(theta), std::cos(theta)};
    std::string why;
    auto s = ASpline::Make(p0, t0, 1 / R, p2, t2, 1 / R, 2 * std::cos(theta), &why);
    ASSERT_TRUE(s) << why;
    for (int i = 0; i <= 50; ++i) {
      EXPECT_NEAR(s->AtPhi(kPi / 2 * i / 50).Length(), R, 1e-12 * R) << theta;
    }
    // The default delta is the same value: the mean chord-tangent angle is theta.
    auto d = ASpline::Make(p0, t0, 1 / R, p2, t2, 1 / R, 0, &why);
    EXPECT_NEAR(d->delta, 2 * std::cos(theta), 1e-12);
  }
}

TEST(ASplineTest, RefusesParallelTangents) {
  std::string why;
  EXPECT_FALSE(ASpline::Make({0, 0}, {1, 0}, 1, {3, 0}, {1, 0}, 1, 0, &why));
  EXPECT_NE(why.find("parallel"), std::string::npos);
  EXPECT_FALSE(ASpline::Make({0, 0}, {1, 1}, 1, {3, 0}, {-1, 1}, 1, 0, &why));
  EXPECT_NE(why.find("interior case"), std::string::npos);
}

}  // namespace
}  // namespace sculpt::skin
