// A snapshot swap that costs what any tick costs (issue 16): a windowed snapshot made with its
// predecessor knows how far phi moved around the tool (SdfSampler::ChangeSince), and the renderer
// keeps its distance bounds through the swap instead of reading every sample again. Counted, not
// timed: lookups per tick, window reads against tree fallbacks, forces bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>
#include <random>

#include "sculpt/haptics/haptic_renderer.h"
#include "sculpt/haptics/sculpture_snapshot.h"
#include "sculpt/levelset/edit.h"

namespace sculpt::haptics {
namespace {

constexpr double kDt = 1e-3;
constexpr double kSphere = 30;
constexpr double kTool = 4;
constexpr double kWindow = kTool + 6;  // as the bench and `sculpt play` size it
constexpr int kSwapEvery = 8;          // 120 Hz snapshots at 1 kHz

std::shared_ptr<const levelset::Sculpture> Sphere() {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, kSphere);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::make_shared<const levelset::Sculpture>(std::move(s).value());
}

// A copy of `s` with a small dent cut at `where`.
std::shared_ptr<const levelset::Sculpture> Dented(const levelset::Sculpture& s, const Vec3& where,
                                                  double radius) {
  auto copy = std::make_shared<levelset::Sculpture>(s.Clone());
  levelset::EditRequest cut;
  cut.kind = levelset::EditKind::kSubtract;
  cut.tool = levelset::ToolShape::Sphere(where, radius);
  EXPECT_TRUE(levelset::ApplyEdit(*copy, cut, levelset::EditSettings{}).ok());
  return copy;
}

// The bench's path: the tool centre sliding over the sphere at 20 voxels/s, 1 voxel deep.
Vec3 PathAt(double t) {
  const double r = kSphere + kTool - 1;
  const double a = 20 * t / r;
  return Vec3{r * std::cos(a), r * std::sin(a) * 0.6, r * std::sin(a) * 0.8};
}

HapticSettings Settings(ForceModel model, int samples) {
  HapticSettings s;
  s.model = model;
  s.tool_radius = kTool;
  s.tool_samples = samples;
  s.proxy_radius = model == ForceModel::kProxy ? kTool : 0.0;
  s.blend_ms = 0;  // forces compared bit for bit: no blend across swaps
  s.tick_budget_us = 0;
  return s;
}

TEST(SwapCarryTest, ChangeSinceIsZeroForTheSameSculptureAndUnknownWithoutAPredecessor) {
  const auto s = Sphere();
  const SculptureSnapshot a(s), b(s, PathAt(0), kWindow);
  double bound = -1;
  Vec3 lo, hi;
  ASSERT_TRUE(b.ChangeSince(a, &bound, &lo, &hi));
  EXPECT_EQ(bound, 0);
  EXPECT_TRUE(std::isinf(lo.x) && std::isinf(hi.x));
  // A separate copy with no predecessor given, or given another one: nothing known.
  const auto copy = std::make_shared<const levelset::Sculpture>(s->Clone());
  const SculptureSnapshot c(copy, PathAt(0), kWindow), d(copy, PathAt(0), kWindow, &c);
  EXPECT_FALSE(c.ChangeSince(b, &bound, &lo, &hi));
  EXPECT_FALSE(d.ChangeSince(b, &bound, &lo, &hi)) << "made against c, not b";
  EXPECT_FALSE(SculptureSnapshot(copy).ChangeSince(b, &bound, &lo, &hi))
      << "a tree snapshot of another copy";
}

// Across an edit near the tool, the bound holds at every point of its box, is not zero, and the
// box is the two windows' overlap (it holds the tool and the band around it).
TEST(SwapCarryTest, ChangeBoundCoversAnEditInTheWindowOverlap) {
  const auto s = Sphere();
  const Vec3 at = PathAt(0);
  const auto dented = Dented(*s, Vec3{kSphere + 0.5, 1.5, 0}, 1.5);
  const SculptureSnapshot before(s, at, kWindow);
  const SculptureSnapshot after(dented, at + Vec3{0, 0.7, 0.2}, kWindow, &before);
  double bound = -1;
  Vec3 lo, hi;
  ASSERT_TRUE(after.ChangeSince(before, &bound, &lo, &hi));
  EXPECT_GT(bound, 0.5);
  for (const Vec3& p : {at, at + Vec3{kTool, kTool, kTool}, at - Vec3{kTool, kTool, kTool}}) {
    EXPECT_TRUE(p.x > lo.x && p.y > lo.y && p.z > lo.z && p.x < hi.x && p.y < hi.y && p.z < hi.z);
  }
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double largest = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 p{lo.x + u(rng) * (hi.x - lo.x), lo.y + u(rng) * (hi.y - lo.y),
                 lo.z + u(rng) * (hi.z - lo.z)};
    const double moved = std::abs(after.Phi(p) - before.Phi(p));
    ASSERT_LE(moved, bound) << i;
    largest = std::max(largest, moved);
  }
  EXPECT_GT(largest, 0.5 * bound) << "the bound is the change, not a loose guess";
}

struct RunCounts {
  double normal_mean = 0;
  uint64_t normal_max = 0, swap_max = 0, tree = 0;
  double swap_mean = 0;
};

// Feeds `r` a new windowed snapshot every kSwapEvery ticks (made by `make(i, previous)`) along
// the path, keeping the last three as the publisher does; counts lookups per tick kind.
template <typename Make>
RunCounts RunPath(HapticRenderer* r, int ticks, const Make& make, std::vector<Vec3>* forces) {
  RunCounts c;
  int normal = 0, swaps = 0;
  std::shared_ptr<const SculptureSnapshot> snap;
  std::deque<std::shared_ptr<const SculptureSnapshot>> retained;
  for (int i = 0; i < ticks; ++i) {
    const double t = i * kDt;
    const bool swapped = i % kSwapEvery == 0;
    if (swapped) {
      snap = make(i, snap);
      retained.push_back(snap);
      if (retained.size() > 3) retained.pop_front();
    }
    const auto n0 = SculptureSnapshot::ThreadLookupCounts();
    forces->push_back(r->Tick(snap, DeviceSample{t, PathAt(t), {}}).model_force);
    const auto n = SculptureSnapshot::ThreadLookupCounts() - n0;
    c.tree += n.tree();
    if (i < kSwapEvery) continue;  // the first snapshot knows nothing yet
    if (swapped) {
      c.swap_mean += n.total();
      c.swap_max = std::max(c.swap_max, n.total());
      ++swaps;
    } else {
      c.normal_mean += n.total();
      c.normal_max = std::max(c.normal_max, n.total());
      ++normal;
    }
  }
  c.normal_mean /= normal;
  c.swap_mean /= swaps;
  return c;
}

// The bench's path with a new copy of the sphere every 8 ticks: every lookup reads the window
// (none falls back to the tree), the tick after a swap does no more lookups than the others,
// and the force is the same bits as on one snapshot that never changes.
TEST(SwapCarryTest, SwapTickDoesTheLookupsOfAnyTickAndTheWindowNeverFallsBack) {
  const auto s = Sphere();
  const auto copy = std::make_shared<const levelset::Sculpture>(s->Clone());
  for (ForceModel model : {ForceModel::kPenalty, ForceModel::kProxy}) {
    for (int samples : {128, 512}) {
      auto carried = HapticRenderer::Create(Settings(model, samples));
      auto still = HapticRenderer::Create(Settings(model, samples));
      ASSERT_TRUE(carried.ok() && still.ok());
      std::vector<Vec3> f_carried, f_still;
      const RunCounts c = RunPath(&*carried, 400, [&](int i, const auto& previous) {
        return std::make_shared<const SculptureSnapshot>((i / kSwapEvery) % 2 ? copy : s,
                                                         PathAt(i * kDt), kWindow, previous.get());
      }, &f_carried);
      const auto one = std::make_shared<const SculptureSnapshot>(s, PathAt(0), 3 * kWindow);
      RunPath(&*still, 400, [&](int, const auto&) { return one; }, &f_still);
      const char* name = ForceModelName(model);
      EXPECT_EQ(c.tree, 0u) << name << " " << samples;
      EXPECT_EQ(carried->swaps(), 49u);
      EXPECT_EQ(carried->swaps_carried(), 49u);
      EXPECT_LE(c.swap_max, c.normal_max) << name << " " << samples;
      EXPECT_LE(c.swap_mean, 1.2 * c.normal_mean) << name << " " << samples;
      EXPECT_LT(c.swap_max, static_cast<uint64_t>(samples)) << "not every sample read again";
      ASSERT_EQ(f_carried.size(), f_still.size());
      for (size_t i = 0; i < f_carried.size(); ++i) {
        ASSERT_EQ(f_carried[i], f_still[i]) << name << " " << samples << " tick " << i;
      }
    }
  }
}

// A sculptor cuts a dent ahead of the tool on every new copy: the bounds carried through each
// swap are lowered by the change, the samples near the dent are read again, and the force is
// the same bits as a renderer's that forgets everything at each swap, with fewer lookups.
TEST(SwapCarryTest, EditsUnderTheToolGiveTheForceOfARendererThatForgets) {
  std::vector<std::shared_ptr<const levelset::Sculpture>> copies{Sphere()};
  for (int k = 1; k < 25; ++k) {
    const Vec3 ahead = PathAt((k * kSwapEvery + 40) * kDt);
    const Vec3 on_surface = ahead * (kSphere / ahead.Length());
    copies.push_back(Dented(*copies.back(), on_surface, 0.8 + 0.05 * k));
  }
  auto carried = HapticRenderer::Create(Settings(ForceModel::kPenalty, 128));
  auto forgets = HapticRenderer::Create(Settings(ForceModel::kPenalty, 128));
  ASSERT_TRUE(carried.ok() && forgets.ok());
  std::vector<Vec3> f_carried, f_forgets;
  const int ticks = kSwapEvery * static_cast<int>(copies.size());
  const RunCounts c = RunPath(&*carried, ticks, [&](int i, const auto& previous) {
    return std::make_shared<const SculptureSnapshot>(copies[i / kSwapEvery], PathAt(i * kDt),
                                                     kWindow, previous.get());
  }, &f_carried);
  const RunCounts f = RunPath(&*forgets, ticks, [&](int i, const auto&) {
    return std::make_shared<const SculptureSnapshot>(copies[i / kSwapEvery], PathAt(i * kDt),
                                                     kWindow, nullptr);
  }, &f_forgets);
  EXPECT_EQ(carried->swaps_carried(), carried->swaps());
  EXPECT_EQ(forgets->swaps_carried(), 0u);
  EXPECT_EQ(c.tree, 0u);
  EXPECT_LT(c.swap_mean, 0.5 * f.swap_mean);
  ASSERT_EQ(f_carried.size(), f_forgets.size());
  bool dent_felt = false;
  for (size_t i = 0; i < f_carried.size(); ++i) {
    ASSERT_EQ(f_carried[i], f_forgets[i]) << "tick " << i;
    dent_felt = dent_felt || f_carried[i] != f_carried[std::min(i, size_t{8})];
  }
  EXPECT_TRUE(dent_felt);
}

// A binding budget (16 of 128 samples a tick) across carried swaps: the force stays within a
// few percent of the full renderer's, as on one snapshot (TickBudgetTest).
TEST(SwapCarryTest, BudgetedTicksAcrossCarriedSwapsStayCloseToTheFullForce) {
  const auto s = Sphere();
  const auto copy = std::make_shared<const levelset::Sculpture>(s->Clone());
  HapticSettings cut = Settings(ForceModel::kPenalty, 128);
  cut.tick_budget_samples = 16;
  auto full = HapticRenderer::Create(Settings(ForceModel::kPenalty, 128));
  auto budgeted = HapticRenderer::Create(cut);
  ASSERT_TRUE(full.ok() && budgeted.ok());
  const auto make = [&](int i, const auto& previous) {
    return std::make_shared<const SculptureSnapshot>((i / kSwapEvery) % 2 ? copy : s,
                                                     PathAt(i * kDt), kWindow, previous.get());
  };
  std::vector<Vec3> f_full, f_cut;
  RunPath(&*full, 600, make, &f_full);
  RunPath(&*budgeted, 600, make, &f_cut);
  double max_rel_err = 0;
  for (size_t i = 40; i < f_full.size(); ++i) {
    max_rel_err = std::max(max_rel_err, (f_cut[i] - f_full[i]).Length() / f_full[i].Length());
  }
  EXPECT_LT(max_rel_err, 0.05);
  EXPECT_EQ(budgeted->swaps_carried(), budgeted->swaps());
}

}  // namespace
}  // namespace sculpt::haptics
