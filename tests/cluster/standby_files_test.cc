// The standby copy on disk (cluster/standby_follower.h): which generation is complete, and the
// promotion that makes it the data directory without deleting what was there.
#include <gtest/gtest.h>

#include <fstream>

#include "cluster/processes.h"
#include "cluster/standby_follower.h"

namespace sculpt::server::cluster {
namespace {

namespace fs = std::filesystem;

void Touch(const fs::path& p, const std::string& text = "x") {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

std::string Read(const fs::path& p) {
  std::ifstream in(p);
  std::string s;
  std::getline(in, s);
  return s;
}

class StandbyFilesTest : public ::testing::Test {
 protected:
  std::string data() const { return (dir_.path() / "data").string(); }
  fs::path standby() const { return StandbyDir(data(), "default"); }
  sculpt::testing::TempDir dir_{"sculpt-standby-files"};
};

TEST_F(StandbyFilesTest, OnlyACompleteGenerationNamedByCurrentCounts) {
  EXPECT_FALSE(CurrentStandbyCopy(data(), "default").has_value());
  fs::create_directories(standby() / "gen-2" / "snapshots");
  EXPECT_FALSE(CurrentStandbyCopy(data(), "default").has_value()) << "no CURRENT yet";
  Touch(standby() / "CURRENT", "gen-2 5\n");
  uint64_t epoch = 0;
  auto copy = CurrentStandbyCopy(data(), "default", &epoch);
  ASSERT_TRUE(copy.has_value());
  EXPECT_EQ(fs::path(*copy), standby() / "gen-2");
  EXPECT_EQ(epoch, 5u);
  Touch(standby() / "CURRENT", "gen-3 5\n");  // names a generation that is not there
  EXPECT_FALSE(CurrentStandbyCopy(data(), "default").has_value());
  Touch(standby() / "CURRENT", "gen-2/../../x 5\n");
  EXPECT_FALSE(CurrentStandbyCopy(data(), "default").has_value());
  EXPECT_FALSE(CurrentStandbyCopy(data(), "other").has_value());
}

TEST_F(StandbyFilesTest, PromotionMovesTheOldDataAsideAndTheCopyIn) {
  const fs::path root = data();
  Touch(root / "log" / "log-old.sclog", "old log");
  Touch(root / "snapshots" / "snap-old.vdb", "old snapshot");
  Touch(root / "resend.pb", "old table");
  Touch(standby() / "gen-4" / "snapshots" / "snap-new.vdb", "new snapshot");
  Touch(standby() / "gen-4" / "log" / "log-new.sclog", "new log");
  Touch(standby() / "CURRENT", "gen-4 7\n");

  ASSERT_TRUE(PromoteStandbyCopy(data(), "default", data(), 7).ok());
  EXPECT_EQ(Read(root / "snapshots" / "snap-new.vdb"), "new snapshot");
  EXPECT_EQ(Read(root / "log" / "log-new.sclog"), "new log");
  EXPECT_FALSE(fs::exists(root / "resend.pb")) << "the old owner's files must not mix in";
  EXPECT_FALSE(fs::exists(root / "log" / "log-old.sclog"));
  EXPECT_FALSE(fs::exists(standby()));
  // Nothing deleted: the old directory is under superseded/<epoch>-<ms>/.
  std::vector<fs::path> aside;
  for (const auto& e : fs::directory_iterator(root / "superseded")) aside.push_back(e.path());
  ASSERT_EQ(aside.size(), 1u);
  EXPECT_EQ(aside[0].filename().string().rfind("7-", 0), 0u) << aside[0];
  EXPECT_EQ(Read(aside[0] / "log" / "log-old.sclog"), "old log");
  EXPECT_EQ(Read(aside[0] / "resend.pb"), "old table");

  EXPECT_EQ(PromotedFromEpoch(data(), "default"), std::optional<uint64_t>(7));
  EXPECT_FALSE(PromotedFromEpoch(data(), "other").has_value());
  ClearPromotedMarker(data());
  EXPECT_FALSE(PromotedFromEpoch(data(), "default").has_value());
}

TEST_F(StandbyFilesTest, PromotionWithoutACopyChangesNothing) {
  const fs::path root = data();
  Touch(root / "log" / "log-old.sclog", "old log");
  const Status s = PromoteStandbyCopy(data(), "default", data(), 1);
  EXPECT_EQ(s.code(), Status::Code::kFailedPrecondition) << s;
  EXPECT_EQ(Read(root / "log" / "log-old.sclog"), "old log");
  EXPECT_FALSE(fs::exists(root / "superseded"));
  EXPECT_FALSE(PromotedFromEpoch(data(), "default").has_value());
}

}  // namespace
}  // namespace sculpt::server::cluster

namespace sculpt::server::cluster {
namespace {

// A member hosting several scenes: a copy is promoted into its own scene's directory; the
// member's other scenes (`scenes/`) and its other copies (`standby/`) stay where they are, also
// when the promoted scene is the configured one whose directory holds them.
TEST_F(StandbyFilesTest, PromotionIntoAHostedScenesDirectoryLeavesTheOtherScenes) {
  const fs::path root = data();
  const fs::path pot = root / "scenes" / "pot";
  Touch(root / "log" / "log-main.sclog", "main log");
  Touch(pot / "log" / "log-pot.sclog", "pot log");
  Touch(root / "scenes" / "urn" / "log" / "log-urn.sclog", "urn log");
  Touch(fs::path(StandbyDir(data(), "pot")) / "gen-1" / "snapshots" / "snap-pot.vdb", "pot copy");
  Touch(fs::path(StandbyDir(data(), "pot")) / "CURRENT", "gen-1 3\n");
  Touch(fs::path(StandbyDir(data(), "urn")) / "gen-2" / "snapshots" / "snap-urn.vdb", "urn copy");
  Touch(fs::path(StandbyDir(data(), "urn")) / "CURRENT", "gen-2 4\n");

  ASSERT_TRUE(PromoteStandbyCopy(data(), "pot", pot.string(), 3).ok());
  EXPECT_EQ(Read(pot / "snapshots" / "snap-pot.vdb"), "pot copy");
  EXPECT_FALSE(fs::exists(pot / "log" / "log-pot.sclog"));
  EXPECT_EQ(PromotedFromEpoch(pot.string(), "pot"), std::optional<uint64_t>(3));
  EXPECT_FALSE(PromotedFromEpoch(data(), "pot").has_value()) << "the marker is the scene's";
  EXPECT_EQ(Read(root / "log" / "log-main.sclog"), "main log");
  EXPECT_EQ(Read(root / "scenes" / "urn" / "log" / "log-urn.sclog"), "urn log");
  EXPECT_TRUE(CurrentStandbyCopy(data(), "urn").has_value());
  EXPECT_FALSE(fs::exists(StandbyDir(data(), "pot")));

  // The configured scene's copy into data(): scenes/ and standby/ are not moved aside.
  Touch(standby() / "gen-5" / "snapshots" / "snap-main.vdb", "main copy");
  Touch(standby() / "CURRENT", "gen-5 9\n");
  ASSERT_TRUE(PromoteStandbyCopy(data(), "default", data(), 9).ok());
  EXPECT_EQ(Read(root / "snapshots" / "snap-main.vdb"), "main copy");
  EXPECT_FALSE(fs::exists(root / "log" / "log-main.sclog"));
  EXPECT_EQ(Read(root / "scenes" / "urn" / "log" / "log-urn.sclog"), "urn log");
  EXPECT_EQ(Read(pot / "snapshots" / "snap-pot.vdb"), "pot copy");
  EXPECT_TRUE(CurrentStandbyCopy(data(), "urn").has_value());
  EXPECT_EQ(PromotedFromEpoch(data(), "default"), std::optional<uint64_t>(9));
  EXPECT_EQ(PromotedFromEpoch(pot.string(), "pot"), std::optional<uint64_t>(3));
}

}  // namespace
}  // namespace sculpt::server::cluster
