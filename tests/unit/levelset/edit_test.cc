#include "sculpt/levelset/edit.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <random>

namespace sculpt::levelset {
namespace {

Sculpture Ball(double r = 12.0, double dx = 0.5) {
  SculptureOptions o;
  o.voxel_size = dx;
  o.name = "ball";
  auto s = Sculpture::MakeSphere(o, {0, 0, 0}, r);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move(s).value();
}

EditRequest Press(Vec3 c, double r) {
  EditRequest e;
  e.kind = EditKind::kPress;
  e.tool = ToolShape::Sphere(c, r);
  e.speed = 10;
  e.dt = 0.05;
  return e;
}

TEST(EditTest, PressEmptiesTheToolRegion) {
  Sculpture s = Ball();
  EditSettings set;
  set.compensation = CompensationRegion::kNone;
  auto r = ApplyEdit(s, Press({13, 0, 0}, 3.0), set);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->changed);
  EXPECT_GT(r->substeps, 0);
  EXPECT_FALSE(r->press_fallback_csg);
  // Every voxel centre inside the tool is now outside the material.
  for (double x = 10.5; x <= 12.5; x += 0.5) {
    EXPECT_GT(s.SampleWorld({x, 0, 0}), 0.0) << x;
  }
  EXPECT_LT(r->volume_after, r->volume_before);
  EXPECT_GT(r->volume_before - r->volume_after, 5.0);
}

TEST(EditTest, ShellCompensationRestoresTheReferenceVolume) {
  Sculpture s = Ball();
  const double v0 = s.volume();
  EditSettings set;
  auto r = ApplyEdit(s, Press({13, 0, 0}, 3.0), set);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_GT(r->compensation_iterations, 0);
  EXPECT_FALSE(r->compensation_failed);
  EXPECT_NEAR(s.volume(), v0, 1e-5 * v0);
  EXPECT_NEAR(s.reference_volume(), v0, 1e-12 * v0);
  // The clay went to the shell: a surface point 6.5 units from the tool centre (inside the
  // shell, outside the tool) is now inside the material; the far side did not move.
  const double th = std::acos(0.868);
  EXPECT_LT(s.SampleWorld({12 * std::cos(th), 12 * std::sin(th), 0}), -0.02);
  EXPECT_NEAR(s.SampleWorld({-12, 0, 0}), 0.0, 0.02);
}

TEST(EditTest, IncrementalVolumeAgreesWithFullRecomputation) {
  Sculpture s = Ball();
  EditSettings set;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const EditKind kinds[] = {EditKind::kPress, EditKind::kAdd, EditKind::kSubtract,
                            EditKind::kSmooth, EditKind::kInflate, EditKind::kDeflate};
  for (int i = 0; i < 36; ++i) {
    Vec3 d{u(rng), u(rng), u(rng)};
    d = d / std::max(1e-9, d.Length());
    EditRequest e = Press(d * 12.5, 2.0 + (i % 3));
    e.kind = kinds[i % 6];
    e.amount = 1.0;
    auto r = ApplyEdit(s, e, set);
    ASSERT_TRUE(r.ok()) << r.status();
    const double full = s.ComputeVolume();
    EXPECT_NEAR(s.volume(), full, 1e-6 * full) << "edit " << i << " " << EditKindName(e.kind);
  }
  EXPECT_TRUE(s.CheckLevelSet().ok()) << s.CheckLevelSet();
}

TEST(EditTest, AddAndSubtractMoveTheReferenceVolume) {
  Sculpture s = Ball();
  EditSettings set;
  EditRequest add;
  add.kind = EditKind::kAdd;
  add.tool = ToolShape::Sphere({14, 0, 0}, 3.0);
  auto r = ApplyEdit(s, add, set);
  ASSERT_TRUE(r.ok());
  EXPECT_GT(r->volume_after - r->volume_before, 40.0);
  EXPECT_DOUBLE_EQ(s.reference_volume(), s.volume());
  EXPECT_LT(s.SampleWorld({16, 0, 0}), 0);
  EditRequest sub = add;
  sub.kind = EditKind::kSubtract;
  sub.tool = ToolShape::Box({0, 0, 12}, {3, 3, 3});
  r = ApplyEdit(s, sub, set);
  ASSERT_TRUE(r.ok());
  EXPECT_LT(r->volume_after, r->volume_before);
  EXPECT_GT(s.SampleWorld({0, 0, 10}), 0);
  EXPECT_DOUBLE_EQ(s.reference_volume(), s.volume());
}

TEST(EditTest, InflateGrowsAndDeflateShrinks) {
  Sculpture s = Ball();
  EditSettings set;
  EditRequest e;
  e.kind = EditKind::kInflate;
  e.tool = ToolShape::Sphere({12, 0, 0}, 4.0);
  e.amount = 1.0;
  const double before = s.SampleWorld({12.5, 0, 0});
  auto r = ApplyEdit(s, e, set);
  ASSERT_TRUE(r.ok());
  EXPECT_GT(r->volume_after, r->volume_before);
  EXPECT_NEAR(s.SampleWorld({12.5, 0, 0}), before - 1.0, 0.2);
  e.kind = EditKind::kDeflate;
  e.tool = ToolShape::Sphere({-12, 0, 0}, 4.0);
  r = ApplyEdit(s, e, set);
  ASSERT_TRUE(r.ok());
  EXPECT_LT(r->volume_after, r->volume_before);
}

TEST(EditTest, SmoothRoundsABoxEdge) {
  SculptureOptions o;
  o.voxel_size = 0.5;
  auto s = Sculpture::MakeBox(o, {-6, -6, -6}, {6, 6, 6});
  ASSERT_TRUE(s.ok());
  EditSettings set;
  set.compensation = CompensationRegion::kNone;
  EditRequest e;
  e.kind = EditKind::kSmooth;
  e.tool = ToolShape::Sphere({6, 6, 0}, 3.0);
  e.amount = 4.0;
  const double corner = s->SampleWorld({5.75, 5.75, 0});
  auto r = ApplyEdit(*s, e, set);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->changed);
  EXPECT_GT(s->SampleWorld({5.75, 5.75, 0}), corner + 0.05);  // the edge was eaten away
  EXPECT_LT(r->volume_after, r->volume_before);
}

TEST(EditTest, DirtyLeavesStayNearTheTool) {
  Sculpture s = Ball(20.0, 0.5);
  EditSettings set;
  auto r = ApplyEdit(s, Press({20.5, 0, 0}, 2.0), set);
  ASSERT_TRUE(r.ok());
  ASSERT_FALSE(r->dirty_leaves.empty());
  // Tool radius 4 voxels, shell 1 radius + 1.5 voxels, halo: all within ~24 voxels of the tool.
  const Int3 tool_index{41, 0, 0};
  for (const Int3& l : r->dirty_leaves) {
    EXPECT_LE(std::abs(l.x + 4 - tool_index.x), 24);
    EXPECT_LE(std::abs(l.y + 4 - tool_index.y), 24);
    EXPECT_LE(std::abs(l.z + 4 - tool_index.z), 24);
  }
  EXPECT_LT(r->dirty_leaves.size(), 200u);
}

TEST(EditTest, SameEditsGiveTheSameHashOnOneAndTwoThreads) {
  auto run = [](int threads) {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, threads);
    Sculpture s = Ball();
    EditSettings set;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < 20; ++i) {
      Vec3 d{u(rng), u(rng), u(rng)};
      d = d / std::max(1e-9, d.Length());
      EditRequest e = Press(d * 12.8, 2.5);
      if (i % 5 == 4) e.kind = EditKind::kSmooth;
      EXPECT_TRUE(ApplyEdit(s, e, set).ok());
    }
    return s.StateHash();
  };
  const uint64_t one = run(1);
  EXPECT_EQ(one, run(2));
  EXPECT_EQ(one, run(1));
}

TEST(EditTest, RejectsNanToolCenter) {
  Sculpture s = Ball();
  const uint64_t h = s.StateHash();
  auto r = ApplyEdit(s, Press({NAN, 0, 0}, 2), EditSettings{});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("tool.center"), std::string::npos) << r.status();
  EXPECT_EQ(s.StateHash(), h);
}

TEST(EditTest, RejectsNegativeRadius) {
  Sculpture s = Ball();
  const uint64_t h = s.StateHash();
  auto r = ApplyEdit(s, Press({12, 0, 0}, -1), EditSettings{});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("tool.size.x=-1 outside"), std::string::npos) << r.status();
  EXPECT_EQ(s.StateHash(), h);
}

TEST(EditTest, RejectsInfiniteSpeedAndBadDt) {
  Sculpture s = Ball();
  const uint64_t h = s.StateHash();
  EditRequest e = Press({12, 0, 0}, 2);
  e.speed = INFINITY;
  auto r = ApplyEdit(s, e, EditSettings{});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("edit.speed=inf"), std::string::npos) << r.status();
  e.speed = 1;
  e.dt = 0;
  r = ApplyEdit(s, e, EditSettings{});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("edit.dt=0 outside"), std::string::npos) << r.status();
  EXPECT_EQ(s.StateHash(), h);
}

TEST(EditTest, RejectsRadiusFarAboveTheObject) {
  Sculpture s = Ball(4.0, 0.5);
  const uint64_t h = s.StateHash();
  EditSettings set;
  set.max_tool_voxels = 1000;
  auto r = ApplyEdit(s, Press({0, 0, 0}, 200), set);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("tool.size=200 outside"), std::string::npos) << r.status();
  EXPECT_EQ(s.StateHash(), h);
}

TEST(EditTest, RejectsBadSettings) {
  Sculpture s = Ball();
  EditSettings set;
  set.cfl = 2.0;
  auto r = ApplyEdit(s, Press({12, 0, 0}, 2), set);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("cfl=2 outside"), std::string::npos);
  set = EditSettings{};
  set.motion.spatial = SpatialScheme::kCentral;
  EXPECT_FALSE(ApplyEdit(s, Press({12, 0, 0}, 2), set).ok());
}

TEST(EditTest, ValidEditSettingsRejectsBadSettings) {
  EditSettings set;
  set.cfl = 2.0;
  auto v = ValidEditSettings::Validate(set);
  ASSERT_FALSE(v.ok());
  EXPECT_NE(v.status().message().find("cfl=2 outside"), std::string::npos) << v.status();
  // The default-constructed one holds the defaults, which pass.
  EXPECT_TRUE(ValidEditSettings::Validate(EditSettings{}).ok());
  EXPECT_EQ(ValidEditSettings().get().cfl, EditSettings{}.cfl);
}

TEST(EditTest, ValidatedAndUnvalidatedSettingsEditAlike) {
  Sculpture a = Ball();
  Sculpture b = Ball();
  EditSettings set;
  set.cfl = 0.3;
  auto valid = ValidEditSettings::Validate(set);
  ASSERT_TRUE(valid.ok()) << valid.status();
  ASSERT_TRUE(ApplyEdit(a, Press({12, 0, 0}, 2), set).ok());
  ASSERT_TRUE(ApplyEdit(b, Press({12, 0, 0}, 2), *valid).ok());
  EXPECT_EQ(a.StateHash(), b.StateHash());
}

TEST(EditTest, GlobalCompensationRestoresVolume) {
  Sculpture s = Ball(8.0, 0.5);
  const double v0 = s.volume();
  EditSettings set;
  set.compensation = CompensationRegion::kGlobal;
  auto r = ApplyEdit(s, Press({9, 0, 0}, 2.5), set);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_GT(r->compensation_iterations, 0);
  EXPECT_NEAR(s.volume(), v0, 1e-4 * v0);
  EXPECT_NEAR(s.volume(), s.ComputeVolume(), 1e-6 * v0);
  EXPECT_TRUE(s.CheckLevelSet().ok()) << s.CheckLevelSet();
}

TEST(EditTest, GradientDescentFormsReduceTheVolumeError) {
  for (auto method : {CompensationMethod::kGradientDescentDelta,
                      CompensationMethod::kGradientDescentGrad}) {
    Sculpture s = Ball();
    EditSettings none;
    none.compensation = CompensationRegion::kNone;
    Sculpture t = s.Clone();
    auto lost = ApplyEdit(t, Press({13, 0, 0}, 3.0), none);
    ASSERT_TRUE(lost.ok());
    const double uncompensated = std::abs(lost->volume_after - lost->reference_volume);
    EditSettings set;
    set.compensation_method = method;
    set.max_compensation_iterations = 20;
    auto r = ApplyEdit(s, Press({13, 0, 0}, 3.0), set);
    ASSERT_TRUE(r.ok());
    EXPECT_LT(std::abs(r->volume_after - r->reference_volume), 0.05 * uncompensated)
        << static_cast<int>(method);
  }
}

TEST(EditTest, ReinitializeRegionKeepsVolumeTracked) {
  Sculpture s = Ball();
  auto r = ReinitializeRegion(s, Aabb{{6, -6, -6}, {14, 6, 6}}, 4, MotionSettings{});
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_NEAR(s.volume(), s.ComputeVolume(), 1e-9 * s.volume());
  EXPECT_FALSE(ReinitializeRegion(s, Aabb{{6, 0, 0}, {1, 0, 0}}, 4, MotionSettings{}).ok());
  EXPECT_FALSE(ReinitializeRegion(s, Aabb{{0, 0, 0}, {1, 1, 1}}, 0, MotionSettings{}).ok());
}

TEST(EditTest, BatchOfOverlappingPressesEmptiesEveryToolAndCompensatesOnce) {
  Sculpture s = Ball();
  const double v0 = s.volume();
  std::vector<EditRequest> stroke;
  for (int i = 0; i < 4; ++i) stroke.push_back(Press({12.8, 0.6 * i, 0}, 2.5));
  auto r = ApplyEdits(s, stroke, EditSettings{});
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->changed);
  for (int i = 0; i < 4; ++i) EXPECT_GT(s.SampleWorld({11.0, 0.6 * i, 0}), 0.0) << i;
  EXPECT_NEAR(s.volume(), v0, 1e-5 * v0);
  EXPECT_NEAR(s.volume(), s.ComputeVolume(), 1e-6 * v0);
  EXPECT_TRUE(s.CheckLevelSet().ok());
  // Deterministic.
  Sculpture t = Ball();
  ASSERT_TRUE(ApplyEdits(t, stroke, EditSettings{}).ok());
  EXPECT_EQ(s.StateHash(), t.StateHash());
}

TEST(EditTest, RejectsEmptyOrMixedBatch) {
  Sculpture s = Ball();
  const uint64_t h = s.StateHash();
  EXPECT_FALSE(ApplyEdits(s, {}, EditSettings{}).ok());
  std::vector<EditRequest> mixed{Press({12.8, 0, 0}, 2.5), Press({12.8, 1, 0}, 2.5)};
  mixed[1].kind = EditKind::kAdd;
  auto r = ApplyEdits(s, mixed, EditSettings{});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("edits[1].kind=add"), std::string::npos) << r.status();
  std::vector<EditRequest> bad{Press({12.8, 0, 0}, 2.5), Press({NAN, 1, 0}, 2.5)};
  EXPECT_FALSE(ApplyEdits(s, bad, EditSettings{}).ok());
  EXPECT_EQ(s.StateHash(), h);
}

}  // namespace
}  // namespace sculpt::levelset
