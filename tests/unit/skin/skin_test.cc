#include "sculpt/skin/skin.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace sculpt::skin {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

SkinOptions Opts(Method m, double tol = 1e-3) {
  SkinOptions o;
  o.method = m;
  o.chord_tolerance = tol;
  return o;
}

bool HasNote(const SectionReport& r, const std::string& text) {
  for (const std::string& n : r.notes) {
    if (n.find(text) != std::string::npos) return true;
  }
  return false;
}

// Digest §5.2 example 2 (moderate right bend): min(1+kd) = 0.528 (+) and 1.196 (-); the hybrid
// puts the offset on the - (exterior) side and an A-spline on the + side; total.
TEST(SkinSectionTest, ModerateBendMatchesDigest) {
  const OrientedBall b0{{0, 0}, 1.0, 40 * kDeg}, b1{{4, 0}, 0.6, -40 * kDeg};
  const Section s = BuildSection(b0, b1, Opts(Method::kHybrid));
  EXPECT_NEAR(s.report.side[0].min_one_plus_kd, 0.528, 5e-4);
  EXPECT_NEAR(s.report.side[1].min_one_plus_kd, 1.196, 5e-4);
  EXPECT_EQ(s.report.side[0].aspline_pieces, 1);
  EXPECT_EQ(s.report.side[1].offset_pieces, 1);
  EXPECT_TRUE(s.report.simple);
  EXPECT_TRUE(s.report.total);
  EXPECT_GE(s.report.clearance, -1e-3);
}

// Digest §5.2 example 3 (tight bend): the offset's + side has min(1+kd) = -0.865, loops and cuts
// a ball; the hybrid's A-spline there is clean.
TEST(SkinSectionTest, TightBendOffsetLoopsHybridClean) {
  const OrientedBall b0{{0, 0}, 1.5, 70 * kDeg}, b1{{3.5, 0}, 1.2, -70 * kDeg};
  const Section off = BuildSection(b0, b1, Opts(Method::kOffset));
  EXPECT_NEAR(off.report.side[0].min_one_plus_kd, -0.865, 5e-4);
  EXPECT_GE(off.report.side[0].self_intersections, 1);
  EXPECT_LT(off.report.side[0].clearance, -0.07);
  EXPECT_FALSE(off.report.simple);
  EXPECT_FALSE(off.report.total);
  EXPECT_TRUE(HasNote(off.report, "side + crosses itself"));

  const Section hyb = BuildSection(b0, b1, Opts(Method::kHybrid));
  EXPECT_EQ(hyb.report.side[0].aspline_pieces, 1);
  EXPECT_EQ(hyb.report.side[0].self_intersections, 0);
  EXPECT_GE(hyb.report.side[0].clearance, -1e-3);
  EXPECT_TRUE(hyb.report.total);
}

// Digest §5.2 example 1 and §3.6: collinear centres, r0 = 2, r1 = 1: the offset cuts B0 iff
// L^2 < 12; L = 3 gives clearance -0.0114.
TEST(SkinSectionTest, CollinearFailingRatioReportedNonTotal) {
  const Section bad = BuildSection({{0, 0}, 2, 0}, {{3, 0}, 1, 0}, Opts(Method::kHybrid));
  EXPECT_FALSE(bad.report.total);
  EXPECT_NEAR(bad.report.clearance, -0.0114, 3e-4);
  EXPECT_TRUE(HasNote(bad.report, "collinear centres: L^2=9 < 6 r_big (r_big - r_small)=12"));
  EXPECT_TRUE(HasNote(bad.report, "enters balls[0]"));
  const Section good = BuildSection({{0, 0}, 2, 0}, {{3.5, 0}, 1, 0}, Opts(Method::kHybrid));
  EXPECT_TRUE(good.report.total);
  EXPECT_FALSE(HasNote(good.report, "collinear"));
}

// Digest §5.2 example 4: S-shape, hidden ball at (2, 0), r = 1, t = (0.9736, -0.2281).
TEST(SkinSectionTest, SShapeHiddenBall) {
  const Section s =
      BuildSection({{0, 0}, 1, 30 * kDeg}, {{4, 0}, 1, 30 * kDeg}, Opts(Method::kHybrid));
  ASSERT_EQ(s.report.hidden.size(), 1u);
  const OrientedBall& h = s.report.hidden[0];
  EXPECT_NEAR(h.c.x, 2, 1e-12);
  EXPECT_NEAR(h.c.y, 0, 1e-12);
  EXPECT_NEAR(h.r, 1, 1e-12);
  EXPECT_NEAR(h.t().x, 0.9736, 1e-4);
  EXPECT_NEAR(h.t().y, -0.2281, 1e-4);
  for (int side = 0; side < 2; ++side) {
    EXPECT_EQ(s.report.side[side].offset_pieces, 1);
    EXPECT_EQ(s.report.side[side].aspline_pieces, 1);
    EXPECT_EQ(s.report.side[side].self_intersections, 0);
    // G1 at the hidden ball: the two pieces meet with the same analytic tangent.
    const auto& p = s.pieces[side];
    ASSERT_EQ(p.size(), 2u);
    EXPECT_NEAR((p[0].end - p[1].start).Length(), 0, 1e-12);
    EXPECT_LT(1 - p[0].end_tangent.Dot(p[1].start_tangent), 1e-12);
  }
  EXPECT_TRUE(s.report.total);
}

TEST(SkinTest, ChainListsShareJointsOnceAndStartAtContacts) {
  std::vector<OrientedBall> balls{
      {{0, 0}, 1, 10 * kDeg}, {{3, 0.5}, 0.8, -5 * kDeg}, {{6, 0}, 1.1, -20 * kDeg}};
  auto skin = Skin::Build(balls, Opts(Method::kHybrid));
  ASSERT_TRUE(skin.ok()) << skin.status();
  for (int side : {1, -1}) {
    const Polyline2 chain = skin->Chain(side);
    EXPECT_EQ(chain.front(), balls[0].Contact(side));
    EXPECT_EQ(chain.back(), balls[2].Contact(side));
    for (size_t i = 1; i < chain.size(); ++i) EXPECT_NE(chain[i], chain[i - 1]);
    const Section& s0 = skin->section(0);
    const Section& s1 = skin->section(1);
    EXPECT_EQ(chain.size(), (side > 0 ? s0.plus.size() + s1.plus.size()
                                      : s0.minus.size() + s1.minus.size()) - 1);
  }
  const Polyline2 outline = skin->Outline();
  EXPECT_GT(outline.size(), 10u);
}

// Digest §7 claim 24: moving one ball rebuilds its two sections; the others are byte-identical
// (with the curvature sampler; the codec's sampler also rebuilds up to the next restart, below).
TEST(SkinTest, SetBallRebuildsOnlyItsTwoSections) {
  std::vector<OrientedBall> balls;
  for (int i = 0; i < 8; ++i) balls.push_back({{2.0 * i, 0.3 * (i % 2)}, 0.7, 0});
  SkinOptions o = Opts(Method::kHybrid);
  o.sample_for_codec = false;
  auto skin = Skin::Build(balls, o);
  ASSERT_TRUE(skin.ok()) << skin.status();
  const Skin before = *skin;
  auto change = skin->SetBall(4, {{8.1, 0.5}, 0.8, 10 * kDeg});
  ASSERT_TRUE(change.ok()) << change.status();
  EXPECT_EQ(change->changed, (std::vector<size_t>{3, 4}));
  for (size_t k = 0; k < skin->sections().size(); ++k) {
    const bool changed = k == 3 || k == 4;
    EXPECT_EQ(skin->section(k).id, before.section(k).id);
    EXPECT_EQ(skin->section(k).version, before.section(k).version + (changed ? 1 : 0));
    EXPECT_EQ(skin->section(k).plus == before.section(k).plus, !changed) << k;
  }
  // End balls touch one section.
  EXPECT_EQ(skin->SetBall(0, {{0, 0.1}, 0.7, 0})->changed, (std::vector<size_t>{0}));
  EXPECT_EQ(skin->SetBall(7, {{14, 0.4}, 0.7, 0})->changed, (std::vector<size_t>{6}));
}

TEST(SkinTest, SetBallRefusesInadmissibleMoveAndKeepsSkin) {
  auto skin = Skin::Build({{{0, 0}, 1, 0}, {{3, 0}, 1, 0}, {{6, 0}, 1, 0}});
  ASSERT_TRUE(skin.ok());
  const Skin before = *skin;
  auto r = skin->SetBall(1, {{0.2, 0}, 0.5, 0});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("balls[1] lies inside balls[0]"), std::string::npos)
      << r.status();
  EXPECT_EQ(skin->balls()[1].c, before.balls()[1].c);
  EXPECT_FALSE(skin->SetBall(3, {{9, 0}, 1, 0}).ok());
}

TEST(SkinTest, InsertAndRemoveSpliceSections) {
  SkinOptions o;
  o.sample_for_codec = false;  // the splice alone (the codec's sampler: SampledForTheCodec...)
  auto skin = Skin::Build({{{0, 0}, 1, 0}, {{4, 0}, 1, 0}, {{8, 0}, 1, 0}}, o);
  ASSERT_TRUE(skin.ok());
  const uint64_t id0 = skin->section(0).id, id1 = skin->section(1).id;
  auto ins = skin->InsertBall(1, {{2, 0.2}, 0.8, 0});
  ASSERT_TRUE(ins.ok()) << ins.status();
  EXPECT_EQ(ins->changed, (std::vector<size_t>{0, 1}));
  EXPECT_EQ(ins->splice_at, 0u);
  EXPECT_EQ(ins->removed, 1u);
  EXPECT_EQ(ins->inserted, 2u);
  ASSERT_EQ(skin->sections().size(), 3u);
  EXPECT_EQ(skin->section(2).id, id1);
  EXPECT_NE(skin->section(0).id, id0);
  auto app = skin->InsertBall(4, {{12, 0}, 1, 0});
  ASSERT_TRUE(app.ok());
  EXPECT_EQ(app->changed, (std::vector<size_t>{3}));
  auto rem = skin->RemoveBall(1);
  ASSERT_TRUE(rem.ok()) << rem.status();
  EXPECT_EQ(rem->changed, (std::vector<size_t>{0}));
  EXPECT_EQ(skin->sections().size(), 3u);
  auto rem_end = skin->RemoveBall(0);
  ASSERT_TRUE(rem_end.ok());
  EXPECT_TRUE(rem_end->changed.empty());
  EXPECT_EQ(skin->sections().size(), 2u);
  ASSERT_TRUE(skin->RemoveBall(0).ok());
  EXPECT_FALSE(skin->RemoveBall(0).ok());  // two balls remain
}

// With the codec's sampler (the default) a section starts from the decoder state its
// predecessor ends with, unless it is a codec restart. An edit rebuilds the sections after its
// own up to the next restart, so the skin stays a function of its balls: after every move,
// insert and remove of a random sequence it equals a skin built from the same balls point for
// point, and every section it did not list is unchanged.
TEST(SkinTest, SampledForTheCodecTheSkinIsAFunctionOfItsBalls) {
  std::mt19937_64 rng(20261207);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<OrientedBall> balls;
  for (int i = 0; i < 40; ++i) {
    balls.push_back({{2.0 * i, 0.6 * std::sin(0.7 * i)}, 0.8 + 0.2 * std::cos(1.3 * i),
                     0.3 * std::cos(0.5 * i)});
  }
  SkinOptions o;
  ASSERT_TRUE(o.sample_for_codec);  // the default
  auto skin = Skin::Build(balls, o);
  ASSERT_TRUE(skin.ok()) << skin.status();
  const auto same = [](const CodecCursor& a, const CodecCursor& b) {
    return a.theta == b.theta && a.omega == b.omega && a.lp == b.lp && a.l1 == b.l1 &&
           a.actx == b.actx && a.mag_e == b.mag_e && a.valid == b.valid &&
           a.has_point == b.has_point && a.p == b.p;
  };
  size_t edits = 0, listed = 0, max_listed = 0;
  for (int e = 0; e < 120; ++e) {
    const Skin before = *skin;
    const size_t n = skin->balls().size();
    const int kind = static_cast<int>(rng() % 4);
    StatusOr<SkinChange> change = InvalidArgument("none");
    if (kind <= 1 || n <= 6) {
      const size_t i = rng() % n;
      OrientedBall b = skin->balls()[i];
      b.c = b.c + Vec2{0.1 * u(rng), 0.3 * u(rng)};
      b.theta += 0.1 * u(rng);
      change = skin->SetBall(i, b);
    } else if (kind == 2 && n < 60) {
      const size_t i = rng() % (n + 1);
      const Vec2 at = i == 0 ? skin->balls()[0].c - Vec2{2, 0}
                      : i == n ? skin->balls()[n - 1].c + Vec2{2, 0}
                               : (skin->balls()[i - 1].c + skin->balls()[i].c) * 0.5;
      change = skin->InsertBall(i, {at + Vec2{0, 0.2 * u(rng)}, 0.3, 0});
    } else {
      change = skin->RemoveBall(rng() % n);
    }
    if (!change.ok()) continue;  // an inadmissible pair: the skin is unchanged
    ++edits;
    listed += change->changed.size();
    max_listed = std::max(max_listed, change->changed.size());
    auto fresh = Skin::Build(skin->balls(), skin->options());
    ASSERT_TRUE(fresh.ok()) << fresh.status();
    ASSERT_EQ(skin->sections().size(), fresh->sections().size());
    for (size_t k = 0; k < skin->sections().size(); ++k) {
      const Section& a = skin->section(k);
      const Section& b = fresh->section(k);
      ASSERT_EQ(a.plus, b.plus) << "edit " << e << " section " << k;
      ASSERT_EQ(a.minus, b.minus) << "edit " << e << " section " << k;
      ASSERT_EQ(a.codec_restart, b.codec_restart) << "edit " << e << " section " << k;
      ASSERT_EQ(a.codec_restart, skin->CodecRestart(k));
      ASSERT_TRUE(same(a.codec_end[0], b.codec_end[0]) && same(a.codec_end[1], b.codec_end[1]))
          << "edit " << e << " section " << k;
    }
    // Listed sections are consecutive; the one after the last listed restarts (or none follows).
    for (size_t j = 1; j < change->changed.size(); ++j) {
      ASSERT_EQ(change->changed[j], change->changed[j - 1] + 1) << "edit " << e;
    }
    if (!change->changed.empty() && change->changed.back() + 1 < skin->sections().size()) {
      EXPECT_TRUE(skin->CodecRestart(change->changed.back() + 1)) << "edit " << e;
    }
    // Sections neither listed nor spliced in keep their points (and ids).
    if (kind <= 1 || n <= 6) {
      for (size_t k = 0; k < skin->sections().size(); ++k) {
        if (std::find(change->changed.begin(), change->changed.end(), k) !=
            change->changed.end()) {
          continue;
        }
        EXPECT_EQ(skin->section(k).plus, before.section(k).plus) << "edit " << e << " " << k;
        EXPECT_EQ(skin->section(k).version, before.section(k).version);
      }
    }
  }
  EXPECT_GT(edits, 80u);
  // About kCodecRestartPeriod sections past an edit's own, not the rest of the chain.
  EXPECT_LT(static_cast<double>(listed) / static_cast<double>(edits),
            2.0 + 2.0 * kCodecRestartPeriod);
  EXPECT_LT(max_listed, 30u);
}

TEST(SkinTest, BuildRefusesBadOptions) {
  std::vector<OrientedBall> balls{{{0, 0}, 1, 0}, {{3, 0}, 1, 0}};
  SkinOptions o;
  o.chord_tolerance = std::nan("");
  EXPECT_NE(Skin::Build(balls, o).status().message().find("chord_tolerance=nan"),
            std::string::npos);
  o.chord_tolerance = 1e-20;
  EXPECT_FALSE(Skin::Build(balls, o).ok());
  EXPECT_FALSE(ParseMethod("spline").ok());
  EXPECT_EQ(*ParseMethod("offset"), Method::kOffset);
}

TEST(SkinTest, DefaultToleranceIsAThousandthOfSmallestRadius) {
  auto skin = Skin::Build({{{0, 0}, 2, 0}, {{4, 0}, 0.5, 0}});
  ASSERT_TRUE(skin.ok());
  EXPECT_DOUBLE_EQ(skin->chord_tolerance(), 5e-4);
}

}  // namespace
}  // namespace sculpt::skin

namespace sculpt::skin {
namespace {

double DistToPolyline(Vec2 p, const Polyline2& pl) {
  double best = INFINITY;
  for (size_t i = 1; i < pl.size(); ++i) {
    const Vec2 a = pl[i - 1], ab = pl[i] - a;
    const double t = std::clamp((p - a).Dot(ab) / ab.LengthSqr(), 0.0, 1.0);
    best = std::min(best, (p - (a + ab * t)).Length());
  }
  return best;
}

// Digest §7 claim 26: every point of the exact curves lies within the chord tolerance of the
// polylines (checked on 400 exact samples per piece).
TEST(SkinTest, PolylinesWithinChordToleranceOfExactCurves) {
  // Both samplers: by curvature, and following the contour codec (SkinOptions::sample_for_codec).
  for (bool follow : {false, true}) {
  for (Method m : {Method::kHybrid, Method::kOffset, Method::kNaive}) {
    std::vector<OrientedBall> balls;
    for (int i = 0; i < 8; ++i) {
      balls.push_back({{2.6 * i, 0.9 * std::sin(0.8 * i)}, 0.5 + 0.4 * std::abs(std::cos(1.1 * i)),
                       25 * kDeg * std::cos(0.8 * i)});
    }
    SkinOptions o = Opts(m, 2e-3);
    o.sample_for_codec = follow;
    auto skin = Skin::Build(balls, o);
    ASSERT_TRUE(skin.ok()) << skin.status();
    double worst = 0;
    for (size_t k = 0; k < skin->sections().size(); ++k) {
      const Section& s = skin->section(k);
      const HermiteMother mother = HermiteMother::FromBalls(balls[k], balls[k + 1]);
      const DistanceFn dist{balls[k].r, balls[k + 1].r};
      for (int si = 0; si < 2; ++si) {
        const Offset off{&mother, &dist, si == 0 ? 1 : -1};
        for (const SkinPiece& p : s.pieces[si]) {
          for (int i = 0; i <= 400; ++i) {
            const double w = i / 400.0;
            const Vec2 exact = p.kind == SkinPiece::Kind::kOffset
                                   ? off.P(p.tau_a + (p.tau_b - p.tau_a) * w)
                                   : p.spline.AtPhi(std::numbers::pi / 2 * w);
            worst = std::max(worst, DistToPolyline(exact, si == 0 ? s.plus : s.minus));
          }
        }
      }
    }
    EXPECT_LE(worst, 2e-3) << MethodName(m) << (follow ? " following the codec" : "");
    EXPECT_GT(worst, 2e-4) << MethodName(m);  // the sampling uses the tolerance, not far less
  }
  }
}

}  // namespace
}  // namespace sculpt::skin
