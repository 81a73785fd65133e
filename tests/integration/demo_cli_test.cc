// End to end: the `sculpt` binary as a user runs it (`sculpt demo`, `sculpt info`,
// `sculpt export`), checked through the files it writes.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "sculpt/levelset/sculpture.h"

namespace {

namespace fs = std::filesystem;

std::string Bin() { return std::string(SCULPT_BIN_DIR) + "/sculpt"; }

int RunSculpt(const std::string& args, const fs::path& log) {
  const std::string cmd = Bin() + " " + args + " > " + log.string() + " 2>&1";
  return std::system(cmd.c_str());
}

class DemoCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_demo_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(DemoCliTest, DemoWritesVdbMeshAndSummary) {
  const fs::path out = dir_ / "out";
  ASSERT_EQ(RunSculpt("demo --out " + out.string() + " --strokes 60", dir_ / "log.txt"), 0);
  ASSERT_TRUE(fs::exists(out / "sculpture.vdb"));
  ASSERT_TRUE(fs::exists(out / "sculpture.ply"));
  std::ifstream in(out / "summary.json");
  nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["edits"].get<int>(), 60 + 5);
  const double v0 = j["volume_before"].get<double>();
  const double v1 = j["volume_after"].get<double>();
  EXPECT_GT(v0, 0);
  EXPECT_NEAR(j["volume_after_recomputed"].get<double>(), v1, 1e-6 * v1);
  EXPECT_LT(std::abs(j["press_volume_drift_rel"].get<double>()), 5e-4);
  EXPECT_EQ(j["level_set_check"].get<std::string>(), "clean");
  EXPECT_GT(j["mesh"]["triangles"].get<uint64_t>(), 1000u);
  EXPECT_NE(j["state_hash"], j["state_hash_before"]);

  // The written .vdb reloads to the same state the summary names.
  auto s = sculpt::levelset::Sculpture::LoadVdb((out / "sculpture.vdb").string());
  ASSERT_TRUE(s.ok()) << s.status();
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(s->StateHash()));
  EXPECT_EQ(j["state_hash"].get<std::string>(), hex);

  // And `sculpt info` / `sculpt export` work on it.
  ASSERT_EQ(RunSculpt("info " + (out / "sculpture.vdb").string(), dir_ / "info.txt"), 0);
  std::ifstream info(dir_ / "info.txt");
  nlohmann::json ji = nlohmann::json::parse(info);
  EXPECT_EQ(ji["state_hash"].get<std::string>(), hex);
  EXPECT_FALSE(ji.contains("mesh"));
  // --mesh-stats: the mesh viewers get, counted. The demo's sculpture is one closed piece,
  // wound outward, enclosing the tracked volume.
  ASSERT_EQ(RunSculpt("info --mesh-stats " + (out / "sculpture.vdb").string(),
                      dir_ / "stats.txt"),
            0);
  std::ifstream stats(dir_ / "stats.txt");
  nlohmann::json jm = nlohmann::json::parse(stats)["mesh"];
  EXPECT_EQ(jm["boundary_edges"].get<uint64_t>(), 0u) << jm.dump();
  EXPECT_EQ(jm["non_manifold_edges"].get<uint64_t>(), 0u) << jm.dump();
  EXPECT_EQ(jm["inconsistent_edges"].get<uint64_t>(), 0u) << jm.dump();
  EXPECT_GE(jm["components"].get<uint64_t>(), 1u);
  EXPECT_NEAR(jm["signed_volume_over_tracked"].get<double>(), 1.0, 0.01) << jm.dump();
  ASSERT_EQ(RunSculpt("export " + (out / "sculpture.vdb").string() + " --out " +
                    (dir_ / "m.obj").string(),
                dir_ / "export.txt"),
            0);
  EXPECT_GT(fs::file_size(dir_ / "m.obj"), 10000u);
}

TEST_F(DemoCliTest, DemoIsDeterministic) {
  ASSERT_EQ(RunSculpt("demo --strokes 30 --out " + (dir_ / "a").string(), dir_ / "a.txt"), 0);
  ASSERT_EQ(RunSculpt("demo --strokes 30 --out " + (dir_ / "b").string(), dir_ / "b.txt"), 0);
  std::ifstream a(dir_ / "a" / "summary.json"), b(dir_ / "b" / "summary.json");
  EXPECT_EQ(nlohmann::json::parse(a)["state_hash"], nlohmann::json::parse(b)["state_hash"]);
}

TEST_F(DemoCliTest, RejectsBadFlagsWithHelpfulErrors) {
  EXPECT_NE(RunSculpt("demo --voxel-size 0", dir_ / "bad.txt"), 0);
  std::ifstream bad(dir_ / "bad.txt");
  std::string text((std::istreambuf_iterator<char>(bad)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("voxel-size"), std::string::npos) << text;
  EXPECT_NE(RunSculpt("info " + (dir_ / "missing.vdb").string(), dir_ / "missing.txt"), 0);
  EXPECT_EQ(RunSculpt("--help", dir_ / "help.txt"), 0);
  EXPECT_EQ(RunSculpt("demo --help", dir_ / "help2.txt"), 0);
}

}  // namespace
