// Seed 000 §6.1 (digest §3.1, claims 2-7): the thesis's haptic scene in a one-voxel slab.
// Circle tool r = 15 from (50, 73) towards (50, 20), 7 units per step; rectangle material
// centred at (50, 20), 50 x 30; kappa = 1; h = 0.5 (the thesis's grid of §6.2).
#include <gtest/gtest.h>

#include <cmath>

#include "sculpt/haptics/penalty.h"
#include "sculpt/levelset/thesis_repro.h"

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

}  // namespace
}  // namespace sculpt::haptics
