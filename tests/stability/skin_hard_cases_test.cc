// Ball skins (seed 004, issue 6): the hard cases. Every report must stay truthful: a section
// reported total is checked here again, independently, on its closed polyline.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "sculpt/skin/skin.h"

namespace sculpt::skin {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

double SegDist(Vec2 p, Vec2 a, Vec2 b) {
  const Vec2 ab = b - a;
  const double l2 = ab.LengthSqr();
  const double t = l2 > 0 ? std::clamp((p - a).Dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (p - (a + ab * t)).Length();
}

// Crossing-number inside test and distance to the closed polygon, written apart from the
// library's own so that a bug there cannot hide here.
bool BallInside(const Polyline2& loop, const OrientedBall& b, double tol) {
  bool in = false;
  double d = INFINITY;
  for (size_t i = 0, j = loop.size() - 1; i < loop.size(); j = i++) {
    const Vec2 a = loop[i], c = loop[j];
    if ((a.y > b.c.y) != (c.y > b.c.y) && b.c.x < (c.x - a.x) * (b.c.y - a.y) / (c.y - a.y) + a.x) {
      in = !in;
    }
    d = std::min(d, SegDist(b.c, a, c));
  }
  return in && d >= b.r - tol * (1 + 1e-9) - 1e-9 * b.r;
}

void ExpectFiniteAndTruthful(const Skin& skin, size_t max_checked = 1000) {
  const size_t n = skin.sections().size();
  const size_t stride = std::max<size_t>(1, n / max_checked);
  for (size_t k = 0; k < n; k += stride) {
    const Section& s = skin.section(k);
    for (const Polyline2* p : {&s.plus, &s.minus}) {
      for (const Vec2& v : *p) ASSERT_TRUE(v.IsFinite()) << "section " << k;
    }
    const SectionReport& r = s.report;
    EXPECT_FALSE(std::isnan(r.clearance));
    EXPECT_FALSE(std::isnan(r.side[0].min_one_plus_kd));
    EXPECT_FALSE(std::isnan(r.side[1].min_one_plus_kd));
    if (r.total) {
      const Polyline2 loop = skin.SectionOutline(k);
      EXPECT_TRUE(BallInside(loop, skin.balls()[k], skin.chord_tolerance())) << k;
      EXPECT_TRUE(BallInside(loop, skin.balls()[k + 1], skin.chord_tolerance())) << k;
      EXPECT_TRUE(r.simple);
    } else {
      EXPECT_FALSE(r.notes.empty()) << "section " << k << " is not total and says nothing why";
    }
  }
}

std::vector<OrientedBall> Line(int n) {
  std::vector<OrientedBall> b;
  for (int i = 0; i < n; ++i) b.push_back({{3.0 * i, 0}, 1, 0});
  return b;
}

TEST(SkinHardCasesTest, RefusesNestedConcentricCoincidentNamingThePair) {
  auto b = Line(5);
  b[3] = {{b[2].c.x + 0.1, 0}, 0.3, 0};
  auto s = Skin::Build(b);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("balls[3] lies inside balls[2]"), std::string::npos)
      << s.status();
  b = Line(5);
  b[4] = {b[3].c, 2, 0};
  EXPECT_NE(Skin::Build(b).status().message().find("balls[3] and balls[4] are concentric"),
            std::string::npos);
  b = Line(5);
  b[1] = b[0];
  EXPECT_NE(Skin::Build(b).status().message().find("balls[0] and balls[1] are coincident"),
            std::string::npos);
}

TEST(SkinHardCasesTest, RefusesNanAndInfInEveryField) {
  const double bad[] = {std::nan(""), std::numeric_limits<double>::infinity(),
                        -std::numeric_limits<double>::infinity()};
  for (double v : bad) {
    for (int field = 0; field < 4; ++field) {
      auto b = Line(3);
      double* f[] = {&b[1].c.x, &b[1].c.y, &b[1].r, &b[1].theta};
      *f[field] = v;
      auto s = Skin::Build(b);
      ASSERT_FALSE(s.ok());
      EXPECT_NE(s.status().message().find("balls[1]."), std::string::npos) << s.status();
      auto ok = Skin::Build(Line(3));
      ASSERT_TRUE(ok.ok());
      EXPECT_FALSE(ok->SetBall(1, b[1]).ok());
      EXPECT_FALSE(ok->InsertBall(1, b[1]).ok());
    }
    SkinOptions o;
    o.chord_tolerance = v;
    EXPECT_FALSE(Skin::Build(Line(3), o).ok());
    o.chord_tolerance = 0;
    o.delta = v;
    EXPECT_FALSE(Skin::Build(Line(3), o).ok());
  }
}

// Digest §5.2 fixtures inside a chain: the diagnostics are the digest's.
TEST(SkinHardCasesTest, DigestFixturesInAChain) {
  // Collinear, r0 = 2, r1 = 1, L = 3 (< sqrt 12): non-total with the collinear reason.
  auto col = Skin::Build({{{-4, 0}, 1, 0}, {{0, 0}, 2, 0}, {{3, 0}, 1, 0}});
  ASSERT_TRUE(col.ok());
  EXPECT_FALSE(col->section(1).report.total);
  bool said = false;
  for (const auto& n : col->section(1).report.notes) said |= n.find("collinear centres") == 0;
  EXPECT_TRUE(said);
  ExpectFiniteAndTruthful(*col);

  // Tight bend: offset loops on + (min(1+kd) = -0.865), the hybrid does not.
  const std::vector<OrientedBall> tight{{{0, 0}, 1.5, 70 * kDeg}, {{3.5, 0}, 1.2, -70 * kDeg}};
  SkinOptions off;
  off.method = Method::kOffset;
  auto o = Skin::Build(tight, off);
  ASSERT_TRUE(o.ok());
  EXPECT_NEAR(o->section(0).report.side[0].min_one_plus_kd, -0.865, 5e-4);
  EXPECT_FALSE(o->section(0).report.total);
  EXPECT_GE(o->section(0).report.side[0].self_intersections, 1);
  auto h = Skin::Build(tight);
  ASSERT_TRUE(h.ok());
  EXPECT_TRUE(h->section(0).report.total);
  ExpectFiniteAndTruthful(*o);
  ExpectFiniteAndTruthful(*h);

  // S-shape: hidden ball at (2, 0), r = 1.
  auto s = Skin::Build({{{0, 0}, 1, 30 * kDeg}, {{4, 0}, 1, 30 * kDeg}});
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(s->section(0).report.hidden.size(), 1u);
  EXPECT_NEAR((s->section(0).report.hidden[0].c - Vec2{2, 0}).Length(), 0, 1e-12);
  EXPECT_NEAR(s->section(0).report.hidden[0].r, 1, 1e-12);
  ExpectFiniteAndTruthful(*s);
}

TEST(SkinHardCasesTest, RadiiDifferingByAMillion) {
  for (Method m : {Method::kHybrid, Method::kOffset, Method::kNaive}) {
    SkinOptions o;
    o.method = m;
    auto s = Skin::Build({{{0, 0}, 1, 0}, {{2.5, 0.1}, 1e-6, -5 * kDeg}, {{5, 0}, 1, 0}}, o);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_DOUBLE_EQ(s->chord_tolerance(), 1e-9);
    ExpectFiniteAndTruthful(*s);
  }
}

TEST(SkinHardCasesTest, CoordinatesNearAMillion) {
  std::vector<OrientedBall> near, far;
  for (int i = 0; i < 12; ++i) {
    near.push_back({{2.5 * i, std::sin(0.6 * i)}, 0.7 + 0.2 * std::cos(i), 15 * kDeg * std::cos(0.6 * i)});
    far.push_back(near.back());
    far.back().c = far.back().c + Vec2{1e6, -1e6};
  }
  auto a = Skin::Build(near), b = Skin::Build(far);
  ASSERT_TRUE(a.ok() && b.ok());
  ExpectFiniteAndTruthful(*b);
  for (size_t k = 0; k < a->sections().size(); ++k) {
    EXPECT_EQ(a->section(k).report.total, b->section(k).report.total) << k;
    EXPECT_NEAR(a->section(k).report.clearance, b->section(k).report.clearance, 1e-6) << k;
  }
}

TEST(SkinHardCasesTest, TouchingDirectionParallelToTheChain) {
  // t along the chain: straight mother, offset on both sides; total for equal radii.
  auto s = Skin::Build(Line(6));
  ASSERT_TRUE(s.ok());
  for (const Section& sec : s->sections()) EXPECT_TRUE(sec.report.total);
  ExpectFiniteAndTruthful(*s);
  // t across the chain puts the contact points on the chain: refused, naming the pair.
  auto b = Line(4);
  b[2].theta = 90 * kDeg;
  b[2].c.x = b[1].c.x + 1.5;
  auto bad = Skin::Build(b);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("balls[1] and balls[2] are not admissible"),
            std::string::npos)
      << bad.status();
  // t across the chain with room: built, and the report says what it is.
  b = Line(4);
  b[2].theta = 90 * kDeg;
  auto wide = Skin::Build(b);
  ASSERT_TRUE(wide.ok()) << wide.status();
  ExpectFiniteAndTruthful(*wide);
}

TEST(SkinHardCasesTest, HundredThousandBalls) {
  std::mt19937_64 rng(100000);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<OrientedBall> balls;
  double x = 0;
  for (int i = 0; i < 100000; ++i) {
    const double r = 0.5 + 0.25 * (u(rng) + 1);
    x += 2.4 + 0.5 * (u(rng) + 1);
    balls.push_back({{x, 0.6 * u(rng)}, r, 20 * kDeg * u(rng)});
  }
  auto s = Skin::Build(balls);
  ASSERT_TRUE(s.ok()) << s.status();
  const SkinSummary sum = s->Summary();
  EXPECT_EQ(sum.sections, 99999u);
  EXPECT_FALSE(std::isnan(sum.min_clearance));
  EXPECT_GT(sum.total, sum.sections / 2);
  ExpectFiniteAndTruthful(*s, 2000);
  // One move still rebuilds its two sections, and those after them up to the next codec
  // restart: a handful, not the rest of the chain.
  auto c = s->SetBall(50000, {{balls[50000].c.x, 0.2}, 0.6, 0});
  ASSERT_TRUE(c.ok());
  ASSERT_GE(c->changed.size(), 2u);
  EXPECT_EQ(c->changed[0], 49999u);
  EXPECT_LT(c->changed.size(), 2 + 16 * kCodecRestartPeriod);
  EXPECT_TRUE(s->CodecRestart(c->changed.back() + 1));
}

}  // namespace
}  // namespace sculpt::skin
