// scene.also: the further scenes one sculptd hosts (docs/scenes.md): reading, the refusals of
// ValidateConfig, and where each scene's data lives.
#include "config/server_config.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace sculpt::server {
namespace {

std::string Write(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("sculpt_hosted_" + name + ".toml");
  std::ofstream(p) << text;
  return p.string();
}

// The refusal of `c`, with its field violation.
Status Refusal(const ServerConfig& c) {
  const Status s = ValidateConfig(c);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.violation(), nullptr) << s;
  return s;
}

TEST(HostedScenesTest, ReadsAlsoFromTheSceneTable) {
  ServerConfig c;
  const std::string path = Write("read", "[scene]\nname = \"main\"\nalso = [\"b\", \"c-2\"]\n");
  ASSERT_TRUE(LoadConfigFile(path, &c).ok());
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
  EXPECT_EQ(c.scene.also, (std::vector<std::string>{"b", "c-2"}));
  EXPECT_EQ(HostedScenes(c), (std::vector<std::string>{"main", "b", "c-2"}));
}

TEST(HostedScenesTest, RejectsAlsoThatIsNotAnArrayOfStrings) {
  for (const char* text : {"[scene]\nalso = \"b\"\n", "[scene]\nalso = [\"b\", 3]\n"}) {
    ServerConfig c;
    const Status s = LoadConfigFile(Write("types", text), &c);
    ASSERT_FALSE(s.ok()) << text;
    EXPECT_NE(s.message().find("scene.also"), std::string::npos) << s;
  }
}

TEST(HostedScenesTest, WithoutAlsoTheDefaultSceneIsTheOnlyOneAndKeepsTheDataDirectory) {
  ServerConfig c;
  c.data_dir = "/srv/sculpt";
  EXPECT_EQ(HostedScenes(c), (std::vector<std::string>{"default"}));
  EXPECT_EQ(SceneDataDir(c, "default"), "/srv/sculpt");
  const ServerConfig one = ConfigForScene(c, "default");
  EXPECT_EQ(one.data_dir, "/srv/sculpt");
  EXPECT_EQ(one.scene.name, "default");
}

TEST(HostedScenesTest, OtherScenesLiveUnderScenesAndShareTheOtherSettings) {
  ServerConfig c;
  c.data_dir = "/srv/sculpt";
  c.scene.name = "a";
  c.scene.also = {"b"};
  c.scene.voxel_size = 0.25;
  c.limits.max_clients_per_scene = 7;
  EXPECT_EQ(SceneDataDir(c, "b"), "/srv/sculpt/scenes/b");
  const ServerConfig b = ConfigForScene(c, "b");
  EXPECT_EQ(b.data_dir, "/srv/sculpt/scenes/b");
  EXPECT_EQ(b.scene.name, "b");
  EXPECT_EQ(b.scene.voxel_size, 0.25);
  EXPECT_EQ(b.limits.max_clients_per_scene, 7u);
  EXPECT_EQ(b.listen, c.listen);
  EXPECT_TRUE(b.scene.also.empty());
  EXPECT_TRUE(ValidateConfig(b).ok()) << ValidateConfig(b);
}

TEST(HostedScenesTest, RejectsARepeatedName) {
  ServerConfig c;
  c.scene.also = {"b", "c", "b"};
  const Status s = Refusal(c);
  ASSERT_NE(s.violation(), nullptr);
  EXPECT_EQ(s.violation()->field, "scene.also[2]");
  EXPECT_EQ(s.violation()->value, "b");
  EXPECT_NE(s.violation()->allowed_range.find("scene.also[0]"), std::string::npos) << s;
}

TEST(HostedScenesTest, RejectsTheDefaultScenesOwnName) {
  ServerConfig c;
  c.scene.name = "main";
  c.scene.also = {"main"};
  const Status s = Refusal(c);
  ASSERT_NE(s.violation(), nullptr);
  EXPECT_EQ(s.violation()->field, "scene.also[0]");
  EXPECT_NE(s.violation()->allowed_range.find("scene.name=main"), std::string::npos) << s;
}

TEST(HostedScenesTest, RejectsNamesThatAreNotPlainDirectoryNames) {
  for (const std::string& bad :
       std::vector<std::string>{"", std::string(65, 'x'), "..", ".", "a/b", "../up", "a b", "é"}) {
    ServerConfig c;
    c.scene.also = {"ok", bad};
    const Status s = Refusal(c);
    ASSERT_NE(s.violation(), nullptr) << bad;
    EXPECT_EQ(s.violation()->field, "scene.also[1]") << bad;
    EXPECT_EQ(s.violation()->value, bad);
    EXPECT_NE(s.violation()->allowed_range.find("1..64 bytes"), std::string::npos) << s;
  }
  ServerConfig c;
  c.scene.also = {std::string(64, 'x'), "A.b_c-9"};
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
}

TEST(HostedScenesTest, RejectsMoreThanTheMostScenes) {
  ServerConfig c;
  for (size_t i = 0; i <= kMaxAlsoScenes; ++i) {
    std::string name = "s";  // (gcc 12 warns, wrongly, of "s" + std::to_string(i) at -O3)
    name += std::to_string(i);
    c.scene.also.push_back(name);
  }
  const Status s = Refusal(c);
  ASSERT_NE(s.violation(), nullptr);
  EXPECT_EQ(s.violation()->field, "scene.also.size");
  EXPECT_EQ(s.violation()->value, std::to_string(kMaxAlsoScenes + 1));
  EXPECT_EQ(s.violation()->allowed_range, "[0, 64]");
  c.scene.also.pop_back();
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
}

// A cluster member offers every scene it hosts (cluster/cluster_agent.h).
TEST(HostedScenesTest, AcceptsAlsoInClusterMode) {
  ServerConfig c;
  c.scene.also = {"b"};
  c.cluster.etcd = {"http://127.0.0.1:2379"};
  c.cluster.member = "m1";
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
  c.scene.also = {"b", "b"};
  EXPECT_FALSE(ValidateConfig(c).ok()) << "a duplicate is refused in cluster mode too";
}

}  // namespace
}  // namespace sculpt::server
