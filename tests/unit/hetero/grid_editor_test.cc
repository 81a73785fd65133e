#include "sculpt/hetero/grid_editor.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sculpt/hetero/corner_block.h"
#include "unit/hetero/hetero_test_util.h"

namespace sculpt::hetero {
namespace {

using testing::BoxPatch;

Hyperpatch Shifted(const Hyperpatch& h, const Vec3& d) {
  Hyperpatch r = h;
  for (int i = 0; i < 64; ++i) r.set_position(i, h.position(i) + d);
  return r;
}

// 2×2×2 box cells of size 3 around the corner point (3,3,3).
class GridEditorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (int c = 0; c < 8; ++c) {
      const Vec3 d{3.0 * ((c >> 2) & 1), 3.0 * ((c >> 1) & 1), 3.0 * (c & 1)};
      ASSERT_TRUE(model_.AddPatch(Shifted(BoxPatch(), d), 1e-9).ok());
    }
    centre_ = model_.cell(0).coef[Hyperpatch::Index(3, 3, 3)];
  }
  std::vector<Vec3> Positions() const {
    std::vector<Vec3> p;
    for (uint32_t q = 0; q < model_.coefficient_count(); ++q) p.push_back(model_.position(q));
    return p;
  }
  CompositeModel model_{2};
  uint32_t centre_ = 0;
  ValidityChecker checker_;
};

TEST_F(GridEditorTest, CentreCornerIsARegularBlockOfEightCells) {
  const auto block = BuildCornerBlock(model_, centre_);
  ASSERT_TRUE(block.ok()) << block.status();
  EXPECT_TRUE(block->regular);
  EXPECT_EQ(block->valence(), 8);
  for (const auto& v : block->coefs) EXPECT_EQ(v.size(), 1u);
  const CornerContinuity c = ClassifyCorner(model_, *block);
  EXPECT_TRUE(c.geometry_c0 && c.geometry_c1 && c.material_c0 && c.material_c1);
}

TEST_F(GridEditorTest, MovingAC1CornerMovesItsTwentySixNeighbours) {
  // Claim 20.
  model_.set_corner_flags(centre_, {true, false});
  EditIntent in{centre_, {0, 0, 0}, {0.2, -0.1, 0.3}};
  const auto out = ApplyIntent(&model_, &checker_, in);
  ASSERT_TRUE(out.ok()) << out.status();
  ASSERT_TRUE(out->applied) << out->rejection.ToString();
  EXPECT_EQ(out->moves.size(), 27u);
  for (const auto& m : out->moves) EXPECT_EQ(m.delta, in.displacement);
  EXPECT_EQ(out->touched_cells.size(), 8u);
}

TEST_F(GridEditorTest, NeighbourEditsMoveSeventeenElevenOrSevenOthersAndKeepC1) {
  // Claim 21: surface, edge and vertex neighbours; (7.6) then holds on all three axes.
  model_.set_corner_flags(centre_, {true, false});
  const struct {
    std::array<int, 3> e;
    size_t moved;
  } cases[] = {{{1, 0, 0}, 18}, {{0, -1, 0}, 18}, {{1, 1, 0}, 12}, {{0, 1, -1}, 12},
               {{1, 1, 1}, 8},  {{-1, 1, -1}, 8}};
  for (const auto& c : cases) {
    const auto out = ApplyIntent(&model_, &checker_, {centre_, c.e, {0.05, 0.1, -0.05}});
    ASSERT_TRUE(out.ok()) << out.status();
    ASSERT_TRUE(out->applied) << out->rejection.ToString();
    EXPECT_EQ(out->moves.size(), c.moved);
    const auto block = BuildCornerBlock(model_, centre_);
    EXPECT_TRUE(ClassifyCorner(model_, *block).geometry_c1);
  }
}

TEST_F(GridEditorTest, NeighbourOfANonContinuousCornerMovesAlone) {
  // Claim 22.
  const auto out = ApplyIntent(&model_, &checker_, {centre_, {1, 0, 0}, {0.1, 0, 0}});
  ASSERT_TRUE(out.ok() && out->applied);
  EXPECT_EQ(out->moves.size(), 1u);
  EXPECT_FALSE(ClassifyCorner(model_, *BuildCornerBlock(model_, centre_)).geometry_c1);
}

TEST_F(GridEditorTest, ExpansionIsDeterministic) {
  model_.set_corner_flags(centre_, {true, false});
  const EditIntent in{centre_, {1, 1, 0}, {0.1, 0.2, 0.3}};
  const auto a = ExpandIntent(model_, in), b = ExpandIntent(model_, in);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->size(), b->size());
  for (size_t i = 0; i < a->size(); ++i) {
    EXPECT_EQ((*a)[i].coef, (*b)[i].coef);
    EXPECT_EQ((*a)[i].delta, (*b)[i].delta);
    if (i > 0) {
      EXPECT_LT((*a)[i - 1].coef, (*a)[i].coef);
    }
  }
}

TEST_F(GridEditorTest, RefusesAFoldingEditAndLeavesTheModelUnchanged) {
  const auto before = Positions();
  // The face neighbour pushed 5 units through the opposite face of its cells.
  const auto out = ApplyIntent(&model_, &checker_, {centre_, {1, 0, 0}, {-5, 0, 0}});
  ASSERT_TRUE(out.ok()) << out.status();
  EXPECT_FALSE(out->applied);
  EXPECT_NE(out->rejection.reason, Reason::kOk);
  EXPECT_GE(out->rejection.cell, 0);
  EXPECT_EQ(Positions(), before);
}

TEST_F(GridEditorTest, RejectsOffsetOutsideTheBlock) {
  const auto out = ApplyIntent(&model_, &checker_, {centre_, {2, 0, 0}, {0.1, 0, 0}});
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("intent.offset[0]=2 outside [-1, 1]"), std::string::npos)
      << out.status();
}

TEST_F(GridEditorTest, RejectsNanDisplacement) {
  const auto out = ApplyIntent(&model_, &checker_, {centre_, {0, 0, 0}, {std::nan(""), 0, 0}});
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("intent.displacement"), std::string::npos);
}

TEST_F(GridEditorTest, RejectsUnknownCorner) {
  const auto out = ApplyIntent(&model_, &checker_, {999999, {0, 0, 0}, {0, 0, 0}});
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("intent.corner=999999 outside"), std::string::npos);
}

TEST_F(GridEditorTest, SettingC1FlagsEnforcesThemFromTheLowerSide) {
  // Break C1 by moving a +x face neighbour alone, then ask for C1: (7.6) restores it.
  ASSERT_TRUE(ApplyIntent(&model_, &checker_, {centre_, {1, 0, 0}, {0.3, 0, 0}})->applied);
  EXPECT_FALSE(ClassifyCorner(model_, *BuildCornerBlock(model_, centre_)).geometry_c1);
  EditIntent in{centre_, {0, 0, 0}, {0, 0, 0}};
  in.set_flags = CornerFlags{true, true};
  const auto out = ApplyIntent(&model_, &checker_, in);
  ASSERT_TRUE(out.ok() && out->applied) << out->rejection.ToString();
  const CornerContinuity c = ClassifyCorner(model_, *BuildCornerBlock(model_, centre_));
  EXPECT_TRUE(c.geometry_c1);
  EXPECT_TRUE(c.material_c1);
  EXPECT_TRUE(model_.corner_flags(centre_).geometry_c1);
}

TEST(GridEditorIrregularTest, LShapedCornerIsIrregularAndRefusesAutomaticC1) {
  // Claim 23: three cells around a corner (valence 3, not a box).
  CompositeModel m(2);
  ASSERT_TRUE(m.AddPatch(BoxPatch(), 1e-9).ok());
  ASSERT_TRUE(m.AddPatch(Shifted(BoxPatch(), {3, 0, 0}), 1e-9).ok());
  ASSERT_TRUE(m.AddPatch(Shifted(BoxPatch(), {0, 3, 0}), 1e-9).ok());
  const uint32_t corner = m.cell(0).coef[Hyperpatch::Index(3, 3, 0)];
  const auto block = BuildCornerBlock(m, corner);
  ASSERT_TRUE(block.ok());
  EXPECT_EQ(block->valence(), 3);
  EXPECT_FALSE(block->regular);
  ValidityChecker checker;
  EditIntent in{corner, {0, 0, 0}, {0.1, 0, 0}};
  in.set_flags = CornerFlags{true, false};
  const auto out = ApplyIntent(&m, &checker, in);
  ASSERT_TRUE(out.ok()) << out.status();
  EXPECT_FALSE(out->applied);
  EXPECT_EQ(out->rejection.reason, Reason::kIrregularCorner);
  // Without C1 a neighbour edit needs the cell whose index space the offset uses.
  const auto bad = ApplyIntent(&m, &checker, {corner, {-1, 0, 0}, {0.1, 0, 0}});
  EXPECT_FALSE(bad.ok());
  EditIntent ok{corner, {-1, 0, 1}, {0.0, 0.1, 0}};
  ok.cell = 0;
  const auto good = ApplyIntent(&m, &checker, ok);
  ASSERT_TRUE(good.ok()) << good.status();
  EXPECT_TRUE(good->applied) << good->rejection.ToString();
  EXPECT_EQ(good->moves.size(), 1u);
}

TEST_F(GridEditorTest, CopyRuleGivesASmoothstepTrilinearGradation) {
  // Claims 18-19: the copy rule keeps A in V and equals trilinear interpolation of the corner
  // distributions in s(t) = 3t² − 2t³, with zero gradient at the corners.
  CompositeModel m(2);
  ASSERT_TRUE(m.AddPatch(BoxPatch(), 1e-9).ok());
  for (int c = 0; c < 8; ++c) {
    const uint32_t q = m.cell(0).coef[Hyperpatch::Index((c & 4) ? 3 : 0, (c & 2) ? 3 : 0, (c & 1) ? 3 : 0)];
    const double w = c / 7.0;
    ASSERT_TRUE(SetCornerMaterial(&m, q, std::vector<double>{w, 1 - w}).ok());
  }
  const Hyperpatch h = m.CellPatch(0);
  auto s = [](double t) { return 3 * t * t - 2 * t * t * t; };
  for (const Vec3 q : {Vec3{0.2, 0.7, 0.4}, Vec3{0.9, 0.1, 0.5}}) {
    double expect = 0;
    for (int c = 0; c < 8; ++c) {
      const double wu = (c & 4) ? s(q.x) : 1 - s(q.x), wv = (c & 2) ? s(q.y) : 1 - s(q.y),
                   ww = (c & 1) ? s(q.z) : 1 - s(q.z);
      expect += wu * wv * ww * (c / 7.0);
    }
    EXPECT_NEAR(h.Materials(q.x, q.y, q.z)[0], expect, 1e-12);
  }
}

TEST_F(GridEditorTest, CellMaterialLeavesNeighboursAndKeepsGeometryC0) {
  // Claim 24 and §8.2: one cell's 64 coefficients get the distribution; neighbours keep theirs.
  ASSERT_TRUE(SetCellMaterial(&model_, 0, std::vector<double>{0.0, 1.0}).ok());
  for (int s = 0; s < 64; ++s) {
    EXPECT_EQ(model_.fractions(model_.cell(0).coef[s])[1], 1.0);
  }
  for (int s = 0; s < 64; ++s) EXPECT_EQ(model_.fractions(model_.cell(7).coef[s])[0], 1.0);
  const CornerContinuity c = ClassifyCorner(model_, *BuildCornerBlock(model_, centre_));
  EXPECT_TRUE(c.geometry_c0);
  EXPECT_FALSE(c.material_c0);
  // The geometry is still one block: a C1 corner move keeps the duplicated entries together.
  EXPECT_TRUE(BuildCornerBlock(model_, centre_)->regular);
  EXPECT_TRUE(checker_.CheckModel(model_).valid);
}

TEST_F(GridEditorTest, SelectedCellsCornerMaterialIsDiscontinuousTowardsOthers) {
  // Fig. 8.7: the copy rule applied in cells 0 and 1 only.
  const std::vector<int> sel = {0, 1};
  ASSERT_TRUE(SetCornerMaterial(&model_, centre_, std::vector<double>{0.25, 0.75}, sel).ok());
  EXPECT_EQ(model_.fractions(model_.cell(0).coef[Hyperpatch::Index(2, 2, 2)])[1], 0.75);
  EXPECT_EQ(model_.fractions(model_.cell(7).coef[Hyperpatch::Index(1, 1, 1)])[1], 0.0);
  EXPECT_FALSE(ClassifyCorner(model_, *BuildCornerBlock(model_, centre_)).material_c0);
}

TEST_F(GridEditorTest, RejectsMaterialOutsideTheSimplex) {
  const Status s = SetPointMaterial(&model_, 0, std::vector<double>{0.4, 0.8});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("fractions.sum=1.2"), std::string::npos) << s;
  EXPECT_FALSE(SetCellMaterial(&model_, 0, std::vector<double>{-0.5, 1.5}).ok());
  EXPECT_FALSE(SetRegionMaterial(&model_, Aabb{{0, 0, 0}, {1, 1, 1}},
                                 std::vector<double>{std::nan(""), 1.0}).ok());
}

TEST_F(GridEditorTest, RegionMaterialSetsCoefficientsInsideTheBox) {
  ASSERT_TRUE(SetRegionMaterial(&model_, Aabb{{-1, -1, -1}, {1.5, 1.5, 1.5}},
                                std::vector<double>{0.5, 0.5}).ok());
  EXPECT_EQ(model_.fractions(model_.cell(0).coef[Hyperpatch::Index(1, 1, 1)])[0], 0.5);
  EXPECT_EQ(model_.fractions(model_.cell(0).coef[Hyperpatch::Index(2, 2, 2)])[0], 1.0);
}

}  // namespace
}  // namespace sculpt::hetero
