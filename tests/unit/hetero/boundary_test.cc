#include "sculpt/hetero/boundary.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sculpt/hetero/examples.h"
#include "sculpt/hetero/grid_editor.h"

namespace sculpt::hetero {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(BoundaryTest, TwoGluedBoxesHaveTenExternalFacesAndAClosedMesh) {
  CompositeModel m(2);
  ValidityChecker checker;
  ASSERT_TRUE(AddCellChecked(&m, &checker, *LibraryBox({0, 0, 0}, {1, 2, 3}, std::vector<double>{1, 0}),
                             CellSource::kLibrary)->added);
  ASSERT_TRUE(Extrude(&m, &checker, {0, 0, 1}, {0.5, 0.5, 0.5})->added);
  // Claim 26: the glued face is internal; a material discontinuity must not open it.
  ASSERT_TRUE(SetCellMaterial(&m, 1, std::vector<double>{0, 1}).ok());
  EXPECT_EQ(ExternalFaces(m).size(), 10u);
  const auto mesh = ExternalBoundaryMesh(m, 4);
  ASSERT_TRUE(mesh.ok());
  EXPECT_EQ(mesh->open_edges, 0u);
  EXPECT_NEAR(mesh->Volume(), 2.5 * 2 * 3, 1e-9);  // outward: positive volume
  const MaterialVolumes v = IntegrateVolumes(m);
  EXPECT_NEAR(v.total, 15.0, 1e-9);
  EXPECT_NEAR(v.per_material[0], 6.0, 1e-9);
  EXPECT_NEAR(v.per_material[1], 9.0, 1e-9);
}

TEST(BoundaryTest, TyreMeshIsClosedAndMatchesItsVolume) {
  const auto tyre = BuildMotorcycleTyre();
  ASSERT_TRUE(tyre.ok());
  const auto mesh = ExternalBoundaryMesh(*tyre, 6);
  ASSERT_TRUE(mesh.ok());
  EXPECT_EQ(mesh->open_edges, 0u);
  const MaterialVolumes v = IntegrateVolumes(*tyre);
  // The faceted mesh undercuts the curved cells slightly (48 chords of 7.5°: about 0.3%).
  EXPECT_NEAR(mesh->Volume() / v.total, 1.0, 4e-3);
  double sum = 0;
  for (double m : v.per_material) sum += m;
  EXPECT_NEAR(sum, v.total, 1e-9 * v.total);
  // Carbon black + silica make 0.8 of the tread everywhere: 0.8 of an annulus r 28.5..30,
  // width 18, to the cubic arcs' accuracy.
  const double tread = (v.per_material[0] + v.per_material[1]) / 0.8;
  EXPECT_NEAR(tread / (kPi * (30.0 * 30.0 - 28.5 * 28.5) * 18.0), 1.0, 1e-3);
}

TEST(BoundaryTest, RejectsBadSubdivision) {
  CompositeModel m(1);
  EXPECT_FALSE(ExternalBoundaryMesh(m, 0).ok());
  EXPECT_FALSE(ExternalBoundaryMesh(m, 65).ok());
}

}  // namespace
}  // namespace sculpt::hetero
