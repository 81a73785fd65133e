#include "sculpt/haptics/sculpture_snapshot.h"

#include <gtest/gtest.h>

#include <random>
#include <thread>

namespace sculpt::haptics {
namespace {

TEST(SculptureSnapshotTest, MatchesTheSculptureSampler) {
  levelset::SculptureOptions o;
  o.voxel_size = 0.5;
  auto s = levelset::Sculpture::MakeSphere(o, {1, 2, 3}, 8.0);
  ASSERT_TRUE(s.ok());
  const SculptureSdf reference(*s);
  const SculptureSnapshot snap(*s);
  EXPECT_EQ(snap.cell_size(), 0.5);
  for (const Vec3& p : {Vec3{9.1, 2, 3}, Vec3{1, 9.7, 3.3}, Vec3{1.2, 2.1, -4.6}, Vec3{1, 2, 3}}) {
    EXPECT_NEAR(snap.Phi(p), reference.Phi(p), 1e-5) << p.x;
    const Vec3 g = snap.Gradient(p), r = reference.Gradient(p);
    EXPECT_NEAR((g - r).Length(), 0, 1e-5) << p.x;
  }
}

// The dense window holds the tree's own values: phi and the gradient read through it are the
// same bits as through the tree, inside the window, across its border and outside it.
TEST(SculptureSnapshotTest, DenseWindowGivesTheTreesBits) {
  levelset::SculptureOptions o;
  o.voxel_size = 0.5;
  auto s = levelset::Sculpture::MakeSphere(o, {1, 2, 3}, 8.0);
  ASSERT_TRUE(s.ok());
  auto shared = std::make_shared<const levelset::Sculpture>(std::move(s).value());
  const Vec3 centre{9, 2, 3};  // on the surface
  const SculptureSnapshot tree(shared), window(shared, centre, 3.0);
  EXPECT_EQ(tree.window_values(), 0u);
  EXPECT_GT(window.window_values(), 12u * 12 * 12);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-5.0, 5.0);  // past the 3-unit window
  const auto before = SculptureSnapshot::ThreadLookupCounts();
  for (int i = 0; i < 2000; ++i) {
    const Vec3 p = centre + Vec3{u(rng), u(rng), u(rng)};
    ASSERT_EQ(window.Phi(p), tree.Phi(p)) << i;
    ASSERT_EQ(window.Gradient(p), tree.Gradient(p)) << i;
    double phi;
    Vec3 g;
    window.PhiAndGradient(p, &phi, &g);
    ASSERT_EQ(phi, tree.Phi(p)) << i;
    ASSERT_EQ(g, tree.Gradient(p)) << i;
  }
  // Both of the window's paths were compared: the 8 corners, and the 8 corners with their
  // stored differences.
  const auto read = SculptureSnapshot::ThreadLookupCounts() - before;
  EXPECT_GT(read.window_phi, 100u);
  EXPECT_GT(read.window_stencil, 100u);
  EXPECT_EQ(SculptureSnapshot(shared, centre, 0).window_values(), 0u);
  EXPECT_EQ(SculptureSnapshot(shared, Vec3{NAN, 0, 0}, 3).window_values(), 0u);
}

// The stencil's gradient (the corner differences interpolated with shared weights) is the
// central difference of the snapshot's own trilinear phi one voxel either side, up to rounding:
// the function whose continuity across cell faces the hard-case tests rely on.
TEST(SculptureSnapshotTest, StencilGradientIsTheCentralDifferenceOfPhi) {
  levelset::SculptureOptions o;
  o.voxel_size = 0.5;
  auto s = levelset::Sculpture::MakeSphere(o, {1, 2, 3}, 8.0);
  ASSERT_TRUE(s.ok());
  auto shared = std::make_shared<const levelset::Sculpture>(std::move(s).value());
  const Vec3 centre{9, 2, 3};
  const SculptureSnapshot tree(shared), window(shared, centre, 3.0);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  const double h = 0.5;
  for (int i = 0; i < 2000; ++i) {
    const Vec3 p = centre + Vec3{u(rng), u(rng), u(rng)};
    const Vec3 expected{(tree.Phi(p + Vec3{h, 0, 0}) - tree.Phi(p - Vec3{h, 0, 0})) / (2 * h),
                        (tree.Phi(p + Vec3{0, h, 0}) - tree.Phi(p - Vec3{0, h, 0})) / (2 * h),
                        (tree.Phi(p + Vec3{0, 0, h}) - tree.Phi(p - Vec3{0, 0, h})) / (2 * h)};
    for (const SculptureSnapshot* snap : {&tree, &window}) {
      const Vec3 g = snap->Gradient(p);
      ASSERT_NEAR((g - expected).Length(), 0, 1e-9) << i;
    }
  }
}

TEST(SculptureSnapshotTest, IdsAreUniqueAndTheCopyIsIndependent) {
  levelset::SculptureOptions o;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 10.0);
  ASSERT_TRUE(s.ok());
  SculptureSnapshot a(*s), b(*s);
  EXPECT_NE(a.id(), b.id());
  const double before = a.Phi({10, 0, 0});
  auto smaller = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 5.0);
  ASSERT_TRUE(smaller.ok());
  *s = std::move(smaller).value();
  EXPECT_EQ(a.Phi({10, 0, 0}), before);
}

TEST(SculptureSnapshotTest, ConcurrentReadersAgree) {
  levelset::SculptureOptions o;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 10.0);
  ASSERT_TRUE(s.ok());
  const SculptureSnapshot snap(*s);
  double sums[2] = {0, 0};
  auto work = [&](int i) {
    for (int k = 0; k < 2000; ++k) sums[i] += snap.Phi({k * 0.01, 0.5, 0.25});
  };
  std::thread t0(work, 0), t1(work, 1);
  t0.join();
  t1.join();
  EXPECT_EQ(sums[0], sums[1]);
}

}  // namespace
}  // namespace sculpt::haptics
