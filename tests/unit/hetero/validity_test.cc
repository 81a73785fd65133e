#include "sculpt/hetero/validity.h"

#include <gtest/gtest.h>

#include "sculpt/hetero/composite_model.h"
#include "unit/hetero/hetero_test_util.h"

namespace sculpt::hetero {
namespace {

using testing::BoxPatch;
using testing::RingSectorPatch;
using testing::Rotated;
using testing::SShapedPatch;

Hyperpatch Translated(const Hyperpatch& h, const Vec3& d) {
  Hyperpatch r = h;
  for (int i = 0; i < 64; ++i) r.set_position(i, h.position(i) + d);
  return r;
}

TEST(ValidityTest, BoxCellIsValid) {
  const CellVerdict v = CheckCell(BoxPatch());
  EXPECT_TRUE(v.valid) << v.rejection.ToString();
  EXPECT_EQ(v.frame_index, 0);
  EXPECT_GT(v.min_det_j, 0.0);
}

TEST(ValidityTest, QuarterRingIsValidInSomeFrame) {
  // Digest claim 32: the axis-aligned quarter ring passes requirement 1; the canonical frame sits
  // at 45° to it, so the frame search must find the 45° rotation.
  const CellVerdict v = CheckCell(RingSectorPatch(1, 2, 0, 90));
  EXPECT_TRUE(v.valid) << v.rejection.ToString();
  EXPECT_GT(v.frame_index, 0);
  // Without the search the canonical frame alone refuses it, naming a v span.
  CellCheckOptions strict;
  strict.frame_search = false;
  const CellVerdict s = CheckCell(RingSectorPatch(1, 2, 0, 90), strict);
  EXPECT_EQ(s.rejection.reason, Reason::kSpanNotOrdered);
  EXPECT_EQ(s.rejection.direction, 1);
}

TEST(ValidityTest, InflectedSpanFailsRequirementOne) {
  // Fig. 7.3 / claim 7: x increasing, y decreasing, z with an inflection.
  Hyperpatch h = BoxPatch();
  const double z[4] = {0, 1.5, 0.5, 2};
  for (int q = 0; q < 4; ++q) {
    const int idx = Hyperpatch::Index(q, 1, 1);
    h.set_position(idx, {static_cast<double>(q), 2.0 - 0.5 * q, z[q]});
  }
  const Rejection r = CheckSpansOrdered(h.positions());
  EXPECT_EQ(r.reason, Reason::kSpanNotOrdered);
  EXPECT_EQ(r.direction, 0);
  EXPECT_EQ(r.span, 1 * 4 + 1);
}

TEST(ValidityTest, ReasonCodesPrintWhere) {
  Rejection r;
  r.reason = Reason::kSkinIntersect;
  r.cell = 4;
  r.direction = 2;
  r.skin_a = 0;
  r.skin_b = 1;
  EXPECT_EQ(r.ToString(), "SKIN_INTERSECT cell=4 direction=w skins=(0,1)");
  EXPECT_EQ(r.ToStatus().code(), Status::Code::kFailedPrecondition);
}

TEST(ValidityTest, BoxesSharingAFaceAnEdgeOrACornerDoNotOverlap) {
  const Hyperpatch a = BoxPatch();
  for (const Vec3 d : {Vec3{3, 0, 0}, Vec3{3, 3, 0}, Vec3{3, 3, 3}, Vec3{0, -3, 0}}) {
    EXPECT_FALSE(NetsOverlap(a.positions(), Translated(a, d).positions()))
        << d.x << "," << d.y << "," << d.z;
  }
}

TEST(ValidityTest, CurvedSharedFaceIsNotAnOverlap) {
  // Two ring sectors glued along the curved-free face at 90°, and two stacked in radius along a
  // curved (cylindrical) face.
  EXPECT_FALSE(NetsOverlap(RingSectorPatch(1, 2, 0, 90).positions(),
                           RingSectorPatch(1, 2, 90, 180).positions()));
  EXPECT_FALSE(NetsOverlap(RingSectorPatch(1, 2, 0, 90).positions(),
                           RingSectorPatch(2, 3, 0, 90).positions()));
}

TEST(ValidityTest, DetectsHalfOverlappingBoxes) {
  const Hyperpatch a = BoxPatch();
  EXPECT_TRUE(NetsOverlap(a.positions(), Translated(a, {1.5, 0.5, 0.2}).positions()));
}

TEST(ValidityTest, DetectsContainment) {
  const Hyperpatch big = BoxPatch(9, 9, 9);
  const Hyperpatch small = Translated(BoxPatch(1, 1, 1), {4, 4, 4});
  EXPECT_TRUE(NetsOverlap(big.positions(), small.positions()));
}

TEST(ValidityTest, DisjointBoxesNeedNoSubdivision) {
  // Claim 11.
  int boxes = 0;
  EXPECT_FALSE(NetsOverlap(BoxPatch().positions(), Translated(BoxPatch(), {5, 0, 0}).positions(),
                           {}, &boxes));
  EXPECT_EQ(boxes, 1);
}

TEST(ValidityTest, InterpenetratingFacesWithSharedCornersOverlap) {
  // Same four corners and edges on x=3, but A's face interior bulges 0.3 into B (§10.6-8).
  Hyperpatch a = BoxPatch();
  for (int j = 1; j <= 2; ++j)
    for (int k = 1; k <= 2; ++k)
      for (int i = 2; i <= 3; ++i) {
        const int idx = Hyperpatch::Index(i, j, k);
        a.set_position(idx, a.position(idx) + Vec3{0.3, 0, 0});
      }
  const Hyperpatch b = Translated(BoxPatch(), {3, 0, 0});
  ASSERT_TRUE(CheckCell(a).valid) << CheckCell(a).rejection.ToString();
  EXPECT_TRUE(NetsOverlap(a.positions(), b.positions()));
}

TEST(ValidityTest, CellInsideAnotherSharingAnEdgeOverlaps) {
  const Hyperpatch a = BoxPatch();
  const Hyperpatch b = Translated(BoxPatch(2, 2, 3), {1, 1, 0});  // shares A's edge x=y=3
  EXPECT_TRUE(NetsOverlap(a.positions(), b.positions()));
}

TEST(ValidityTest, CheckerCachesByCellVersion) {
  CompositeModel m(2);
  for (int x = 0; x < 3; ++x) ASSERT_TRUE(m.AddPatch(Translated(BoxPatch(), {3.0 * x, 0, 0}), 1e-9).ok());
  EXPECT_EQ(m.coefficient_count(), 64u * 3 - 16 * 2);  // two shared faces welded
  ValidityChecker checker;
  const auto first = checker.CheckModel(m);
  EXPECT_TRUE(first.valid);
  EXPECT_EQ(first.cells_checked, 3);
  const auto second = checker.CheckModel(m);
  EXPECT_TRUE(second.valid);
  EXPECT_EQ(second.cells_checked, 0);
  EXPECT_GT(second.cache_hits, 0);
  // Moving a coefficient of cell 2 only re-checks cell 2 (and its pairs).
  const uint32_t c = m.cell(2).coef[Hyperpatch::Index(3, 3, 3)];
  m.SetPosition(c, m.position(c) + Vec3{0.1, 0.1, 0.1});
  const auto third = checker.CheckModel(m);
  EXPECT_TRUE(third.valid);
  EXPECT_EQ(third.cells_checked, 1);
}

TEST(ValidityTest, CheckerReportsOverlapWithBothCells) {
  CompositeModel m(2);
  ASSERT_TRUE(m.AddPatch(BoxPatch(), 1e-9).ok());
  ASSERT_TRUE(m.AddPatch(Translated(BoxPatch(), {1, 1, 1}), 1e-9).ok());
  ValidityChecker checker;
  const auto rep = checker.CheckModel(m);
  ASSERT_FALSE(rep.valid);
  ASSERT_EQ(rep.rejections.size(), 1u);
  EXPECT_EQ(rep.rejections[0].reason, Reason::kCellOverlap);
  EXPECT_EQ(rep.rejections[0].cell, 0);
  EXPECT_EQ(rep.rejections[0].other_cell, 1);
}

}  // namespace
}  // namespace sculpt::hetero
