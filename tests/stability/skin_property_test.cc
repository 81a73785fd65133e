// Ball skins (seed 004, issue 6): seeded property tests over random admissible chains — exact
// tangency at the touching points, G1 at the joints, contact points on the circles, and total
// sections containing their balls (digest §7 claims 1, 5, 17, 22).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "sculpt/skin/skin.h"

namespace sculpt::skin {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

std::vector<OrientedBall> RandomChain(uint64_t seed, int n) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (;;) {
    std::vector<OrientedBall> b;
    Vec2 c{0, 0};
    double heading = 0;
    for (int i = 0; i < n; ++i) {
      const double r = 0.3 + 0.9 * u(rng);
      if (i > 0) {
        heading = std::clamp(heading + (u(rng) - 0.5) * 50 * kDeg, -50 * kDeg, 50 * kDeg);
        const double step = (b.back().r + r) * (1.1 + u(rng));
        c = c + Vec2{std::cos(heading), std::sin(heading)} * step;
      }
      b.push_back({c, r, heading + (u(rng) - 0.5) * 40 * kDeg});
    }
    if (ValidateChain(b).ok()) return b;
  }
}

class SkinPropertyTest : public ::testing::TestWithParam<Method> {};

TEST_P(SkinPropertyTest, TangencyG1ContactsAndContainment) {
  int total = 0, sections = 0;
  for (uint64_t seed = 1; seed <= 40; ++seed) {
    const auto balls = RandomChain(seed, 12);
    SkinOptions o;
    o.method = GetParam();
    auto skin = Skin::Build(balls, o);
    ASSERT_TRUE(skin.ok()) << skin.status();
    const double tol = skin->chord_tolerance();
    for (size_t k = 0; k < skin->sections().size(); ++k) {
      const Section& s = skin->section(k);
      ++sections;
      total += s.report.total;
      for (int si = 0; si < 2; ++si) {
        const int side = si == 0 ? 1 : -1;
        const auto& pieces = s.pieces[si];
        ASSERT_FALSE(pieces.empty());
        const OrientedBall& b0 = balls[k];
        const OrientedBall& b1 = balls[k + 1];
        // Contact points: on the circles, and the pieces start/end there exactly.
        EXPECT_EQ(pieces.front().start, b0.Contact(side));
        EXPECT_EQ(pieces.back().end, b1.Contact(side));
        EXPECT_NEAR((b0.Contact(side) - b0.c).Length(), b0.r, 1e-12 * (1 + b0.c.Length()));
        const Polyline2& pl = si == 0 ? s.plus : s.minus;
        EXPECT_EQ(pl.front(), b0.Contact(side));
        EXPECT_EQ(pl.back(), b1.Contact(side));
        // Exact tangency: the analytic tangents at the balls are parallel to t_i
        // (reversed only where the report says the offset runs backwards).
        const double c0 = pieces.front().start_tangent.Dot(b0.t());
        const double c1 = pieces.back().end_tangent.Dot(b1.t());
        EXPECT_LT(std::abs(pieces.front().start_tangent.Cross(b0.t())), 1e-12);
        EXPECT_LT(std::abs(pieces.back().end_tangent.Cross(b1.t())), 1e-12);
        if (!s.report.end_reversed) {
          EXPECT_LT(1 - c0, 1e-12) << "seed " << seed << " section " << k;
          EXPECT_LT(1 - c1, 1e-12) << "seed " << seed << " section " << k;
        }
        // G1 inside the section (hidden-ball joints) on analytic tangents.
        for (size_t p = 1; p < pieces.size(); ++p) {
          EXPECT_LT((pieces[p - 1].end - pieces[p].start).Length(), 1e-12 * (1 + b0.c.Length()));
          EXPECT_LT(1 - pieces[p - 1].end_tangent.Dot(pieces[p].start_tangent), 1e-12);
        }
        // G1 at the joint with the next section.
        if (k + 1 < skin->sections().size() && !s.report.end_reversed &&
            !skin->section(k + 1).report.end_reversed) {
          const SkinPiece& next = skin->section(k + 1).pieces[si].front();
          EXPECT_EQ(pieces.back().end, next.start);
          EXPECT_LT(1 - pieces.back().end_tangent.Dot(next.start_tangent), 1e-12);
        }
      }
      // Total => both balls inside the closed polyline within the chord tolerance.
      if (s.report.total) {
        const Polyline2 loop = skin->SectionOutline(k);
        for (const OrientedBall* b : {&balls[k], &balls[k + 1]}) {
          double d = INFINITY;
          int crossings = 0;
          for (size_t i = 0; i < loop.size(); ++i) {
            const Vec2 a = loop[i], c = loop[(i + 1) % loop.size()];
            const Vec2 ab = c - a;
            const double t = std::clamp((b->c - a).Dot(ab) / ab.LengthSqr(), 0.0, 1.0);
            d = std::min(d, (b->c - (a + ab * t)).Length());
            if ((a.y > b->c.y) != (c.y > b->c.y) &&
                b->c.x < a.x + (c.x - a.x) * (b->c.y - a.y) / (c.y - a.y)) {
              ++crossings;
            }
          }
          EXPECT_EQ(crossings % 2, 1) << "seed " << seed << " section " << k;
          EXPECT_GE(d, b->r - tol * (1 + 1e-9) - 1e-9 * b->r) << "seed " << seed;
        }
      }
    }
  }
  // The hybrid is the method that usually succeeds (digest §3.5 step 7).
  if (GetParam() == Method::kHybrid) {
    EXPECT_GT(total, sections * 3 / 4) << total << "/" << sections;
  }
  RecordProperty("total_sections", total);
}

INSTANTIATE_TEST_SUITE_P(Methods, SkinPropertyTest,
                         ::testing::Values(Method::kHybrid, Method::kOffset, Method::kNaive),
                         [](const auto& info) { return std::string(MethodName(info.param)); });

}  // namespace
}  // namespace sculpt::skin
