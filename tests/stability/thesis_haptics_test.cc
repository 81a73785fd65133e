// Seed 000 §6.1 (digest §3.1, claims 2-7): the thesis's haptic scene in a one-voxel slab.
// Circle tool r = 15 from (50, 73) towards (50, 20), 7 units per step; rectangle material
// centred at (50, 20), 50 x 30; kappa = 1; h = 0.5 (the thesis's grid of §6.2).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sculpt/haptics/penalty.h"
#include "sculpt/levelset/thesis_repro.h"
#include "sculpt/levelset/tool.h"

namespace sculpt::haptics {
namespace {

using levelset::thesis::GridSpec;
using levelset::thesis::MaterialField;
using levelset::thesis::Shape2D;

class ThesisHaptics : public ::testing::Test {
 protected:
  void SetUp() override {
    field_ = MaterialField(Shape2D::Rectangle({50, 20}, 25, 15), GridSpec{});
    sdf_ = DenseSdf{&field_, {0, 0, 0}, GridSpec{}.h()};
  }
  // Moves the tool 7 units per step until some sample collides; returns the steps taken.
  int StepsToContact(int k, Vec3* centre) const {
    Vec3 c{50, 73, 0};
    const Vec3 dir{0, -1, 0};
    for (int step = 0; step < 20; ++step) {
      if (ComputePenaltyForce(sdf_, CircleSamples(c, 15, k), 1.0).colliding > 0) {
        *centre = c;
        return step;
      }
      c += dir * 7.0;
    }
    return -1;
  }
  levelset::DenseField field_;
  DenseSdf sdf_;
};

// Claim 2: first contact after 4 steps, centre (50, 45), penetration 5.
TEST_F(ThesisHaptics, FirstContactAfterFourSteps) {
  Vec3 c;
  EXPECT_EQ(StepsToContact(50, &c), 4);
  EXPECT_NEAR(c.y, 45.0, 1e-9);
}

// Claims 3, 5, 7: summed and averaged force for 25, 50, 100 samples (thesis: 22/44/88 and
// 3.14/3.147/3.26; tolerance 0.05 on the average as the digest suggests, 1 on the sum).
TEST_F(ThesisHaptics, SummedAndAveragedForcesMatchTheThesis) {
  struct Row {
    int k, colliding;
    double sum, average;
  };
  for (const Row& r : {Row{25, 7, 22, 3.14}, Row{50, 14, 44, 3.147}, Row{100, 27, 88, 3.26}}) {
    Vec3 c;
    ASSERT_EQ(StepsToContact(r.k, &c), 4) << r.k;
    const PenaltyForce f = ComputePenaltyForce(sdf_, CircleSamples(c, 15, r.k), 1.0);
    EXPECT_EQ(f.colliding, r.colliding) << r.k;
    EXPECT_NEAR(f.sum.Length(), r.sum, 1.0) << r.k;
    EXPECT_NEAR(f.average.Length(), r.average, 0.05) << r.k;
    // Claim 6: the force pushes the tool out of the material, here straight up.
    EXPECT_GT(f.average.y, 0.99 * f.average.Length()) << r.k;
  }
}

// Claim 4: the force is linear in kappa (thesis: 22 / 1.6 at 0.5, 66 / 5 at 1.5).
TEST_F(ThesisHaptics, ForceIsLinearInKappa) {
  Vec3 c;
  ASSERT_EQ(StepsToContact(50, &c), 4);
  const auto samples = CircleSamples(c, 15, 50);
  const PenaltyForce one = ComputePenaltyForce(sdf_, samples, 1.0);
  for (double kappa : {0.5, 1.5}) {
    const PenaltyForce f = ComputePenaltyForce(sdf_, samples, kappa);
    EXPECT_NEAR(f.sum.Length(), kappa * one.sum.Length(), 1e-9);
    EXPECT_NEAR(f.average.Length(), kappa * one.average.Length(), 1e-9);
  }
}

TEST_F(ThesisHaptics, NoContactMeansNoForce) {
  const PenaltyForce f = ComputePenaltyForce(sdf_, CircleSamples({50, 73, 0}, 15, 50), 1.0);
  EXPECT_EQ(f.colliding, 0);
  EXPECT_EQ(f.sum.Length(), 0.0);
}

// The same experiment in 3D (issue "Haptic rendering", thesis 6.1 in 3D): a sphere tool of
// radius 5 pressed 2 units into a sphere of radius 20 (band half-width 8, so phi is not clamped
// at the tool's samples). The averaged force does not depend on the sample count (within 5%),
// and it points along the outward normal at the contact (within 2 degrees). Below ~200
// samples only a dozen fall in the contact cap and their mean depth still wanders by ~15%.
TEST(ThesisHaptics3D, AveragedForceIsSamplingInvariantAndNormal) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 8;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 20.0);
  ASSERT_TRUE(s.ok());
  const SculptureSdf sdf(*s);
  const Vec3 normal = Vec3{1, 2, 3} / Vec3{1, 2, 3}.Length();
  const Vec3 centre = normal * (20.0 + 5.0 - 2.0);
  double reference = 0;
  for (int k : {200, 400, 800, 1600}) {
    const auto samples = levelset::ToolSurfaceSamples(levelset::ToolShape::Sphere(centre, 5), k);
    const PenaltyForce f = ComputePenaltyForce(sdf, samples, 1.0);
    ASSERT_GT(f.colliding, 0) << k;
    const double m = f.average.Length();
    if (reference == 0) reference = m;
    EXPECT_NEAR(m, reference, 0.05 * reference) << k << " samples";
    const double angle = std::acos(std::clamp(f.average.Dot(normal) / m, -1.0, 1.0));
    EXPECT_LT(angle * 180 / M_PI, 2.0) << k << " samples";
  }
}

}  // namespace
}  // namespace sculpt::haptics

namespace sculpt::haptics {
namespace {

// The same 3D scene with the area-weighted average (ComputeAreaWeightedPenaltyForce: each
// sample weighted by its share of the tool surface inside the material). It is the mean depth
// over the contact area, so it no longer depends on how many samples happen to fall in the
// contact cap, and it holds the 5% from far fewer samples than the plain mean.
// Measured against 3200 samples: 64 -> +4.2%, 96 -> +2.5%, 128 -> +1.9%, 200 -> +1.2%,
// 400 -> +0.4% (converging from above); below 64 it does not hold (32 -> +9%, 16 -> +19%).
// The plain mean of the test above wanders instead: -7.6% at 64, -4.1% at 200, -1.4% at 1600.
TEST(ThesisHaptics3D, AreaWeightedAverageIsSamplingInvariantFromFewSamples) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 8;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 20.0);
  ASSERT_TRUE(s.ok());
  const SculptureSdf sdf(*s);
  const Vec3 normal = Vec3{1, 2, 3} / Vec3{1, 2, 3}.Length();
  const Vec3 centre = normal * (20.0 + 5.0 - 2.0);
  const levelset::ToolShape tool = levelset::ToolShape::Sphere(centre, 5);
  auto weighted = [&](int k) {
    const auto samples = levelset::ToolSurfaceSamples(tool, k);
    return ComputeAreaWeightedPenaltyForce(sdf, samples, 4 * M_PI * 25 / samples.size(), 1.0,
                                           centre);
  };
  const double reference = weighted(3200).average.Length();
  for (int k : {64, 96, 128, 200, 400, 800, 1600}) {
    const PenaltyForce f = weighted(k);
    const double m = f.average.Length();
    EXPECT_NEAR(m, reference, 0.05 * reference) << k << " samples";
    const double angle = std::acos(std::clamp(f.average.Dot(normal) / m, -1.0, 1.0));
    EXPECT_LT(angle * 180 / M_PI, 2.0) << k << " samples";
  }
}

}  // namespace
}  // namespace sculpt::haptics
