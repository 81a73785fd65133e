// Hard numerical cases of the sculpting kernel (issue: "Sculpting kernel"), each with an
// asserted bound.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sculpt/levelset/edit.h"
#include "levelset/sculpture_grid.h"

namespace sculpt::levelset {
namespace {

SculptureOptions Opts(double dx) {
  SculptureOptions o;
  o.voxel_size = dx;
  o.name = "stability";
  return o;
}

bool AllFinite(const Sculpture& s) {
  for (auto it = levelset::internal::GridOf(s).tree().cbeginValueAll(); it; ++it) {
    if (!std::isfinite(*it)) return false;
  }
  return true;
}

// Largest |phi_a - phi_b| over voxels near either surface, in voxels.
double MaxSurfaceDifferenceVoxels(const Sculpture& a, const Sculpture& b) {
  const auto& ga = levelset::internal::GridOf(a);
  const auto& gb = levelset::internal::GridOf(b);
  auto acc = gb.getConstAccessor();
  double worst = 0;
  for (auto it = ga.tree().cbeginValueOn(); it; ++it) {
    const float va = *it;
    const float vb = acc.getValue(it.getCoord());
    if (std::min(std::abs(va), std::abs(vb)) > a.voxel_size()) continue;
    worst = std::max(worst, static_cast<double>(std::abs(va - vb)));
  }
  return worst / a.voxel_size();
}

// A tool moving 10 voxels per step (CFL 20 at cfl 0.5 without substeps) against the same tool
// moving 0.5 voxel per step: substeps keep the result within one voxel of the slow one.
TEST(EditStability, FastToolMatchesSlowMotion) {
  auto slow = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 10.0);
  ASSERT_TRUE(slow.ok());
  Sculpture fast = slow->Clone();
  EditSettings set;
  EditRequest e;
  e.kind = EditKind::kPress;
  e.tool = ToolShape::Sphere({11.5, 0, 0}, 4.0);
  e.dt = 1.0;
  e.speed = 0.25;  // 0.5 voxel per step
  auto rs = ApplyEdit(*slow, e, set);
  e.speed = 5.0;  // 10 voxels per step
  auto rf = ApplyEdit(fast, e, set);
  ASSERT_TRUE(rs.ok() && rf.ok());
  // One step would move 10 voxels: the CFL limit splits it into substeps of half a voxel.
  EXPECT_EQ(rf->steps, 1);
  EXPECT_GE(rf->substeps, 8);
  EXPECT_GT(rs->steps, rf->steps);
  EXPECT_TRUE(AllFinite(fast));
  EXPECT_TRUE(fast.CheckLevelSet().ok()) << fast.CheckLevelSet();
  EXPECT_LT(MaxSurfaceDifferenceVoxels(fast, *slow), 1.0);
  // And a swept stroke (capsule) between two poses 20 voxels apart carves one continuous groove.
  EditRequest stroke;
  stroke.kind = EditKind::kPress;
  stroke.tool = ToolShape::Capsule({10.5, -5, 0}, {10.5, 5, 0}, 2.0);
  stroke.speed = 20.0;
  auto rc = ApplyEdit(fast, stroke, set);
  ASSERT_TRUE(rc.ok()) << rc.status();
  for (double y = -5; y <= 5; y += 1.0) EXPECT_GT(fast.SampleWorld({9.5, y, 0}), 0.0) << y;
  EXPECT_TRUE(fast.CheckLevelSet().ok());
}

TEST(EditStability, ToolLargerThanTheObjectRemovesIt) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 4.0);
  ASSERT_TRUE(s.ok());
  EditSettings set;
  EditRequest e;
  e.kind = EditKind::kPress;
  e.tool = ToolShape::Sphere({1, 0, 0}, 7.0);
  e.speed = 10;
  auto r = ApplyEdit(*s, e, set);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(AllFinite(*s));
  EXPECT_LT(s->volume(), 0.01 * r->volume_before);
  EXPECT_TRUE(r->compensation_failed);  // nowhere left to put the clay; reported, not hidden
  EXPECT_NEAR(s->volume(), s->ComputeVolume(), 1e-6 * r->volume_before);
}

TEST(EditStability, ToolFullyInsideTheObjectLeavesACavity) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 12.0);
  ASSERT_TRUE(s.ok());
  EditSettings set;
  set.compensation = CompensationRegion::kNone;
  EditRequest e;
  e.kind = EditKind::kPress;
  e.tool = ToolShape::Sphere({0, 0, 0}, 4.0);
  auto r = ApplyEdit(*s, e, set);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->press_fallback_csg);
  EXPECT_GT(s->SampleWorld({0, 0, 0}), 0.0);
  EXPECT_LT(s->SampleWorld({0, 0, 6}), 0.0);
  const double tool_volume = 4.0 / 3.0 * M_PI * 64;
  EXPECT_NEAR(r->volume_before - r->volume_after, tool_volume, 0.05 * tool_volume);
  EXPECT_TRUE(s->CheckLevelSet().ok()) << s->CheckLevelSet();
}

TEST(EditStability, ToolThatNeverTouchesChangesNothing) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 8.0);
  ASSERT_TRUE(s.ok());
  const uint64_t h = s->StateHash();
  EditSettings set;
  for (EditKind k : {EditKind::kPress, EditKind::kSubtract, EditKind::kSmooth,
                     EditKind::kDeflate}) {
    EditRequest e;
    e.kind = k;
    e.tool = ToolShape::Sphere({14, 0, 0}, 2.0);
    auto r = ApplyEdit(*s, e, set);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_FALSE(r->changed) << EditKindName(k);
  }
  EXPECT_EQ(s->StateHash(), h);
}

TEST(EditStability, ZeroSpeedPressChangesNothing) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 8.0);
  ASSERT_TRUE(s.ok());
  const uint64_t h = s->StateHash();
  EditRequest e;
  e.kind = EditKind::kPress;
  e.tool = ToolShape::Sphere({9, 0, 0}, 2.0);
  e.speed = 0;
  auto r = ApplyEdit(*s, e, EditSettings{});
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_FALSE(r->changed);
  EXPECT_EQ(r->substeps, 0);
  EXPECT_EQ(s->StateHash(), h);
}

// A crawling tool (1e-9 units per second) still presses through in bounded work: the press runs
// until the tool is empty, so a floor on the motion per step changes nothing but the cost.
TEST(EditStability, CrawlingToolFinishesInBoundedSteps) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 10.0);
  ASSERT_TRUE(s.ok());
  Sculpture fast = s->Clone();
  EditRequest e;
  e.kind = EditKind::kPress;
  e.tool = ToolShape::Sphere({11, 0, 0}, 3.0);
  e.dt = 0.01;
  e.speed = 1e-9;
  auto slow = ApplyEdit(*s, e, EditSettings{});
  ASSERT_TRUE(slow.ok()) << slow.status();
  EXPECT_LE(slow->steps, 200);
  EXPECT_FALSE(slow->press_fallback_csg);
  EXPECT_GT(s->SampleWorld({9.5, 0, 0}), 0.0);
  e.speed = 100;
  ASSERT_TRUE(ApplyEdit(fast, e, EditSettings{}).ok());
  EXPECT_LT(MaxSurfaceDifferenceVoxels(*s, fast), 1.0);
}

// A 2-voxel sheet cut through by a wall-shaped tool: the piece cut off is found, removed under
// kRemoveSmall with the reference re-baselined, and kept (but reported) under kKeep.
TEST(EditStability, ThinSheetPressedThroughSplitsAndAppliesIslandsPolicy) {
  const double dx = 0.5;
  auto make = [&] { return Sculpture::MakeBox(Opts(dx), {-10, -10, -0.5}, {10, 10, 0.5}); };
  EditRequest cut;
  cut.kind = EditKind::kPress;
  cut.tool = ToolShape::Box({6.5, 0, 0}, {1.0, 12.0, 3.0});
  cut.speed = 10;
  {
    auto s = make();
    ASSERT_TRUE(s.ok());
    EditSettings set;
    set.islands = IslandPolicy::kRemoveSmall;
    set.min_island_volume = 100.0;  // the 2.5 x 20 x 1 strip beyond the cut is ~50
    const double v0 = s->volume();
    auto r = ApplyEdit(*s, cut, set);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_EQ(r->islands_found, 1);
    EXPECT_EQ(r->islands_removed, 1);
    EXPECT_NEAR(r->island_volume_removed, 2.5 * 20 * 1, 8.0);
    EXPECT_GT(s->SampleWorld({9, 0, 0}), 0.0);   // the strip is gone
    EXPECT_LT(s->SampleWorld({0, 0, 0}), 0.0);   // the main sheet stays
    EXPECT_NEAR(s->reference_volume(), v0 - r->island_volume_removed, 1e-9 * v0);
    EXPECT_NEAR(s->volume(), s->ComputeVolume(), 1e-6 * v0);
    EXPECT_TRUE(s->CheckLevelSet().ok()) << s->CheckLevelSet();
  }
  {
    auto s = make();
    EditSettings set;
    set.islands = IslandPolicy::kKeep;
    auto r = ApplyEdit(*s, cut, set);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->islands_found, 1);
    EXPECT_EQ(r->islands_removed, 0);
    EXPECT_LT(s->SampleWorld({9, 0, 0}), 0.0);  // kept
    EXPECT_GT(s->SampleWorld({6.5, 0, 0}), 0.0);  // the cut is through
  }
}

// 10,000 random press strokes with shell compensation: the volume stays within 0.05% of the
// initial volume at every checkpoint and the band stays valid.
TEST(EditStability, TenThousandPressStrokesKeepVolume) {
  auto s = Sculpture::MakeSphere(Opts(1.0), {0, 0, 0}, 32.0);
  ASSERT_TRUE(s.ok());
  const double v0 = s->volume();
  EditSettings set;
  std::mt19937 rng(2024);
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> depth(0.5, 3.0);
  double worst = 0;
  Sculpture::EikonalReport half_way;
  for (int i = 1; i <= 10000; ++i) {
    Vec3 d{n(rng), n(rng), n(rng)};
    d = d / d.Length();
    // Put the tool relative to the current surface so strokes keep touching as the shape moves.
    double r = 32;
    for (int k = 0; k < 8 && s->SampleWorld(d * r) < 0; ++k) r += 1;
    for (int k = 0; k < 8 && s->SampleWorld(d * r) > 0; ++k) r -= 1;
    EditRequest e;
    e.kind = EditKind::kPress;
    e.tool = ToolShape::Sphere(d * (r + 5 - depth(rng)), 5.0);
    e.speed = 120;
    e.dt = 1.0 / 120;
    auto res = ApplyEdit(*s, e, set);
    ASSERT_TRUE(res.ok()) << res.status();
    const double drift = std::abs(s->volume() - v0) / v0;
    worst = std::max(worst, drift);
    if (i % 500 == 0) {
      ASSERT_LE(drift, 5e-4) << "stroke " << i;
      ASSERT_NEAR(s->volume(), s->ComputeVolume(), 1e-6 * v0) << "stroke " << i;
    }
    if (i == 5000) half_way = s->MeasureEikonal();
  }
  EXPECT_LE(worst, 5e-4);
  EXPECT_TRUE(AllFinite(*s));
  EXPECT_TRUE(s->CheckLevelSet().ok()) << s->CheckLevelSet();
  // The reinitialisation policy holds the edited band near its threshold (mean error 0.15 per
  // edited region), so the Eikonal error settles instead of growing: bounded in absolute terms
  // and no worse after 10,000 strokes than after 5,000.
  const auto eik = s->MeasureEikonal();
  EXPECT_LT(eik.mean_abs_error, 0.2);
  EXPECT_LT(eik.fraction_outside_half, 0.08);
  EXPECT_LT(eik.mean_abs_error, half_way.mean_abs_error + 0.03);
  RecordProperty("eikonal_mean", std::to_string(eik.mean_abs_error));
  RecordProperty("worst_drift", std::to_string(worst));
}

// Seed 000 claim 18: reinitialisation keeps the zero level set within a fraction of a voxel.
TEST(EditStability, RepeatedReinitializationBarelyMovesTheSurface) {
  auto s = Sculpture::MakeSphere(Opts(1.0), {0, 0, 0}, 16.0);
  ASSERT_TRUE(s.ok());
  const Sculpture original = s->Clone();
  for (int i = 0; i < 25; ++i) {
    auto r = ReinitializeRegion(*s, Aabb{{-20, -20, -20}, {20, 20, 20}}, 4, MotionSettings{});
    ASSERT_TRUE(r.ok()) << r.status();
  }
  // 100 pseudo-time steps: surface displacement below 0.1 voxel everywhere near the surface.
  EXPECT_LT(MaxSurfaceDifferenceVoxels(*s, original), 0.1);
  const double radius_shift =
      std::cbrt(s->volume() * 3 / (4 * M_PI)) - std::cbrt(original.volume() * 3 / (4 * M_PI));
  EXPECT_LT(std::abs(radius_shift), 0.1);
}

}  // namespace
}  // namespace sculpt::levelset
