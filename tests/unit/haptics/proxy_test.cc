#include "sculpt/haptics/proxy.h"

#include <gtest/gtest.h>

#include "unit/haptics/field_helpers.h"

namespace sculpt::haptics {
namespace {

constexpr double kDt = 1e-3;

TEST(ProxyModelTest, FreeMotionGivesNoForce) {
  auto floor = testing::Floor(0);
  ProxyModel m(1.0, 0.05);
  m.Reset(floor.get(), {0, 0, 5});
  const ProxyState& s = m.Update(floor.get(), {1, 0, 4}, kDt);
  EXPECT_FALSE(s.contact);
  EXPECT_EQ(s.force.Length(), 0);
  EXPECT_NEAR((s.proxy - Vec3{1, 0, 4}).Length(), 0, 1e-12);
}

TEST(ProxyModelTest, ProxyStaysOnSurfaceAndPushesOut) {
  auto floor = testing::Floor(0);
  ProxyModel m(2.0, 0.05);
  m.Reset(floor.get(), {0, 0, 1});
  const ProxyState& s = m.Update(floor.get(), {0.5, 0, -3}, kDt);
  ASSERT_TRUE(s.contact);
  EXPECT_NEAR(s.proxy.z, 0, 0.01);
  EXPECT_NEAR(s.proxy.x, 0.5, 0.01);  // slid to above the device
  EXPECT_NEAR(s.force.z, 2.0 * 3, 0.05);
  EXPECT_NEAR(s.force.x, 0, 0.05);
  EXPECT_NEAR(s.normal.z, 1, 1e-6);
}

TEST(ProxyModelTest, SlidesAlongTheSurface) {
  auto floor = testing::Floor(0);
  ProxyModel m(1.0, 0.05);
  m.Reset(floor.get(), {0, 0, 1});
  for (int i = 0; i <= 100; ++i) m.Update(floor.get(), {0.05 * i, 0, -1}, kDt);
  EXPECT_NEAR(m.state().proxy.x, 5.0, 0.01);
  EXPECT_GE(floor->Phi(m.state().proxy), 0);
}

TEST(ProxyModelTest, NullSnapshotFreesTheProxy) {
  auto floor = testing::Floor(0);
  ProxyModel m(1.0, 0.05);
  m.Reset(floor.get(), {0, 0, 1});
  m.Update(floor.get(), {0, 0, -2}, kDt);
  ASSERT_TRUE(m.state().contact);
  const ProxyState& s = m.Update(nullptr, {0, 0, -2}, kDt);
  EXPECT_FALSE(s.contact);
  EXPECT_EQ(s.force.Length(), 0);
}

TEST(ProxyModelTest, IgnoresNonFiniteDevice) {
  auto floor = testing::Floor(0);
  ProxyModel m(1.0, 0.05);
  m.Reset(floor.get(), {0, 0, 1});
  const Vec3 before = m.Update(floor.get(), {0, 0, -2}, kDt).force;
  const ProxyState& s = m.Update(floor.get(), {NAN, 0, 0}, kDt);
  EXPECT_EQ(s.force, before);
}

}  // namespace
}  // namespace sculpt::haptics
