#include "sculpt/haptics/sculpture_snapshot.h"

#include <gtest/gtest.h>

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
