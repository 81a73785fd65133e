// The haptic tick's cost controls (issue 16): far samples skipped by a distance bound without
// changing the force, and the per-tick budget: a tick that reaches it stops within it (counted,
// not timed), resumes on the next tick, and the force stays continuous and close to the full one.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <set>

#include "sculpt/haptics/haptic_device.h"
#include "sculpt/haptics/haptic_renderer.h"
#include "sculpt/haptics/sculpture_snapshot.h"
#include "unit/haptics/field_helpers.h"

namespace sculpt::haptics {
namespace {

constexpr double kDt = 1e-3;
constexpr double kSphere = 30;
constexpr double kTool = 4;

// A field lookup counter around another sampler: every Phi, Gradient or PhiAndGradient call
// advances `lookups` (and the fake clock reads it as microseconds).
class CountingSdf : public SdfSampler {
 public:
  explicit CountingSdf(std::shared_ptr<const SdfSampler> inner) : inner_(std::move(inner)) {}
  double Phi(const Vec3& p) const override {
    ++lookups;
    return inner_->Phi(p);
  }
  Vec3 Gradient(const Vec3& p) const override {
    ++lookups;
    return inner_->Gradient(p);
  }
  void PhiAndGradient(const Vec3& p, double* phi, Vec3* g) const override {
    ++lookups;
    inner_->PhiAndGradient(p, phi, g);
  }
  double cell_size() const override { return inner_->cell_size(); }
  mutable std::atomic<uint64_t> lookups{0};

 private:
  std::shared_ptr<const SdfSampler> inner_;
};

// A clock that reads one microsecond per field lookup: a tick's "time" is its lookup count.
class LookupClock : public TickClock {
 public:
  explicit LookupClock(const CountingSdf* sdf) : sdf_(sdf) {}
  double NowUs() override { return static_cast<double>(sdf_->lookups.load()); }

 private:
  const CountingSdf* sdf_;
};

std::shared_ptr<const SdfSampler> Sphere() {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, kSphere);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::make_shared<const SculptureSnapshot>(std::move(s).value());
}

// The tool centre sliding over the sphere at 20 voxels/s, `depth` deep.
Vec3 PathAt(double t, double depth = 1) {
  const double r = kSphere + kTool - depth;
  const double a = 20 * t / r;
  return Vec3{r * std::cos(a), r * std::sin(a) * 0.6, r * std::sin(a) * 0.8};
}

HapticSettings Penalty(int samples) {
  HapticSettings s;
  s.model = ForceModel::kPenalty;
  s.tool_radius = kTool;
  s.tool_samples = samples;
  s.blend_ms = 0;
  s.tick_budget_us = 0;
  return s;
}

TEST(TickBudgetTest, SkippingFarSamplesLeavesTheForceAsComputedFromEverySample) {
  const auto sphere = Sphere();
  auto r = HapticRenderer::Create(Penalty(128));
  ASSERT_TRUE(r.ok());
  const double area = 4 * M_PI * kTool * kTool / 128;
  int skipped = 0, evaluated = 0;
  for (int i = 0; i < 300; ++i) {
    const Vec3 c = PathAt(i * kDt);
    const TickOutput& o = r->Tick(sphere, DeviceSample{i * kDt, c, {}});
    std::vector<Vec3> samples;
    for (const Vec3& l : r->tool_samples()) samples.push_back(c + l);
    const PenaltyForce ref =
        ComputeAreaWeightedPenaltyForce(*sphere, samples, area, 1.0, c, Vec3{0, 0, 1});
    ASSERT_GT(ref.average.Length(), 0.1);
    EXPECT_NEAR((o.model_force - ref.average).Length(), 0, 1e-9 * ref.average.Length()) << i;
    EXPECT_EQ(o.colliding, ref.colliding) << i;
    EXPECT_FALSE(o.over_budget);
    EXPECT_EQ(o.samples_known, 128);
    if (i > 0) {
      skipped += o.samples_skipped;
      evaluated += o.samples_evaluated;
    }
  }
  // Most samples are well above the surface: after the first tick they cost no lookup.
  EXPECT_GT(skipped, 2 * evaluated);
}

TEST(TickBudgetTest, SampleBudgetStopsTheTickAndTheNextResumes) {
  const auto sphere = Sphere();
  HapticSettings s = Penalty(128);
  s.tick_budget_samples = 8;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  // The first tick on a snapshot knows nothing: each tick evaluates at most 8 samples, and
  // together the ticks cover the tool without repeating one until all are known.
  int ticks_to_know_all = 0;
  for (int i = 0; i < 40; ++i) {
    const TickOutput& o = r->Tick(sphere, DeviceSample{i * kDt, PathAt(i * kDt), {}});
    EXPECT_LE(o.samples_evaluated, 8) << i;
    if (o.samples_known == 128 && ticks_to_know_all == 0) ticks_to_know_all = i + 1;
    if (i < 15) {
      EXPECT_TRUE(o.over_budget) << i;
      EXPECT_EQ(o.samples_known, 8 * (i + 1)) << i;
    }
    // From the first tick on, the estimate has a force (the first 8 samples are spread over the
    // tool, and at least one of them is in the contact patch).
    if (i >= 2) {
      EXPECT_GT(o.model_force.Dot(PathAt(i * kDt)), 0) << i;
    }
  }
  EXPECT_EQ(ticks_to_know_all, 16);
}

TEST(TickBudgetTest, ForcedOverrunOnAnInjectedClockReturnsWithinTheBudget) {
  const auto floor = std::make_shared<CountingSdf>(testing::Floor(0));
  HapticSettings s = Penalty(512);
  s.tool_radius = 2;
  s.tick_budget_us = 40;  // on the lookup clock: 40 lookups
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  LookupClock clock(floor.get());
  r->set_clock(&clock);
  int over = 0;
  for (int i = 0; i < 200; ++i) {
    const uint64_t before = floor->lookups.load();
    const Vec3 c{0.01 * i, 0, 1.2 - 0.002 * i};  // pressing in while sliding
    const TickOutput& o = r->Tick(floor, DeviceSample{i * kDt, c, {}});
    const uint64_t used = floor->lookups.load() - before;
    // The clock is read every 2 evaluated samples. On a floor a sample takes at most 6 lookups:
    // phi at its end, 4 bisections of its 0.01-long path where it crosses (to 1e-3 of a cell)
    // and phi with the gradient; so a tick ends at most 12 past its budget.
    EXPECT_LE(used, 40u + 12u) << i;
    over += o.over_budget ? 1 : 0;
    EXPECT_GT(o.force.z, 0) << i;
  }
  EXPECT_GT(over, 100);  // the budget binds on most ticks: a forced overrun, not a quiet run
}

// Along the sliding path, a renderer held to 16 of 128 samples a tick (the rest keep their
// terms from up to 8 ticks before) gives a force whose tick-to-tick steps stay as small as the
// full renderer's, and which stays within a few percent of the full force.
TEST(TickBudgetTest, BudgetedForceIsContinuousAndCloseToTheFullForce) {
  const auto sphere = Sphere();
  auto full = HapticRenderer::Create(Penalty(128));
  HapticSettings s = Penalty(128);
  s.tick_budget_samples = 16;
  auto cut = HapticRenderer::Create(s);
  ASSERT_TRUE(full.ok() && cut.ok());
  Vec3 last_full, last_cut;
  double max_step_full = 0, max_step_cut = 0, max_rel_err = 0;
  int over = 0;
  for (int i = 0; i < 1000; ++i) {
    const double t = i * kDt;
    // Pressing from 0.5 to 1.5 deep and back while sliding.
    const Vec3 c = PathAt(t, 1.0 + 0.5 * std::sin(2 * M_PI * t));
    const Vec3 ff = full->Tick(sphere, DeviceSample{t, c, {}}).force;
    const TickOutput& oc = cut->Tick(sphere, DeviceSample{t, c, {}});
    over += oc.over_budget ? 1 : 0;
    if (i >= 20) {
      max_step_full = std::max(max_step_full, (ff - last_full).Length());
      max_step_cut = std::max(max_step_cut, (oc.force - last_cut).Length());
      max_rel_err = std::max(max_rel_err, (oc.force - ff).Length() / ff.Length());
    }
    last_full = ff;
    last_cut = oc.force;
  }
  EXPECT_GT(over, 900);
  EXPECT_GT(max_step_full, 0);
  EXPECT_LE(max_step_cut, 2 * max_step_full);
  EXPECT_LT(max_rel_err, 0.05);
}

// A tool dropped on the floor with the penalty model and a binding budget (32 of 128 samples a
// tick), held by a damped hand: the energy never exceeds what it was dropped with, and
// it comes to rest, as with the full renderer.
TEST(TickBudgetTest, DroppedToolStaysPassiveUnderABindingBudget) {
  const auto floor = testing::Floor(0, 60);
  for (int budget : {0, 32}) {
    HapticSettings s = Penalty(128);
    s.tool_radius = 2;
    s.stiffness = 1;
    s.blend_ms = 4;
    s.tick_budget_samples = budget;
    auto r = HapticRenderer::Create(s);
    ASSERT_TRUE(r.ok());
    SpringMassHand::Params p;
    p.mass = 0.05;
    p.gravity = {0, 0, -9.81};
    p.hand_damping = 0.1;
    SpringMassHand hand(p, {0.3, -0.2, 3.0});  // tool surface 1 unit above the floor
    const double g = 9.81, e0 = p.mass * g * 3.0;
    int over = 0;
    bool touched = false;
    for (int i = 0; i < 10000; ++i) {
      const double t = i * kDt;
      const TickOutput& out = r->Tick(floor, hand.Read(t));
      hand.ApplyForce(out.force, t);
      touched = touched || out.contact;
      over += out.over_budget ? 1 : 0;
      // Kinetic and gravitational energy; the penalty's own potential is >= 0 on top.
      const double e =
          0.5 * p.mass * hand.velocity().LengthSqr() + p.mass * g * hand.position().z;
      ASSERT_LE(e, e0 * 1.001) << "budget " << budget << " tick " << i;
    }
    EXPECT_TRUE(touched);
    if (budget > 0) {
      EXPECT_GT(over, 100) << budget;
    }
    EXPECT_LT(hand.velocity().Length(), 1e-2) << budget;
  }
}

}  // namespace
}  // namespace sculpt::haptics
