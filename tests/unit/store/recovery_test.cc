/// @brief Tests of Recover: snapshot plus log tail, per-object skipping, gaps, real edits.
#include "store/recovery.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sculpt/levelset/edit.h"

namespace sculpt::server::store {
namespace {

namespace fs = std::filesystem;
using levelset::Sculpture;

Sculpture SmallSphere() {
  levelset::SculptureOptions o;
  o.voxel_size = 1;
  auto s = Sculpture::MakeSphere(o, {0, 0, 0}, 6);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move(s).value();
}

// Test payloads: "<object> <free text>".
std::string Payload(const std::string& object, uint64_t seq) {
  return object + " edit " + std::to_string(seq);
}

StatusOr<std::string> RouteByFirstWord(const LogRecord& record) {
  const size_t space = record.payload.find(' ');
  if (space == std::string::npos || space == 0) {
    return DataLoss("payload of seq " + std::to_string(record.seq) + " names no object");
  }
  return record.payload.substr(0, space);
}

class RecoveryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = (fs::temp_directory_path() /
            ("sculpt_recovery_" + std::string(info->name()) + "_" + std::to_string(::getpid())))
               .string();
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string LogDir() const { return (fs::path(dir_) / kLogSubdir).string(); }
  std::string SnapDir() const { return (fs::path(dir_) / kSnapshotSubdir).string(); }

  // Appends records first..last; record seq goes to objects[seq % objects.size()].
  void WriteLog(uint64_t first, uint64_t last, const std::vector<std::string>& objects,
                uint64_t segment_bytes = kDefaultSegmentBytes) {
    EditLogOptions options;
    options.fsync.mode = FsyncPolicy::Mode::kGroup;
    options.segment_bytes = segment_bytes;
    auto log = EditLog::Open(LogDir(), options, nullptr);
    ASSERT_TRUE(log.ok()) << log.status();
    for (uint64_t seq = first; seq <= last; ++seq) {
      ASSERT_TRUE((*log)->Append(seq, Payload(objects[seq % objects.size()], seq)).ok());
    }
  }

  void WriteSnapshot(uint64_t seq, const std::string& object, const Sculpture& s) {
    auto store = SnapshotStore::Open(SnapDir());
    ASSERT_TRUE(store.ok()) << store.status();
    ASSERT_TRUE((*store)->Write(seq, object, s).ok());
  }

  // Appends records first.. to object "ball", record i with epochs[i] ("ball edit <seq> e<epoch>").
  void WriteEpochLog(uint64_t first, const std::vector<uint64_t>& epochs) {
    auto log = EditLog::Open(LogDir(), FsyncPolicy{}, nullptr);
    ASSERT_TRUE(log.ok()) << log.status();
    for (size_t i = 0; i < epochs.size(); ++i) {
      ASSERT_TRUE(
          (*log)->Append(first + i, Payload("ball", first + i) + " e" + std::to_string(epochs[i]))
              .ok());
    }
  }

  // Recover with a fake apply that records (object, seq) and leaves the sculpture alone; with
  // `epochs`, every record's epoch is read from the number after " e" (0 without one).
  StatusOr<RecoveredScene> RecoverRecording(const std::vector<std::string>& objects,
                                            bool epochs = false) {
    RecoveryOptions options;
    options.objects = objects;
    if (epochs) {
      options.epoch_of = [](const LogRecord& record) -> StatusOr<uint64_t> {
        const std::string last = record.payload.substr(record.payload.rfind(' ') + 1);
        if (last.empty() || last[0] != 'e') return 0;
        if (last == "ebad") return DataLoss("epoch does not parse");
        return std::stoull(last.substr(1));
      };
    }
    return Recover(
        dir_, options,
        [&](const std::string& object) -> StatusOr<Sculpture> {
          initial_.push_back(object);
          return SmallSphere();
        },
        RouteByFirstWord,
        [&](Sculpture&, const LogRecord& record) {
          applied_.emplace_back(RouteByFirstWord(record).value(), record.seq);
          return Status::Ok();
        });
  }

  std::string dir_;
  std::vector<std::string> initial_;
  std::vector<std::pair<std::string, uint64_t>> applied_;
};

TEST_F(RecoveryTest, ReplaysExactlyTheRecordsAfterTheSnapshot) {
  WriteSnapshot(50, "ball", SmallSphere());
  WriteLog(1, 80, {"ball"});
  auto scene = RecoverRecording({"ball"});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_TRUE(initial_.empty());
  ASSERT_EQ(applied_.size(), 30u);
  for (size_t i = 0; i < applied_.size(); ++i) EXPECT_EQ(applied_[i].second, 51 + i);
  EXPECT_EQ(scene->last_seq, 80u);
  EXPECT_EQ(scene->snapshot_seq.at("ball"), 50u);
  EXPECT_EQ(scene->report.replayed_records, 30u);
  EXPECT_EQ(scene->report.records, 80u);
  ASSERT_NE(scene->log, nullptr);
  EXPECT_TRUE(scene->log->Append(81, Payload("ball", 81)).ok()) << "the log continues";
}

TEST_F(RecoveryTest, BuildsInitialObjectsWithoutSnapshots) {
  WriteLog(1, 10, {"ball"});
  auto scene = RecoverRecording({"ball"});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(initial_, (std::vector<std::string>{"ball"}));
  EXPECT_EQ(applied_.size(), 10u);
  EXPECT_EQ(scene->snapshot_seq.at("ball"), 0u);
  EXPECT_EQ(scene->last_seq, 10u);
}

TEST_F(RecoveryTest, NewDataDirectoryGivesTheInitialScene) {
  auto scene = RecoverRecording({"a", "b"});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(initial_, (std::vector<std::string>{"a", "b"}));
  EXPECT_TRUE(applied_.empty());
  EXPECT_EQ(scene->last_seq, 0u);
  EXPECT_EQ(scene->sculptures.size(), 2u);
  EXPECT_TRUE(fs::is_directory(LogDir()));
  EXPECT_TRUE(fs::is_directory(SnapDir()));
}

TEST_F(RecoveryTest, SkipsRecordsEachObjectsSnapshotHolds) {
  WriteSnapshot(50, "a", SmallSphere());
  WriteSnapshot(30, "b", SmallSphere());
  WriteLog(1, 80, {"a", "b"});  // even seqs edit a, odd seqs edit b
  auto scene = RecoverRecording({"a", "b"});
  ASSERT_TRUE(scene.ok()) << scene.status();
  size_t a = 0, b = 0;
  for (const auto& [object, seq] : applied_) {
    if (object == "a") {
      EXPECT_GT(seq, 50u);
      ++a;
    } else {
      EXPECT_GT(seq, 30u);
      ++b;
    }
  }
  EXPECT_EQ(a, 15u);  // 52, 54, ..., 80
  EXPECT_EQ(b, 25u);  // 31, 33, ..., 79
  for (size_t i = 1; i < applied_.size(); ++i) {
    EXPECT_LT(applied_[i - 1].second, applied_[i].second);
  }
}

TEST_F(RecoveryTest, FallsBackToAnOlderSnapshotWhenTheNewestDoesNotLoad) {
  WriteSnapshot(50, "ball", SmallSphere());
  WriteLog(1, 80, {"ball"});
  {
    std::ofstream out(fs::path(SnapDir()) / "snap-00000000000000000070-ball.vdb", std::ios::binary);
    out << "cut short by a power loss";
  }
  auto scene = RecoverRecording({"ball"});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->snapshot_seq.at("ball"), 50u);
  EXPECT_EQ(applied_.size(), 30u);
  EXPECT_EQ(scene->report.skipped_snapshots.size(), 1u);
}

TEST_F(RecoveryTest, RefusesASnapshotOlderThanTheStartOfTheLog) {
  WriteSnapshot(30, "ball", SmallSphere());
  // Two records per segment; segments up to seq 40 were dropped after a (now lost) snapshot.
  WriteLog(1, 80, {"ball"}, kSegmentHeaderBytes + 2 * (kRecordHeaderBytes + 13));
  {
    auto log = EditLog::Open(LogDir(), FsyncPolicy{}, nullptr);
    ASSERT_TRUE(log.ok());
    ASSERT_TRUE((*log)->DropSegmentsBefore(40).ok());
    ASSERT_EQ((*log)->base_seq(), 40u);
  }
  auto scene = RecoverRecording({"ball"});
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(scene.status().message().find("seq 30"), std::string::npos) << scene.status();
  EXPECT_NE(scene.status().message().find("after seq 40"), std::string::npos) << scene.status();
}

TEST_F(RecoveryTest, RefusesATrimmedLogWithoutSnapshots) {
  WriteLog(1, 80, {"ball"}, kSegmentHeaderBytes + 2 * (kRecordHeaderBytes + 13));
  {
    auto log = EditLog::Open(LogDir(), FsyncPolicy{}, nullptr);
    ASSERT_TRUE(log.ok());
    ASSERT_TRUE((*log)->DropSegmentsBefore(40).ok());
  }
  auto scene = RecoverRecording({"ball"});
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(scene.status().message().find("no usable snapshot"), std::string::npos)
      << scene.status();
}

TEST_F(RecoveryTest, RefusesARecordForAnObjectTheSceneLacks) {
  WriteLog(1, 10, {"ball", "gone"});
  auto scene = RecoverRecording({"ball"});
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(scene.status().message().find("\"gone\""), std::string::npos) << scene.status();
}

TEST_F(RecoveryTest, ApplyErrorStopsRecoveryNamingTheRecord) {
  WriteLog(1, 10, {"ball"});
  RecoveryOptions options;
  options.objects = {"ball"};
  auto scene = Recover(
      dir_, options, [](const std::string&) -> StatusOr<Sculpture> { return SmallSphere(); },
      RouteByFirstWord,
      [](Sculpture&, const LogRecord& record) {
        return record.seq == 7 ? DataLoss("payload does not parse") : Status::Ok();
      });
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(scene.status().message().find("seq 7 on object ball"), std::string::npos)
      << scene.status();
}

TEST_F(RecoveryTest, RefusesALogWhoseEpochGoesBackwardsAndKeepsEveryRecord) {
  // Epoch 2 took over at seq 3; seq 5 was written by the stale owner of epoch 1.
  WriteEpochLog(1, {1, 1, 2, 2, 1, 2});
  auto scene = RecoverRecording({"ball"}, /*epochs=*/true);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), Status::Code::kDataLoss);
  const std::string why(scene.status().message());
  EXPECT_NE(why.find("record seq 5 has epoch 1, lower than epoch 2 of seq 3 before it"),
            std::string::npos)
      << why;
  EXPECT_NE(why.find("stale owner"), std::string::npos) << why;
  EXPECT_NE(why.find(LogDir()), std::string::npos) << why;
  // Nothing from the stale record on was applied ...
  ASSERT_EQ(applied_.size(), 4u);
  EXPECT_EQ(applied_.back().second, 4u);
  // ... and nothing was cut: every record, acknowledged or not, is still in the log.
  RecoveryReport report;
  auto log = EditLog::Open(LogDir(), FsyncPolicy{}, &report);
  ASSERT_TRUE(log.ok()) << log.status();
  EXPECT_EQ(report.records, 6u);
  EXPECT_EQ((*log)->last_seq(), 6u);
}

TEST_F(RecoveryTest, RefusesABackwardEpochBeforeTheSnapshotsToo) {
  WriteSnapshot(8, "ball", SmallSphere());
  WriteEpochLog(1, {3, 3, 4, 3, 4, 4, 4, 4, 4, 4});
  auto scene = RecoverRecording({"ball"}, /*epochs=*/true);
  ASSERT_FALSE(scene.ok());
  EXPECT_NE(scene.status().message().find("record seq 4 has epoch 3, lower than epoch 4 of seq 3"),
            std::string::npos)
      << scene.status();
  EXPECT_TRUE(applied_.empty()) << "the tail past the snapshot was replayed";
}

TEST_F(RecoveryTest, AcceptsEpochsThatNeverGoDownAndSaysWhereEachBegins) {
  WriteSnapshot(3, "ball", SmallSphere());
  WriteEpochLog(1, {0, 0, 3, 3, 5, 5, 5});  // a single process's records, then two owners
  auto scene = RecoverRecording({"ball"}, /*epochs=*/true);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->highest_epoch, 5u);
  EXPECT_EQ(scene->epoch_runs, (std::map<uint64_t, uint64_t>{{1, 0}, {3, 3}, {5, 5}}));
  ASSERT_EQ(applied_.size(), 4u) << "only the tail past the snapshot is applied";
  EXPECT_EQ(applied_.front().second, 4u);
}

TEST_F(RecoveryTest, EpochZeroIsNoOwnershipAndNeverRefused) {
  // Alone, then in a cluster at epochs 3 and 4, then alone again, then in the cluster at 4.
  WriteEpochLog(1, {0, 3, 4, 0, 0, 4});
  auto scene = RecoverRecording({"ball"}, /*epochs=*/true);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(applied_.size(), 6u);
  EXPECT_EQ(scene->highest_epoch, 4u);
  EXPECT_EQ(scene->epoch_runs,
            (std::map<uint64_t, uint64_t>{{1, 0}, {2, 3}, {3, 4}, {4, 0}, {6, 4}}));
  applied_.clear();
  scene->log.reset();        // closes the log
  WriteEpochLog(7, {3});     // but a lower nonzero epoch after them is a stale owner's
  auto refused = RecoverRecording({"ball"}, /*epochs=*/true);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("record seq 7 has epoch 3, lower than epoch 4 of seq 3"),
            std::string::npos)
      << refused.status();
}

TEST_F(RecoveryTest, WithoutEpochsAnyOrderIsReplayed) {
  WriteEpochLog(1, {2, 1});  // no epoch_of: the store never looks inside a payload
  auto scene = RecoverRecording({"ball"});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(applied_.size(), 2u);
  EXPECT_TRUE(scene->epoch_runs.empty());
  EXPECT_EQ(scene->highest_epoch, 0u);
}

TEST_F(RecoveryTest, EpochThatDoesNotReadStopsRecoveryNamingTheRecord) {
  auto log = EditLog::Open(LogDir(), FsyncPolicy{}, nullptr);
  ASSERT_TRUE(log.ok()) << log.status();
  ASSERT_TRUE((*log)->Append(1, "ball edit 1 e1").ok());
  ASSERT_TRUE((*log)->Append(2, "ball edit 2 ebad").ok());
  log->reset();
  auto scene = RecoverRecording({"ball"}, /*epochs=*/true);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(scene.status().message().find("epoch of edit log record seq 2"), std::string::npos)
      << scene.status();
}

TEST_F(RecoveryTest, RejectsOptionsWithoutObjects) {
  auto scene = RecoverRecording({});
  EXPECT_EQ(scene.status().code(), Status::Code::kInvalidArgument);
  auto twice = RecoverRecording({"a", "a"});
  EXPECT_EQ(twice.status().code(), Status::Code::kInvalidArgument);
}

TEST_F(RecoveryTest, EmptyLogContinuesAfterTheSnapshots) {
  WriteSnapshot(50, "a", SmallSphere());
  WriteSnapshot(40, "b", SmallSphere());
  {
    auto scene = RecoverRecording({"a", "b"});
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_EQ(scene->last_seq, 50u);
    EXPECT_EQ(scene->log->base_seq(), 40u);
    ASSERT_TRUE(scene->log->Append(51, Payload("b", 51)).ok());
  }
  applied_.clear();
  auto again = RecoverRecording({"a", "b"});
  ASSERT_TRUE(again.ok()) << again.status();
  ASSERT_EQ(applied_.size(), 1u);
  EXPECT_EQ(applied_[0], (std::pair<std::string, uint64_t>{"b", 51}));
  EXPECT_EQ(again->last_seq, 51u);
}

// A press encoded in the payload: "ball x y z r".
levelset::EditRequest PressAt(double x, double y, double z, double r) {
  levelset::EditRequest e;
  e.kind = levelset::EditKind::kPress;
  e.tool = levelset::ToolShape::Sphere({x, y, z}, r);
  e.speed = 10;
  e.dt = 0.05;
  return e;
}

std::string EncodePress(const levelset::EditRequest& e) {
  std::ostringstream os;
  os.precision(17);
  os << "ball " << e.tool.center.x << ' ' << e.tool.center.y << ' ' << e.tool.center.z << ' '
     << e.tool.size.x;
  return os.str();
}

StatusOr<levelset::EditRequest> DecodePress(const std::string& payload) {
  std::istringstream is(payload);
  std::string object;
  double x, y, z, r;
  if (!(is >> object >> x >> y >> z >> r)) return DataLoss("bad press payload: " + payload);
  return PressAt(x, y, z, r);
}

TEST_F(RecoveryTest, RecoveredStateMatchesApplyingTheSameEditsInMemory) {
  const levelset::EditSettings settings;
  std::vector<levelset::EditRequest> edits;
  for (int i = 0; i < 8; ++i) {
    const double angle = 0.7 * i;
    edits.push_back(
        PressAt(7.0 * std::cos(angle), 7.0 * std::sin(angle), 0.5 * (i % 3) - 0.5, 2.0));
  }

  Sculpture reference = SmallSphere();
  const uint64_t initial_hash = reference.StateHash();
  for (const auto& e : edits) ASSERT_TRUE(levelset::ApplyEdit(reference, e, settings).ok());
  ASSERT_NE(reference.StateHash(), initial_hash);

  // The live server: log each edit, apply it, snapshot after seq 4, keep going to seq 8.
  uint64_t snapshot_hash = 0;
  {
    auto log = EditLog::Open(LogDir(), FsyncPolicy{FsyncPolicy::Mode::kAlways, 5}, nullptr);
    ASSERT_TRUE(log.ok()) << log.status();
    auto store = SnapshotStore::Open(SnapDir());
    ASSERT_TRUE(store.ok()) << store.status();
    Sculpture live = SmallSphere();
    for (uint64_t seq = 1; seq <= edits.size(); ++seq) {
      ASSERT_TRUE((*log)->Append(seq, EncodePress(edits[seq - 1])).ok());
      ASSERT_TRUE(levelset::ApplyEdit(live, edits[seq - 1], settings).ok());
      if (seq == 4) {
        snapshot_hash = live.StateHash();
        (*store)->WriteAsync(seq, "ball", live.Clone(), nullptr);
        (*log)->Roll();
      }
    }
    ASSERT_TRUE((*store)->WaitIdle().ok());
    ASSERT_EQ(live.StateHash(), reference.StateHash());
  }

  RecoveryOptions options;
  options.objects = {"ball"};
  auto scene = Recover(
      dir_, options, [](const std::string&) -> StatusOr<Sculpture> { return SmallSphere(); },
      RouteByFirstWord,
      [&](Sculpture& sculpture, const LogRecord& record) -> Status {
        SCULPT_ASSIGN_OR_RETURN(levelset::EditRequest e, DecodePress(record.payload));
        auto result = levelset::ApplyEdit(sculpture, e, settings);
        return result.ok() ? Status::Ok() : result.status();
      });
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->snapshot_seq.at("ball"), 4u);
  EXPECT_EQ(scene->report.replayed_records, 4u);
  EXPECT_EQ(scene->last_seq, 8u);
  const Sculpture& recovered = scene->sculptures.at("ball");
  EXPECT_NE(recovered.StateHash(), snapshot_hash);
  EXPECT_EQ(recovered.StateHash(), reference.StateHash());
  EXPECT_NEAR(recovered.volume(), reference.volume(), 1e-9 * reference.volume());
}

// Seeded damage to the newest snapshot: every bit of its header flipped in turn, then random bit
// flips in its grid bytes and random truncations. Start-up never crashes, names the file, and
// falls back to the previous snapshot plus the longer log tail.
TEST_F(RecoveryTest, FallsBackFromEveryDamagedNewestSnapshot) {
  levelset::SculptureOptions o;
  o.voxel_size = 1;
  const Sculpture older = SmallSphere();
  const Sculpture newer = Sculpture::MakeSphere(o, {0, 0, 0}, 7).value();
  WriteSnapshot(10, "ball", older);
  WriteSnapshot(20, "ball", newer);
  WriteLog(1, 30, {"ball"});
  const fs::path newest = fs::path(SnapDir()) / "snap-00000000000000000020-ball.vdb";
  std::string pristine;
  {
    std::ifstream in(newest, std::ios::binary);
    pristine.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(pristine.size(), 100u);
  std::vector<std::string> damaged;
  for (size_t bit = 0; bit < 40 * 8; ++bit) {  // the whole 40-byte header
    std::string d = pristine;
    d[bit / 8] = static_cast<char>(d[bit / 8] ^ (1 << (bit % 8)));
    damaged.push_back(std::move(d));
  }
  std::mt19937_64 rng(20261123);
  for (int i = 0; i < 120; ++i) {
    std::string d = pristine;
    const size_t bit = 40 * 8 + rng() % ((pristine.size() - 40) * 8);
    d[bit / 8] = static_cast<char>(d[bit / 8] ^ (1 << (bit % 8)));
    damaged.push_back(std::move(d));
  }
  for (int i = 0; i < 60; ++i) damaged.push_back(pristine.substr(0, rng() % pristine.size()));
  for (size_t n : {size_t{0}, size_t{7}, size_t{8}, size_t{39}, size_t{40}, size_t{41}}) {
    damaged.push_back(pristine.substr(0, n));
  }
  for (size_t i = 0; i < damaged.size(); ++i) {
    {
      std::ofstream out(newest, std::ios::binary | std::ios::trunc);
      out << damaged[i];
    }
    // Every damage is caught by the file's checks, before OpenVDB parses anything.
    auto direct = LoadSnapshotFile(newest.string(), 20);
    ASSERT_FALSE(direct.ok()) << "damage " << i << " went unnoticed";
    EXPECT_NE(direct.status().message().find(newest.string()), std::string::npos)
        << direct.status();
    if (i % 8 != 0) continue;  // the whole start-up for a sample (each loads the older file)
    applied_.clear();
    auto scene = RecoverRecording({"ball"});
    ASSERT_TRUE(scene.ok()) << "damage " << i << ": " << scene.status();
    ASSERT_EQ(scene->snapshot_seq.at("ball"), 10u) << "damage " << i;
    EXPECT_EQ(scene->sculptures.at("ball").StateHash(), older.StateHash()) << "damage " << i;
    ASSERT_EQ(applied_.size(), 20u) << "damage " << i << ": the tail after seq 10 is replayed";
    EXPECT_EQ(applied_.front().second, 11u);
    ASSERT_EQ(scene->report.skipped_snapshots.size(), 1u) << "damage " << i;
    EXPECT_NE(scene->report.skipped_snapshots[0].find(newest.string()), std::string::npos)
        << scene->report.skipped_snapshots[0];
  }
}

}  // namespace
}  // namespace sculpt::server::store
