#include "sculpt/haptics/contact.h"

#include <gtest/gtest.h>

#include <limits>

#include "unit/haptics/field_helpers.h"

namespace sculpt::haptics {
namespace {

using testing::OwnedDenseSdf;

// A wall one voxel thick: phi = |x - 0.3| - 0.5 (h = 1), so only x in (-0.2, 0.8) is inside and
// no node lies deeper than 0.3 (the thinnest thing a grid holds).
std::shared_ptr<const OwnedDenseSdf> ThinWall() {
  return std::make_shared<const OwnedDenseSdf>(
      Vec3{-30, -5, -5}, 1.0, levelset::Int3{61, 11, 11},
      [](const Vec3& p) { return std::abs(p.x - 0.3) - 0.5; });
}

class ContactTest : public ::testing::Test {
 protected:
  std::shared_ptr<const OwnedDenseSdf> wall_ = ThinWall();
};

TEST_F(ContactTest, FastSegmentThroughThinWallIsDetected) {
  // 20 voxels in one tick across a wall one voxel thick: the endpoints are both outside.
  const Vec3 a{-15, 0.2, 0}, b{5, 0.2, 0};
  ASSERT_GT(wall_->Phi(a), 0);
  ASSERT_GT(wall_->Phi(b), 0);
  const SegmentHit h = SweepSegment(*wall_, a, b);
  ASSERT_TRUE(h.hit);
  // The wall's near face is at x = -0.2: t = (15 - 0.2) / 20.
  EXPECT_NEAR(h.time, 14.8 / 20, 0.01);
  EXPECT_LE(h.free_time, h.time);
  EXPECT_GT(wall_->Phi(a + (b - a) * h.free_time), 0);
  EXPECT_LE(wall_->Phi(a + (b - a) * h.time), 0);
}

TEST_F(ContactTest, ClearSegmentHasNoHit) {
  const SegmentHit h = SweepSegment(*wall_, {-15, 0, 0}, {-2, 0, 0});
  EXPECT_FALSE(h.hit);
}

TEST_F(ContactTest, StartInsideHitsAtTimeZero) {
  const SegmentHit h = SweepSegment(*wall_, {0.3, 0, 0}, {5, 0, 0});
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.time, 0);
}

TEST_F(ContactTest, IsoOffsetStopsEarlier) {
  const SegmentHit h = SweepSegment(*wall_, {-15, 0, 0}, {5, 0, 0}, 2.0);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.time, 12.8 / 20, 0.01);
}

TEST_F(ContactTest, RejectsNanSegment) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(SweepSegment(*wall_, {nan, 0, 0}, {5, 0, 0}).hit);
}

TEST_F(ContactTest, FirstContactOfToolIsTheEarliestSample) {
  // Two samples side by side moving 20 voxels; the one starting nearer touches first.
  const std::vector<Vec3> from{{-15, 0, 0}, {-12, 1, 0}};
  const std::vector<Vec3> to{{5, 0, 0}, {8, 1, 0}};
  const SweptContact c = FindFirstContact(*wall_, from, to);
  ASSERT_TRUE(c.hit);
  EXPECT_EQ(c.sample, 1);
  EXPECT_NEAR(c.time, 11.8 / 20, 0.01);
  EXPECT_NEAR(c.point.x, -0.2, 0.02);
}

TEST_F(ContactTest, MismatchedSampleCountsReportNothing) {
  EXPECT_FALSE(FindFirstContact(*wall_, {{-15, 0, 0}}, {}).hit);
}

}  // namespace
}  // namespace sculpt::haptics
