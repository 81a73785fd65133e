#include "sculpt/haptics/haptic_renderer.h"

#include <gtest/gtest.h>

#include <cmath>

#include "unit/haptics/field_helpers.h"

namespace sculpt::haptics {
namespace {

DeviceSample At(int tick, Vec3 p) { return DeviceSample{tick * 1e-3, p, {}}; }

TEST(HapticRendererTest, RejectsInvalidSettings) {
  HapticSettings s;
  s.max_force = -1;
  auto r = HapticRenderer::Create(s);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("HapticSettings.max_force=-1"), std::string::npos);
}

TEST(HapticRendererTest, PenaltyPushesOutOfTheFloor) {
  HapticSettings s;
  s.model = ForceModel::kPenalty;
  s.blend_ms = 0;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  std::shared_ptr<const SdfSampler> floor = testing::Floor(0);
  const TickOutput& o = r->Tick(floor, At(0, {0, 0, 1.5}));  // radius 2: 0.5 deep
  EXPECT_TRUE(o.contact);
  EXPECT_GT(o.colliding, 0);
  EXPECT_GT(o.force.z, 0);
  EXPECT_LT(std::abs(o.force.x) + std::abs(o.force.y), 1e-3 * o.force.z);
}

TEST(HapticRendererTest, ClampsToMaxForce) {
  HapticSettings s;
  s.max_force = 0.5;
  s.blend_ms = 0;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  std::shared_ptr<const SdfSampler> floor = testing::Floor(0);
  r->Tick(floor, At(0, {0, 0, 1}));
  const TickOutput& o = r->Tick(floor, At(1, {0, 0, -5}));
  EXPECT_TRUE(o.clamped);
  EXPECT_NEAR(o.force.Length(), 0.5, 1e-12);
  EXPECT_GT(o.model_force.Length(), 4.0);
}

TEST(HapticRendererTest, NanSampleIsCountedAndForceHeld) {
  HapticSettings s;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  std::shared_ptr<const SdfSampler> floor = testing::Floor(0);
  r->Tick(floor, At(0, {0, 0, 1}));
  const Vec3 held = r->Tick(floor, At(1, {0, 0, -1})).force;
  ASSERT_GT(held.z, 0);
  const TickOutput& o = r->Tick(floor, At(2, {NAN, 0, 0}));
  EXPECT_TRUE(o.nan_ignored);
  EXPECT_EQ(o.force, held);
  EXPECT_EQ(r->nan_samples(), 1u);
}

TEST(HapticRendererTest, NewSnapshotBlendsOverTheBlendTime) {
  HapticSettings s;
  s.blend_ms = 4;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  std::shared_ptr<const SdfSampler> a = testing::Floor(0), b = testing::Floor(1);
  // The device rests 1 deep (force k * 1) for a few ticks, so the damper is idle.
  for (int i = 0; i < 10; ++i) r->Tick(a, At(i, {0, 0, -1}));
  const double before = r->last().force.z;
  ASSERT_NEAR(before, 1.0, 0.01);
  // The new snapshot puts the device 2 deep: the output steps there over 4 ticks.
  double last = before;
  for (int i = 0; i < 4; ++i) {
    const TickOutput& o = r->Tick(b, At(10 + i, {0, 0, -1}));
    EXPECT_TRUE(o.blending) << i;
    EXPECT_GT(o.force.z, last) << i;
    EXPECT_LT(o.force.z - last, 0.3) << i;  // a quarter of the step or less
    last = o.force.z;
  }
  const TickOutput& done = r->Tick(b, At(14, {0, 0, -1}));
  EXPECT_FALSE(done.blending);
  EXPECT_NEAR(done.force.z, 2.0, 0.05);
}

TEST(HapticRendererTest, PointToolUsesOneSample) {
  HapticSettings s;
  s.tool_radius = 0;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->tool_samples().size(), 1u);
}

}  // namespace
}  // namespace sculpt::haptics
