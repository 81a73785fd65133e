#include "config/server_config.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace sculpt::server {
namespace {

std::string Write(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("sculpt_cfg_" + name + ".toml");
  std::ofstream(p) << text;
  return p.string();
}

TEST(ConfigTest, DefaultsAreValid) {
  ServerConfig c;
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
}

TEST(ConfigTest, SampleFileLoads) {
  ServerConfig c;
  const Status s = LoadConfigFile(std::string(SCULPT_SOURCE_DIR) + "/deploy/scene.toml", &c);
  ASSERT_TRUE(s.ok()) << s;
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
  EXPECT_EQ(c.scene.objects.size(), 1u);
  EXPECT_EQ(c.scene.objects[0].name, "clay");
  EXPECT_EQ(c.sculptor_token, "change-me-sculptor");
}

TEST(ConfigTest, RejectsBadFsync) {
  ServerConfig c;
  ASSERT_TRUE(LoadConfigFile(Write("fsync", "[server]\nfsync = \"sometimes\"\n"), &c).ok());
  const Status s = ValidateConfig(c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("fsync=sometimes outside {always, group}"), std::string::npos) << s;
}

TEST(ConfigTest, RejectsNegativeVoxelSize) {
  ServerConfig c;
  ASSERT_TRUE(LoadConfigFile(Write("voxel", "[scene]\nvoxel_size = -1.0\n"), &c).ok());
  const Status s = ValidateConfig(c);
  EXPECT_NE(s.message().find("scene.voxel_size=-1 outside"), std::string::npos) << s;
}

TEST(ConfigTest, RefusalCarriesTheFieldViolation) {
  ServerConfig c;
  ASSERT_TRUE(LoadConfigFile(Write("voxel_violation", "[scene]\nvoxel_size = -1.0\n"), &c).ok());
  const Status s = ValidateConfig(c);
  ASSERT_NE(s.violation(), nullptr) << s;
  EXPECT_EQ(s.violation()->field, "scene.voxel_size");
  EXPECT_EQ(s.violation()->value, "-1");
  EXPECT_FALSE(s.violation()->allowed_range.empty());
}

TEST(ConfigTest, RejectsEqualTokens) {
  ServerConfig c;
  c.viewer_token = c.sculptor_token;
  EXPECT_FALSE(ValidateConfig(c).ok());
}

TEST(ConfigTest, RejectsUnsupportedEffects) {
  ServerConfig c;
  c.scene.effects.materials = {"steel"};
  EXPECT_NE(ValidateConfig(c).message().find("materials"), std::string::npos);
  c.scene.effects.materials.clear();
  c.scene.effects.contours = true;  // contours are served when a scene asks for them
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
}

TEST(ConfigTest, ReadsMaxPendingJoinsAndRejectsZero) {
  ServerConfig c;
  EXPECT_EQ(c.limits.max_pending_joins, 8u);
  ASSERT_TRUE(LoadConfigFile(Write("joins", "[limits]\nmax_pending_joins = 3\n"), &c).ok());
  EXPECT_EQ(c.limits.max_pending_joins, 3u);
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
  ASSERT_TRUE(LoadConfigFile(Write("joins0", "[limits]\nmax_pending_joins = 0\n"), &c).ok());
  const Status s = ValidateConfig(c);
  EXPECT_NE(s.message().find("limits.max_pending_joins=0 outside [1, 1024]"), std::string::npos)
      << s;
}

TEST(ConfigTest, ReportsTomlSyntaxErrorsWithLine) {
  ServerConfig c;
  const Status s = LoadConfigFile(Write("syntax", "[server]\nlisten = \n"), &c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find(":2:"), std::string::npos) << s;
}

// A typo is refused with the key's full name and its line and column, not silently ignored.
TEST(ConfigTest, RejectsUnknownKeysNamingThemAndWhere) {
  struct Case {
    const char* text;
    const char* key;
    const char* where;
  } cases[] = {
      {"[server]\nsnapshot_every_edit = 10\n", "unknown key server.snapshot_every_edit", ":2:1"},
      {"[limits]\n\nstroke_bursts = 3\n", "unknown key limits.stroke_bursts", ":3:1"},
      {"[scene]\nname = \"s\"\nvoxelsize = 1.0\n", "unknown key scene.voxelsize", ":3:1"},
      {"[scene.effects]\ncountours = true\n", "unknown key scene.effects.countours", ":2:1"},
      {"[[scene.objects]]\nname = \"a\"\nradius = 3.0\nraduis = 2.0\n",
       "unknown key scene.objects[0].raduis", ":4:1"},
      {"[[scene.skins]]\nname = \"k\"\ntolerance = 0.1\n", "unknown key scene.skins[0].tolerance",
       ":3:1"},
      {"[serve]\nlisten = \"127.0.0.1:1\"\n", "unknown key serve ", ":1:2"},
  };
  for (const Case& c : cases) {
    ServerConfig config;
    const Status s = LoadConfigFile(Write("unknown", c.text), &config);
    ASSERT_FALSE(s.ok()) << c.text;
    EXPECT_NE(s.message().find(c.key), std::string::npos) << s;
    EXPECT_NE(s.message().find(c.where), std::string::npos) << s;
  }
}

TEST(ConfigTest, ExampleScenesUseOnlyKnownKeys) {
  for (const char* f : {"/deploy/scenes/tyre.toml", "/deploy/scenes/mechanical.toml"}) {
    ServerConfig c;
    const Status s = LoadConfigFile(std::string(SCULPT_SOURCE_DIR) + f, &c);
    EXPECT_TRUE(s.ok()) << f << ": " << s;
  }
}

TEST(ConfigTest, ParsesHostPort) {
  std::string h;
  uint16_t p = 0;
  EXPECT_TRUE(ParseHostPort("127.0.0.1:7420", &h, &p).ok());
  EXPECT_EQ(h, "127.0.0.1");
  EXPECT_EQ(p, 7420);
  EXPECT_TRUE(ParseHostPort("[::1]:0", &h, &p).ok());
  EXPECT_EQ(h, "::1");
  EXPECT_FALSE(ParseHostPort("nohost", &h, &p).ok());
  EXPECT_FALSE(ParseHostPort("h:99999", &h, &p).ok());
  EXPECT_FALSE(ParseHostPort("h:12a", &h, &p).ok());
}

TEST(ConfigTest, EffectsSelectKernelSettings) {
  SceneConfig s;
  s.effects.volume_preservation = "none";
  s.effects.islands = "keep";
  const auto e = EditSettingsFor(s);
  EXPECT_EQ(e.compensation, levelset::CompensationRegion::kNone);
  EXPECT_EQ(e.islands, levelset::IslandPolicy::kKeep);
  EXPECT_FALSE(e.repair_band_every_edit);  // where_needed, the default
  s.effects.band_repair = "every_edit";
  EXPECT_TRUE(EditSettingsFor(s).repair_band_every_edit);
}

TEST(ConfigTest, RejectsAnUnknownBandRepair) {
  ServerConfig c;
  c.scene.effects.band_repair = "always";
  const Status st = ValidateConfig(c);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("scene.effects.band_repair"), std::string::npos) << st;
  EXPECT_NE(st.message().find("always"), std::string::npos) << st;
}

}  // namespace
}  // namespace sculpt::server
