#include "sculpt/hetero/inverse_map.h"

#include <gtest/gtest.h>

#include <random>

#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/grid_editor.h"

namespace sculpt::hetero {
namespace {

// A quarter ring of two sectors with a radial material gradient (3 materials).
CompositeModel RingModel() {
  CompositeModel m(3);
  ValidityChecker checker;
  for (int s = 0; s < 2; ++s) {
    auto h = *LibraryRingSector(1, 2, 45.0 * s, 45.0 * (s + 1), 0, 1, std::vector<double>{1, 0, 0});
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        for (int k = 0; k < 4; ++k) {
          const double t = i / 3.0;
          h.set_fractions(Hyperpatch::Index(i, j, k), std::vector<double>{1 - t, t * 0.5, t * 0.5});
        }
    EXPECT_TRUE(AddCellChecked(&m, &checker, h, CellSource::kLibrary)->added);
  }
  return m;
}

TEST(InverseMapTest, FindsTheParametersOfRandomInteriorPoints) {
  const CompositeModel m = RingModel();
  const InverseMap map(m);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> unit(0.02, 0.98);
  for (int n = 0; n < 200; ++n) {
    const int cell = n % 2;
    const Hyperpatch h = m.CellPatch(cell);
    const Vec3 uvw{unit(rng), unit(rng), unit(rng)};
    const Vec3 x = h.Evaluate(uvw.x, uvw.y, uvw.z);
    const auto loc = map.Locate(x);
    ASSERT_TRUE(loc.has_value()) << n;
    EXPECT_EQ(loc->cell, cell);
    EXPECT_NEAR((loc->uvw - uvw).Length(), 0.0, 1e-7);
    const Fractions a = h.Materials(uvw.x, uvw.y, uvw.z);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(loc->materials[k], a[k], 1e-7);
    EXPECT_TRUE(ValidateFractions("a", loc->materials, 3).ok());
  }
}

TEST(InverseMapTest, PointsOnTheInternalFaceTakeTheLowerIndexCell) {
  // (5.4) and §7.4.1: on the face shared by cells 0 and 1 (the 45° plane), cell 0 wins.
  const CompositeModel m = RingModel();
  const InverseMap map(m);
  const Vec3 x = m.CellPatch(1).Evaluate(0.5, 0.0, 0.5);
  const auto loc = map.Locate(x);
  ASSERT_TRUE(loc.has_value());
  EXPECT_EQ(loc->cell, 0);
  EXPECT_NEAR(loc->uvw.y, 1.0, 1e-9);
}

TEST(InverseMapTest, PointsOutsideAreNotFound) {
  const InverseMap map(RingModel());
  EXPECT_FALSE(map.Locate({0.2, 0.2, 0.5}).has_value());  // inside the ring's hole
  EXPECT_FALSE(map.Locate({1.5, 0.5, 1.5}).has_value());  // above it
  EXPECT_FALSE(map.Locate({std::nan(""), 0, 0}).has_value());
  std::vector<double> out(3);
  EXPECT_FALSE(map.MaterialsAt({5, 5, 5}, out));
}

}  // namespace
}  // namespace sculpt::hetero

namespace sculpt::hetero {
namespace {

TEST(InverseMapTest, HintedLookupGivesTheSameAnswers) {
  const CompositeModel m = RingModel();
  const InverseMap map(m);
  std::optional<Location> prev;
  int found = 0;
  for (double x = 0.05; x < 2.0; x += 0.1)
    for (double y = 0.05; y < 2.0; y += 0.1)
      for (double z = 0.05; z < 1.0; z += 0.1) {
        const auto plain = map.Locate({x, y, z});
        const auto hinted = map.Locate({x, y, z}, prev ? &*prev : nullptr);
        ASSERT_EQ(plain.has_value(), hinted.has_value()) << x << " " << y << " " << z;
        if (!plain) continue;
        ++found;
        EXPECT_EQ(plain->cell, hinted->cell);
        EXPECT_NEAR((plain->uvw - hinted->uvw).Length(), 0, 1e-8);
        prev = hinted;
      }
  EXPECT_GT(found, 100);
}

}  // namespace
}  // namespace sculpt::hetero
