#include "sculpt/hetero/construction.h"

#include <gtest/gtest.h>

#include "sculpt/hetero/corner_block.h"
#include "sculpt/hetero/grid_editor.h"
#include "sculpt/hetero/model_io.h"

namespace sculpt::hetero {
namespace {

const std::vector<double> kSteel = {1.0, 0.0}, kCeramic = {0.0, 1.0};

class ConstructionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto box = LibraryBox({0, 0, 0}, {3, 3, 3}, kSteel);
    ASSERT_TRUE(box.ok()) << box.status();
    const auto r = AddCellChecked(&model_, &checker_, *box, CellSource::kLibrary);
    ASSERT_TRUE(r.ok() && r->added);
  }
  CompositeModel model_{2};
  ValidityChecker checker_;
};

TEST_F(ConstructionTest, ExtrusionAddsFortyEightCoefficientsAndCopiesMaterial) {
  // Claim 28.
  ASSERT_TRUE(SetCellMaterial(&model_, 0, kCeramic).ok());
  const size_t before = model_.coefficient_count();
  const auto r = Extrude(&model_, &checker_, {0, 0, 1}, {1.0, 1.0, 1.0});
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_TRUE(r->added) << r->rejection.ToString();
  EXPECT_EQ(model_.coefficient_count() - before, 48u);
  const Hyperpatch h = model_.CellPatch(r->cell);
  EXPECT_NEAR((h.position(3, 3, 3) - Vec3{6, 3, 3}).Length(), 0, 1e-12);
  for (int s = 0; s < 64; ++s) EXPECT_EQ(h.fractions(s)[1], 1.0);
  // With intervals equal to the interior spacing the junction is geometrically C1.
  const uint32_t corner = model_.cell(0).coef[Hyperpatch::Index(3, 0, 0)];
  const auto block = BuildCornerBlock(model_, corner);
  EXPECT_TRUE(ClassifyCorner(model_, *block).geometry_c1);
  EXPECT_TRUE(model_.corner_flags(block->corner).geometry_c1);
  EXPECT_FALSE(r->c1_corners.empty());
}

TEST_F(ConstructionTest, ExtrudingAnInternalFaceIsRefused) {
  ASSERT_TRUE(Extrude(&model_, &checker_, {0, 0, 1}, {1, 1, 1})->added);
  const auto again = Extrude(&model_, &checker_, {0, 0, 1}, {1, 1, 1});
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.status().message().find("internal"), std::string::npos);
}

TEST_F(ConstructionTest, ExtrusionIntoAnExistingCellIsRefusedAndRolledBack) {
  const auto box = LibraryBox({4, 0, 0}, {7, 3, 3}, kSteel);
  ASSERT_TRUE(AddCellChecked(&model_, &checker_, *box, CellSource::kLibrary)->added);
  const auto cp = model_.MakeCheckpoint();
  const auto r = Extrude(&model_, &checker_, {0, 0, 1}, {1, 1, 1});
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_FALSE(r->added);
  EXPECT_EQ(r->rejection.reason, Reason::kCellOverlap);
  EXPECT_EQ(model_.cell_count(), cp.cells);
  EXPECT_EQ(model_.coefficient_count(), cp.coefficients);
}

TEST_F(ConstructionTest, RejectsBadExtrusionInterval) {
  const auto r = Extrude(&model_, &checker_, {0, 0, 1}, {1, -1, 1});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("extrude.intervals[1]=-1 outside"), std::string::npos);
}

TEST_F(ConstructionTest, ContinuousAndLinearBlendsFillTheGap) {
  // Claim 29.
  const auto box = LibraryBox({6, 0, 0}, {9, 3, 3}, kCeramic);
  ASSERT_TRUE(AddCellChecked(&model_, &checker_, *box, CellSource::kLibrary)->added);
  CompositeModel copy = model_;
  ValidityChecker checker2;
  const auto lin = Blend(&copy, &checker2, {0, 0, 1}, {1, 0, 0}, /*continuous=*/false);
  ASSERT_TRUE(lin.ok() && lin->added) << lin->rejection.ToString();
  const Hyperpatch hl = copy.CellPatch(lin->cell);
  EXPECT_NEAR(hl.position(1, 0, 0).x, 4.0, 1e-12);
  EXPECT_NEAR(hl.position(2, 0, 0).x, 5.0, 1e-12);
  EXPECT_EQ(hl.fractions(Hyperpatch::Index(1, 0, 0))[0], 1.0);
  EXPECT_EQ(hl.fractions(Hyperpatch::Index(2, 0, 0))[1], 1.0);
  const auto cont = Blend(&model_, &checker_, {0, 0, 1}, {1, 0, 0}, /*continuous=*/true);
  ASSERT_TRUE(cont.ok() && cont->added) << cont->rejection.ToString();
  const Hyperpatch hc = model_.CellPatch(cont->cell);
  EXPECT_NEAR(hc.position(1, 1, 1).x, 4.0, 1e-12);  // 2·3 − 2 (7.6)
  EXPECT_NEAR(hc.position(2, 1, 1).x, 5.0, 1e-12);  // 2·6 − 7
  EXPECT_TRUE(checker_.CheckModel(model_).valid);
}

TEST_F(ConstructionTest, LibraryRejectsAnOverlappingCell) {
  const auto box = LibraryBox({1, 1, 1}, {4, 4, 4}, kSteel);
  const auto r = AddCellChecked(&model_, &checker_, *box, CellSource::kLibrary);
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->added);
  EXPECT_EQ(r->rejection.reason, Reason::kCellOverlap);
  EXPECT_EQ(model_.cell_count(), 1u);
}

TEST_F(ConstructionTest, RejectsBadLibraryParameters) {
  EXPECT_FALSE(LibraryBox({0, 0, 0}, {0, 1, 1}, kSteel).ok());
  EXPECT_FALSE(LibraryRingSector(1, 2, 0, 120, 0, 1, kSteel).ok());  // over 90° per cell
  const auto r = LibraryRingSector(2, 1, 0, 90, 0, 1, kSteel);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("ring.r1=1 outside"), std::string::npos);
}

TEST_F(ConstructionTest, RingOfFourSectorsIsValidAndClosed) {
  CompositeModel ring(2);
  ValidityChecker checker;
  for (int s = 0; s < 4; ++s) {
    const auto h = LibraryRingSector(1, 2, 90.0 * s, 90.0 * (s + 1), 0, 1, kSteel);
    ASSERT_TRUE(h.ok());
    const auto r = AddCellChecked(&ring, &checker, *h, CellSource::kLibrary);
    ASSERT_TRUE(r.ok() && r->added) << s << " " << r->rejection.ToString();
  }
  // Closed: every angular face is shared, so only the 4×4 = 16 radial/height faces are external.
  int external = 0;
  for (int c = 0; c < 4; ++c)
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) external += *IsExternalFace(ring, {c, axis, side});
  EXPECT_EQ(external, 16);
}

TEST_F(ConstructionTest, SubdivisionKeepsTheGeometry) {
  const Hyperpatch before = model_.CellPatch(0);
  ASSERT_TRUE(SubdivideCell(&model_, 0, 1, 0.5).ok());
  ASSERT_EQ(model_.cell_count(), 2u);
  EXPECT_NEAR((model_.CellPatch(0).Evaluate(0.3, 1.0, 0.7) - before.Evaluate(0.3, 0.5, 0.7)).Length(), 0, 1e-12);
  EXPECT_NEAR((model_.CellPatch(1).Evaluate(0.3, 0.5, 0.7) - before.Evaluate(0.3, 0.75, 0.7)).Length(), 0, 1e-12);
  EXPECT_TRUE(checker_.CheckModel(model_).valid);
}

TEST(ModelIoTest, RoundTripsAModel) {
  CompositeModel m(2);
  ValidityChecker checker;
  ASSERT_TRUE(AddCellChecked(&m, &checker, *LibraryBox({0, 0, 0}, {1, 1, 1}, kSteel), CellSource::kLibrary)->added);
  ASSERT_TRUE(Extrude(&m, &checker, {0, 2, 1}, {0.5, 0.5, 0.5})->added);
  const std::string text = ModelToJson(m, "two cells");
  const auto back = ModelFromJson(text);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->cell_count(), m.cell_count());
  ASSERT_EQ(back->coefficient_count(), m.coefficient_count());
  for (uint32_t q = 0; q < m.coefficient_count(); ++q) EXPECT_EQ(back->position(q), m.position(q));
  EXPECT_EQ(back->all_corner_flags(), m.all_corner_flags());
  EXPECT_EQ(ModelToJson(*back, "two cells"), text);
}

TEST(ModelIoTest, RejectsFractionsOutsideTheSimplex) {
  const std::string doc = R"({"format":"sculpt-hetero-model","version":1,
    "materials":[{"name":"a"},{"name":"b"}],"coefficients":[[0,0,0,0.7,0.7]],"cells":[]})";
  const auto r = ModelFromJson(doc);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("model.coefficients[0].a.sum=1.4"), std::string::npos)
      << r.status();
}

TEST(ModelIoTest, RejectsCellIndexOutOfRange) {
  std::string cells = "[";
  for (int i = 0; i < 64; ++i) cells += (i ? "," : "") + std::string(i == 5 ? "7" : "0");
  cells += "]";
  const std::string doc = R"({"format":"sculpt-hetero-model","version":1,
    "materials":[{"name":"a"}],"coefficients":[[0,0,0,1]],"cells":[)" + cells + "]}";
  const auto r = ModelFromJson(doc);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("model.cells[0][5]=7 outside [0, 0]"), std::string::npos)
      << r.status();
}

TEST(ModelIoTest, RejectsNotJsonAndWrongFormat) {
  EXPECT_FALSE(ModelFromJson("{").ok());
  EXPECT_FALSE(ModelFromJson(R"({"format":"other","version":1})").ok());
  EXPECT_FALSE(ModelFromJson(R"({"format":"sculpt-hetero-model","version":1,"materials":[],
    "coefficients":[],"cells":[]})").ok());
}

}  // namespace
}  // namespace sculpt::hetero
