#include "sculpt/hetero/examples.h"

#include <gtest/gtest.h>

#include "sculpt/hetero/inverse_map.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"

namespace sculpt::hetero {
namespace {

TEST(ExamplesTest, TyreIsValidWithABlendedTread) {
  const auto tyre = BuildMotorcycleTyre();
  ASSERT_TRUE(tyre.ok()) << tyre.status();
  EXPECT_EQ(tyre->cell_count(), 80u);
  EXPECT_EQ(tyre->materials(), 5);
  ValidityChecker checker;
  EXPECT_TRUE(checker.CheckModel(*tyre).valid);
  // The tread surface at the left edge is carbon-black rich, at the right silica rich, and the
  // three compounds vary continuously across the width.
  const InverseMap map(*tyre);
  const auto left = map.Locate({29.5, 0.3, -8.5});
  const auto mid = map.Locate({29.5, 0.3, 0.0});
  const auto right = map.Locate({29.5, 0.3, 8.5});
  ASSERT_TRUE(left && mid && right);
  EXPECT_GT(left->materials[0], 0.6);
  EXPECT_GT(right->materials[1], 0.6);
  EXPECT_NEAR(mid->materials[0], 0.4, 1e-9);
  EXPECT_NEAR(mid->materials[2], 0.2, 1e-9);
  // The body ply beneath is one material.
  const auto ply = map.Locate({28.0, 0.3, 0.0});
  ASSERT_TRUE(ply);
  EXPECT_NEAR(ply->materials[3], 1.0, 1e-12);
}

TEST(ExamplesTest, MechanicalPartIsValid) {
  const auto part = BuildMechanicalPart();
  ASSERT_TRUE(part.ok()) << part.status();
  EXPECT_EQ(part->cell_count(), 26u);
  ValidityChecker checker;
  EXPECT_TRUE(checker.CheckModel(*part).valid);
}

TEST(ExamplesTest, ShippedSceneFilesMatchTheRecipes) {
  // scenes/ holds the models as files; they must load, be valid, and equal the recipes' output
  // (regenerate with `sculpt-bench hetero --write-scenes scenes`).
  using Builder = StatusOr<CompositeModel> (*)();
  const std::pair<const char*, Builder> scenes[] = {
      {kTyreSceneFile, [] { return BuildMotorcycleTyre(); }},
      {kMechanicalPartSceneFile, [] { return BuildMechanicalPart(); }}};
  for (const auto& [file, build] : scenes) {
    const auto loaded = LoadModel(std::string(SCULPT_SOURCE_DIR) + "/scenes/" + file);
    ASSERT_TRUE(loaded.ok()) << file << ": " << loaded.status();
    const auto built = build();
    ASSERT_TRUE(built.ok());
    ASSERT_EQ(loaded->cell_count(), built->cell_count()) << file;
    ASSERT_EQ(loaded->coefficient_count(), built->coefficient_count()) << file;
    for (uint32_t q = 0; q < built->coefficient_count(); ++q) {
      ASSERT_NEAR((loaded->position(q) - built->position(q)).Length(), 0, 1e-9) << file << " " << q;
    }
    ValidityChecker checker;
    EXPECT_TRUE(checker.CheckModel(*loaded).valid) << file;
  }
}

}  // namespace
}  // namespace sculpt::hetero
