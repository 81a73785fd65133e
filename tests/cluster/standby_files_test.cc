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

  ASSERT_TRUE(PromoteStandbyCopy(data(), "default", 7).ok());
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
  const Status s = PromoteStandbyCopy(data(), "default", 1);
  EXPECT_EQ(s.code(), Status::Code::kFailedPrecondition) << s;
  EXPECT_EQ(Read(root / "log" / "log-old.sclog"), "old log");
  EXPECT_FALSE(fs::exists(root / "superseded"));
  EXPECT_FALSE(PromotedFromEpoch(data(), "default").has_value());
}

}  // namespace
}  // namespace sculpt::server::cluster
