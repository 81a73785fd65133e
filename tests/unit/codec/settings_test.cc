// The edit settings a replica replays with (codec/settings.h): every field the server's scene
// settings can change arrives as sent, so a replica applies an edit as the server did.
#include "sculpt/codec/settings.h"

#include <gtest/gtest.h>

namespace sculpt::codec {
namespace {

TEST(EditSettingsCodecTest, SceneChoicesRoundTrip) {
  levelset::EditSettings s;
  s.compensation = levelset::CompensationRegion::kNone;
  s.islands = levelset::IslandPolicy::kRemoveSmall;
  s.min_island_volume = 12.5;
  s.max_amount_voxels = 16;
  s.repair_band_every_edit = true;
  auto back = SettingsFromProto(SettingsToProto(s));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->get().compensation, levelset::CompensationRegion::kNone);
  EXPECT_EQ(back->get().islands, levelset::IslandPolicy::kRemoveSmall);
  EXPECT_EQ(back->get().min_island_volume, 12.5);
  EXPECT_EQ(back->get().max_amount_voxels, 16);
  EXPECT_TRUE(back->get().repair_band_every_edit);
  // A server that never sets it (or predates it) means the default.
  s.repair_band_every_edit = false;
  auto off = SettingsFromProto(SettingsToProto(s));
  ASSERT_TRUE(off.ok()) << off.status();
  EXPECT_FALSE(off->get().repair_band_every_edit);
}

}  // namespace
}  // namespace sculpt::codec
