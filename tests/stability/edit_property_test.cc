// Issue 11, part 1: the random-edit property test (stability/edit_property.h) at the server's
// settings, with and without the band repair on every edit. A longer run is in
// tests/soak/edit_property_soak_test.cc.
#include "stability/edit_property.h"

#include <gtest/gtest.h>

namespace sculpt::levelset {
namespace {

using testing::Counts;
using testing::ExpectRepairedInvariants;
using testing::RunSeeds;
using testing::ServerSettings;

// Under the sanitizers an edit costs about ten times as much: fewer edits, the same checks.
#if defined(__SANITIZE_ADDRESS__)
constexpr int kEditsPerSeed = 40;
#else
constexpr int kEditsPerSeed = 150;
#endif

// At the server's defaults every random edit leaves a closed, outward mesh whose volume is the
// tracked one within 1% but for rare edits (as with the repair, below); the band checks do not
// hold yet (docs/benchmarks.md, "Invariants under random edits"): their counts are printed and
// recorded, and asserted by the test below with the band repair on.
TEST(EditProperty, RandomEditsLeaveAClosedMeshAtTheDefaults) {
  const Counts c = RunSeeds({1, 2, 3, 4}, kEditsPerSeed, ServerSettings());
  EXPECT_EQ(c.edits, 4 * kEditsPerSeed);
  EXPECT_EQ(c.mesh_open, 0) << c.summary;
  EXPECT_LE(c.volume_off, testing::RareBound(c.edits)) << c.summary;
}

// With the band repair on every edit, no edit leaves the zero crossing at the band's edge,
// |grad phi| outside [0.5, 1.5] or a pocket below min_island_volume, and slivers, specks and a
// mesh volume off the tracked one by more than 1% stay rare (ExpectRepairedInvariants).
TEST(EditProperty, RandomEditsWithTheBandRepairKeepTheInvariantsButForRareEdits) {
  EditSettings set = ServerSettings();
  set.repair_band_every_edit = true;
  const Counts c = RunSeeds({1, 2, 3, 4}, kEditsPerSeed, set);
  EXPECT_EQ(c.edits, 4 * kEditsPerSeed);
  ExpectRepairedInvariants(c);
}

}  // namespace
}  // namespace sculpt::levelset
