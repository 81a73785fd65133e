/// @brief Tests of SnapshotStore: write/load newest, retention, async coalescing, bad files.
#include "store/snapshot_store.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <condition_variable>
#include <filesystem>
#include <boost/crc.hpp>
#include <cstring>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

namespace sculpt::server::store {
namespace {

namespace fs = std::filesystem;
using levelset::Sculpture;

Sculpture Sphere(double radius) {
  levelset::SculptureOptions o;
  o.voxel_size = 1;
  auto s = Sculpture::MakeSphere(o, {0, 0, 0}, radius);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move(s).value();
}

// Blocks the writer thread inside a `done` callback until Release().
class Gate {
 public:
  void WaitEntered() {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return entered_; });
  }
  void Block() {
    std::unique_lock<std::mutex> lock(mu_);
    entered_ = true;
    cv_.notify_all();
    cv_.wait(lock, [&] { return released_; });
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mu_);
    released_ = true;
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool entered_ = false;
  bool released_ = false;
};

class SnapshotStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = (fs::temp_directory_path() /
            ("sculpt_snapshots_" + std::string(info->name()) + "_" + std::to_string(::getpid())))
               .string();
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::unique_ptr<SnapshotStore> OpenOrDie(SnapshotStoreOptions options = {}) {
    auto store = SnapshotStore::Open(dir_, options);
    EXPECT_TRUE(store.ok()) << store.status();
    return store.ok() ? std::move(store).value() : nullptr;
  }

  std::vector<uint64_t> SeqsOf(SnapshotStore& store, const std::string& object) {
    std::vector<uint64_t> seqs;
    auto files = store.List();
    EXPECT_TRUE(files.ok()) << files.status();
    if (!files.ok()) return seqs;
    for (const auto& f : *files) {
      if (f.object == object) seqs.push_back(f.seq);
    }
    return seqs;
  }

  void WriteGarbage(const std::string& name) {
    std::ofstream out(fs::path(dir_) / name, std::ios::binary);
    out << "not a vdb file";
  }

  std::string dir_;
};

TEST_F(SnapshotStoreTest, WritesAndLoadsTheNewestPerObject) {
  auto store = OpenOrDie();
  const Sculpture small = Sphere(4);
  const Sculpture big = Sphere(6);
  ASSERT_TRUE(store->Write(10, "ball", small).ok());
  ASSERT_TRUE(store->Write(20, "ball", big).ok());
  ASSERT_TRUE(store->Write(15, "cube-1", small).ok());
  EXPECT_TRUE(fs::exists(fs::path(dir_) / "snap-00000000000000000020-ball.vdb"));

  auto loaded = store->LoadNewest();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 2u);
  EXPECT_EQ((*loaded)[0].object, "ball");
  EXPECT_EQ((*loaded)[0].seq, 20u);
  EXPECT_EQ((*loaded)[0].sculpture.StateHash(), big.StateHash());
  EXPECT_EQ((*loaded)[1].object, "cube-1");
  EXPECT_EQ((*loaded)[1].seq, 15u);
  EXPECT_EQ((*loaded)[1].sculpture.StateHash(), small.StateHash());
}

TEST_F(SnapshotStoreTest, KeepsTheNewestKPerObject) {
  SnapshotStoreOptions options;
  options.keep = 3;
  auto store = OpenOrDie(options);
  const Sculpture s = Sphere(4);
  for (uint64_t seq = 1; seq <= 5; ++seq) ASSERT_TRUE(store->Write(seq * 10, "a", s).ok());
  ASSERT_TRUE(store->Write(7, "b", s).ok());
  EXPECT_EQ(SeqsOf(*store, "a"), (std::vector<uint64_t>{30, 40, 50}));
  EXPECT_EQ(SeqsOf(*store, "b"), (std::vector<uint64_t>{7}));
}

TEST_F(SnapshotStoreTest, WriteAsyncCoalescesQueuedSnapshots) {
  auto store = OpenOrDie();
  Gate gate;
  std::mutex mu;
  std::vector<std::pair<uint64_t, Status>> results;
  auto record = [&](uint64_t seq) {
    return [&, seq](Status s) {
      std::lock_guard<std::mutex> lock(mu);
      results.emplace_back(seq, s);
    };
  };
  const Sculpture s = Sphere(4);
  store->WriteAsync(1, "ball", s.Clone(), [&](Status st) {
    record(1)(st);
    gate.Block();  // the writer is busy with seq 1 while 2..5 arrive
  });
  gate.WaitEntered();
  for (uint64_t seq = 2; seq <= 5; ++seq) store->WriteAsync(seq, "ball", s.Clone(), record(seq));
  {
    // 2, 3 and 4 were replaced in the queue at once; nothing else is held.
    std::lock_guard<std::mutex> lock(mu);
    ASSERT_EQ(results.size(), 4u);
    for (size_t i = 1; i < 4; ++i) {
      EXPECT_EQ(results[i].first, i + 1);
      EXPECT_EQ(results[i].second.code(), Status::Code::kUnavailable) << results[i].second;
      EXPECT_NE(results[i].second.message().find("superseded"), std::string::npos);
    }
  }
  EXPECT_EQ(store->superseded(), 3u);
  gate.Release();
  ASSERT_TRUE(store->WaitIdle().ok());
  EXPECT_EQ(store->async_writes(), 2u) << "only the one in progress and the last one";
  EXPECT_EQ(SeqsOf(*store, "ball"), (std::vector<uint64_t>{1, 5}));
  std::lock_guard<std::mutex> lock(mu);
  ASSERT_EQ(results.size(), 5u);
  EXPECT_EQ(results.back().first, 5u);
  EXPECT_TRUE(results.back().second.ok()) << results.back().second;
}

TEST_F(SnapshotStoreTest, WriteAsyncQueuesOneSnapshotPerObject) {
  auto store = OpenOrDie();
  Gate gate;
  const Sculpture s = Sphere(4);
  store->WriteAsync(1, "a", s.Clone(), [&](Status) { gate.Block(); });
  gate.WaitEntered();
  store->WriteAsync(2, "a", s.Clone(), nullptr);
  store->WriteAsync(2, "b", s.Clone(), nullptr);  // another object is not coalesced with "a"
  store->WriteAsync(3, "c", s.Clone(), nullptr);
  gate.Release();
  ASSERT_TRUE(store->WaitIdle().ok());
  EXPECT_EQ(store->superseded(), 0u);
  EXPECT_EQ(SeqsOf(*store, "a"), (std::vector<uint64_t>{1, 2}));
  EXPECT_EQ(SeqsOf(*store, "b"), (std::vector<uint64_t>{2}));
  EXPECT_EQ(SeqsOf(*store, "c"), (std::vector<uint64_t>{3}));
}

TEST_F(SnapshotStoreTest, DestructorWritesQueuedSnapshots) {
  const Sculpture s = Sphere(4);
  {
    auto store = OpenOrDie();
    for (uint64_t seq = 1; seq <= 3; ++seq) store->WriteAsync(seq, "ball", s.Clone(), nullptr);
  }
  auto store = OpenOrDie();
  auto loaded = store->LoadNewest();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].seq, 3u);
}

TEST_F(SnapshotStoreTest, SkipsAnUnreadableNewestSnapshot) {
  auto store = OpenOrDie();
  const Sculpture s = Sphere(5);
  ASSERT_TRUE(store->Write(10, "ball", s).ok());
  WriteGarbage("snap-00000000000000000020-ball.vdb");
  std::vector<std::string> skipped;
  auto loaded = store->LoadNewest(&skipped);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].seq, 10u);
  EXPECT_EQ((*loaded)[0].sculpture.StateHash(), s.StateHash());
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_NE(skipped[0].find("snap-00000000000000000020-ball.vdb"), std::string::npos);
}

TEST_F(SnapshotStoreTest, RefusesWhenNoSnapshotOfAnObjectLoads) {
  auto store = OpenOrDie();
  WriteGarbage("snap-00000000000000000020-ball.vdb");
  auto loaded = store->LoadNewest();
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(loaded.status().message().find("ball"), std::string::npos) << loaded.status();
}

TEST_F(SnapshotStoreTest, FileStartsWithAChecksummedHeader) {
  auto store = OpenOrDie();
  ASSERT_TRUE(store->Write(20, "ball", Sphere(5)).ok());
  std::ifstream in(fs::path(dir_) / "snap-00000000000000000020-ball.vdb", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 40u);
  EXPECT_EQ(bytes.substr(0, 8), "SCLPSNAP");
  uint64_t seq = 0;
  uint64_t payload = 0;
  std::memcpy(&seq, bytes.data() + 16, 8);
  std::memcpy(&payload, bytes.data() + 24, 8);
  EXPECT_EQ(seq, 20u);
  EXPECT_EQ(payload, bytes.size() - 40);
}

// A forged header (checksum recomputed) claiming a payload far larger than the file: refused
// before anything is allocated.
TEST_F(SnapshotStoreTest, RejectsAPayloadSizeThatTheFileDoesNotHold) {
  auto store = OpenOrDie();
  ASSERT_TRUE(store->Write(20, "ball", Sphere(5)).ok());
  const fs::path path = fs::path(dir_) / "snap-00000000000000000020-ball.vdb";
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const uint64_t huge = 1ull << 44;
  std::memcpy(bytes.data() + 24, &huge, 8);
  boost::crc_optimal<32, 0x1EDC6F41, 0xFFFFFFFF, 0xFFFFFFFF, true, true> crc;
  crc.process_bytes(bytes.data(), 36);
  const uint32_t header_crc = crc.checksum();
  std::memcpy(bytes.data() + 36, &header_crc, 4);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  auto loaded = LoadSnapshotFile(path.string(), 20);
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(loaded.status().message().find("payload size=17592186044416"), std::string::npos)
      << loaded.status();
  // A cap below the real size refuses an undamaged file too.
  auto capped = LoadSnapshotFile(path.string(), 20, 16);
  EXPECT_EQ(capped.status().code(), Status::Code::kDataLoss);
}

TEST_F(SnapshotStoreTest, RejectsASnapshotWhoseNameAndHeaderDisagree) {
  auto store = OpenOrDie();
  ASSERT_TRUE(store->Write(20, "ball", Sphere(5)).ok());
  fs::rename(fs::path(dir_) / "snap-00000000000000000020-ball.vdb",
             fs::path(dir_) / "snap-00000000000000000030-ball.vdb");
  auto loaded =
      LoadSnapshotFile((fs::path(dir_) / "snap-00000000000000000030-ball.vdb").string(), 30);
  EXPECT_EQ(loaded.status().code(), Status::Code::kDataLoss);
}

TEST_F(SnapshotStoreTest, LoadsABareVdbWrittenBeforeChecksums) {
  const Sculpture s = Sphere(5);
  fs::create_directories(dir_);
  ASSERT_TRUE(s.SaveVdb((fs::path(dir_) / "snap-00000000000000000020-ball.vdb").string()).ok());
  auto store = OpenOrDie();
  auto loaded = store->LoadNewest();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].sculpture.StateHash(), s.StateHash());
}

TEST_F(SnapshotStoreTest, RejectsBadObjectName) {
  auto store = OpenOrDie();
  const Sculpture s = Sphere(4);
  Status bad = store->Write(1, "../escape", s);
  EXPECT_EQ(bad.code(), Status::Code::kInvalidArgument) << bad;
  EXPECT_EQ(store->Write(1, "", s).code(), Status::Code::kInvalidArgument);
  Status async_result;
  store->WriteAsync(2, "a/b", s.Clone(), [&](Status st) { async_result = st; });
  EXPECT_EQ(async_result.code(), Status::Code::kInvalidArgument) << async_result;
  EXPECT_EQ(store->WaitIdle().code(), Status::Code::kInvalidArgument);
  EXPECT_TRUE(store->WaitIdle().ok()) << "WaitIdle reports an error once";
}

TEST_F(SnapshotStoreTest, WaitIdleReportsAFailedWrite) {
  auto store = OpenOrDie();
  fs::remove_all(dir_);  // the directory vanished under the server
  Status result;
  store->WriteAsync(1, "ball", Sphere(4), [&](Status st) { result = st; });
  Status idle = store->WaitIdle();
  EXPECT_FALSE(idle.ok());
  EXPECT_FALSE(result.ok());
}

TEST_F(SnapshotStoreTest, RemovesLeftoversOfInterruptedWrites) {
  fs::create_directories(dir_);
  WriteGarbage("snap-00000000000000000020-ball.vdb.writing");
  WriteGarbage("snap-00000000000000000020-ball.vdb.writing.tmp");
  WriteGarbage("unrelated.txt");
  auto store = OpenOrDie();
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "snap-00000000000000000020-ball.vdb.writing"));
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "snap-00000000000000000020-ball.vdb.writing.tmp"));
  EXPECT_TRUE(fs::exists(fs::path(dir_) / "unrelated.txt"));
  auto loaded = store->LoadNewest();
  ASSERT_TRUE(loaded.ok());
  EXPECT_TRUE(loaded->empty());
}

}  // namespace
}  // namespace sculpt::server::store
