/// @brief Tests of EditLog: round trips, torn tails, corruption, sequences, group commit, segments.
#include "store/edit_log.h"

#include <gtest/gtest.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/crc.hpp>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace sculpt::server::store {
namespace {

namespace fs = std::filesystem;
using Crc32c = boost::crc_optimal<32, 0x1EDC6F41, 0xFFFFFFFF, 0xFFFFFFFF, true, true>;

class EditLogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = (fs::temp_directory_path() /
            ("sculpt_edit_log_" + std::string(info->name()) + "_" + std::to_string(::getpid())))
               .string();
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static FsyncPolicy Always() { return {FsyncPolicy::Mode::kAlways, 5}; }
  static FsyncPolicy Group(int ms = 5) { return {FsyncPolicy::Mode::kGroup, ms}; }

  std::unique_ptr<EditLog> OpenOrDie(EditLogOptions options, RecoveryReport* report = nullptr) {
    auto log = EditLog::Open(dir_, options, report);
    EXPECT_TRUE(log.ok()) << log.status();
    return log.ok() ? std::move(log).value() : nullptr;
  }
  std::unique_ptr<EditLog> OpenOrDie(FsyncPolicy policy, RecoveryReport* report = nullptr) {
    EditLogOptions options;
    options.fsync = policy;
    return OpenOrDie(options, report);
  }

  // Deterministic payload of varying size (0..299 bytes) with every byte value.
  static std::string Payload(uint64_t seq) {
    std::string p(seq * 37 % 300, '\0');
    for (size_t i = 0; i < p.size(); ++i) p[i] = static_cast<char>((seq * 131 + i * 7) & 0xff);
    return p;
  }

  // Writes records 1..n (payload Payload(seq)) and closes the log.
  void WriteRecords(uint64_t n, FsyncPolicy policy = {FsyncPolicy::Mode::kGroup, 5}) {
    auto log = OpenOrDie(policy);
    ASSERT_NE(log, nullptr);
    for (uint64_t seq = 1; seq <= n; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
  }

  std::vector<std::string> SegmentFiles() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }
  std::string OnlySegment() const {
    auto names = SegmentFiles();
    EXPECT_EQ(names.size(), 1u);
    return names.empty() ? std::string() : (fs::path(dir_) / names[0]).string();
  }

  // Byte offset of record `seq` in a single segment written by WriteRecords.
  static uint64_t OffsetOf(uint64_t seq) {
    uint64_t offset = kSegmentHeaderBytes;
    for (uint64_t s = 1; s < seq; ++s) offset += kRecordHeaderBytes + Payload(s).size();
    return offset;
  }

  static std::string ReadFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  static void WriteFile(const std::string& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  // A record framed independently of the implementation, from the documented format.
  static std::string EncodeRecord(uint64_t seq, const std::string& payload) {
    std::string out(kRecordHeaderBytes, '\0');
    auto put = [&](size_t at, uint64_t v, int bytes) {
      for (int i = 0; i < bytes; ++i) out[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
    };
    put(0, payload.size(), 4);
    put(8, seq, 8);
    Crc32c crc;
    crc.process_bytes(out.data() + 8, 8);
    crc.process_bytes(payload.data(), payload.size());
    put(4, crc.checksum(), 4);
    return out + payload;
  }

  std::string dir_;
};

uint32_t LoadU32(const std::string& s, size_t at) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) {
    v |= static_cast<uint32_t>(static_cast<uint8_t>(s[at + i])) << (8 * i);
  }
  return v;
}
uint64_t LoadU64(const std::string& s, size_t at) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) {
    v |= static_cast<uint64_t>(static_cast<uint8_t>(s[at + i])) << (8 * i);
  }
  return v;
}

TEST_F(EditLogTest, RoundTripsThousandRecordsUnderAlwaysPolicy) {
  WriteRecords(1000, Always());
  RecoveryReport report;
  auto log = OpenOrDie(Always(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(report.records, 1000u);
  EXPECT_EQ(report.first_seq, 1u);
  EXPECT_EQ(report.last_seq, 1000u);
  EXPECT_EQ(report.dropped_tail_bytes, 0u);
  EXPECT_EQ(log->last_seq(), 1000u);
  EXPECT_EQ(log->durable_seq(), 1000u);
  auto records = log->ReadFrom(0);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 1000u);
  for (uint64_t i = 0; i < 1000; ++i) {
    EXPECT_EQ((*records)[i].seq, i + 1);
    EXPECT_EQ((*records)[i].payload, Payload(i + 1)) << "seq " << i + 1;
  }
}

TEST_F(EditLogTest, TimesEveryFdatasyncThatMakesRecordsDurable) {
  auto log = OpenOrDie(Always());
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(log->sync_seconds().count, 0u);  // the scan at Open is not counted
  for (uint64_t seq = 1; seq <= 5; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
  const auto after_appends = log->sync_seconds();
  EXPECT_EQ(after_appends.count, 5u);  // kAlways: one fdatasync per Append
  EXPECT_EQ(after_appends.cumulative.back(), after_appends.count);  // none over 10 s
  EXPECT_GE(after_appends.sum, 0.0);
  ASSERT_TRUE(log->Sync().ok());  // nothing new written: no fdatasync
  EXPECT_EQ(log->sync_seconds().count, 5u);
}

TEST_F(EditLogTest, RoundTripsThousandRecordsUnderGroupPolicy) {
  WriteRecords(1000, Group());
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(report.records, 1000u);
  EXPECT_EQ(report.last_seq, 1000u);
  auto records = log->ReadFrom(0);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 1000u);
  for (uint64_t i = 0; i < 1000; ++i) {
    EXPECT_EQ((*records)[i].seq, i + 1);
    EXPECT_EQ((*records)[i].payload, Payload(i + 1)) << "seq " << i + 1;
  }
  auto tail = log->ReadFrom(990);
  ASSERT_TRUE(tail.ok());
  ASSERT_EQ(tail->size(), 10u);
  EXPECT_EQ(tail->front().seq, 991u);
}

TEST_F(EditLogTest, OnDiskFormatMatchesTheDocumentation) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->Append(7, "hello").ok());
  }
  const std::vector<std::string> names = SegmentFiles();
  ASSERT_EQ(names.size(), 1u);
  EXPECT_EQ(names[0], "log-00000000000000000007.sclog");
  const std::string bytes = ReadFile(OnlySegment());
  ASSERT_EQ(bytes.size(), kSegmentHeaderBytes + kRecordHeaderBytes + 5);
  EXPECT_EQ(bytes.substr(0, 8), "SCLPTLOG");
  EXPECT_EQ(LoadU32(bytes, 8), 1u);    // version
  EXPECT_EQ(LoadU32(bytes, 12), 32u);  // header size
  EXPECT_EQ(LoadU64(bytes, 16), 0u);   // base seq
  Crc32c header_crc;
  header_crc.process_bytes(bytes.data(), 28);
  EXPECT_EQ(LoadU32(bytes, 28), header_crc.checksum());
  EXPECT_EQ(bytes.substr(kSegmentHeaderBytes), EncodeRecord(7, "hello"));
  // CRC-32C check value of the standard test vector, so the polynomial is the documented one.
  Crc32c check;
  check.process_bytes("123456789", 9);
  EXPECT_EQ(check.checksum(), 0xE3069283u);
}

TEST_F(EditLogTest, GroupRoundTripsWithTheContinuationFlag) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->Append(1, "a").ok());
    ASSERT_TRUE(log->AppendGroup(2, {"b", "cc", "ddd"}).ok());
    EXPECT_EQ(log->last_seq(), 4u);
    EXPECT_EQ(log->durable_seq(), 4u);
    EXPECT_EQ(log->AppendGroup(4, {"x"}).code(), Status::Code::kFailedPrecondition);
    EXPECT_EQ(log->AppendGroup(5, {}).code(), Status::Code::kInvalidArgument);
  }
  const std::string bytes = ReadFile(OnlySegment());
  const uint64_t second = kSegmentHeaderBytes + kRecordHeaderBytes + 1;
  EXPECT_EQ(LoadU32(bytes, second), 1u | kGroupContinues);
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  EXPECT_EQ(report.records, 4u);
  EXPECT_EQ(report.dropped_tail_bytes, 0u);
  auto records = log->ReadFrom(0);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 4u);
  EXPECT_EQ((*records)[3].seq, 4u);
  EXPECT_EQ((*records)[3].payload, "ddd");
}

TEST_F(EditLogTest, DropsAGroupCutBetweenTwoOfItsRecords) {
  {
    auto log = OpenOrDie(Always());
    for (uint64_t seq = 1; seq <= 3; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
    ASSERT_TRUE(log->AppendGroup(4, {Payload(4), Payload(5), Payload(6), Payload(7)}).ok());
  }
  const std::string path = OnlySegment();
  for (uint64_t cut : {OffsetOf(6), OffsetOf(6) + 5, OffsetOf(7) + 3}) {
    const std::string whole = ReadFile(path);
    fs::resize_file(path, cut);
    RecoveryReport report;
    {
      auto log = OpenOrDie(Group(), &report);
      ASSERT_NE(log, nullptr);
      EXPECT_EQ(report.records, 3u) << "cut at " << cut;
      EXPECT_EQ(report.last_seq, 3u);
      EXPECT_EQ(log->last_seq(), 3u);
      EXPECT_EQ(report.dropped_tail_bytes, cut - OffsetOf(4));
      EXPECT_EQ(fs::file_size(path), OffsetOf(4)) << "the whole group is cut off";
      auto records = log->ReadFrom(0);
      ASSERT_TRUE(records.ok());
      EXPECT_EQ(records->size(), 3u);
    }
    WriteFile(path, whole);
  }
}

TEST_F(EditLogTest, RefusesASegmentEndingInsideAGroupBeforeAnotherSegment) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->AppendGroup(1, {"a", "b", "c"}).ok());
    log->Roll();
    ASSERT_TRUE(log->Append(4, "d").ok());
  }
  const auto names = SegmentFiles();
  ASSERT_EQ(names.size(), 2u);
  const fs::path first = fs::path(dir_) / names[0];
  fs::resize_file(first, kSegmentHeaderBytes + 2 * (kRecordHeaderBytes + 1));
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find(first.string()), std::string::npos) << log.status();
}

TEST_F(EditLogTest, DropsTruncatedTailRecord) {
  WriteRecords(20);
  const std::string path = OnlySegment();
  const uint64_t full = fs::file_size(path);
  fs::resize_file(path, full - 3);

  RecoveryReport report;
  {
    auto log = OpenOrDie(Group(), &report);
    ASSERT_NE(log, nullptr);
    EXPECT_EQ(report.records, 19u);
    EXPECT_EQ(report.last_seq, 19u);
    EXPECT_EQ(report.dropped_tail_bytes, kRecordHeaderBytes + Payload(20).size() - 3);
    EXPECT_EQ(report.dropped_tail_file, path);
    EXPECT_NE(report.dropped_tail_reason.find("truncated record"), std::string::npos)
        << report.dropped_tail_reason;
    ASSERT_EQ(report.warnings.size(), 1u);
    EXPECT_EQ(fs::file_size(path), OffsetOf(20)) << "the torn bytes are cut off the file";
    EXPECT_EQ(log->last_seq(), 19u);
    ASSERT_TRUE(log->Append(20, "after the tear").ok());
  }
  RecoveryReport again;
  auto log = OpenOrDie(Group(), &again);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(again.dropped_tail_bytes, 0u);
  EXPECT_EQ(again.records, 20u);
  auto records = log->ReadFrom(18);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 2u);
  EXPECT_EQ((*records)[0].payload, Payload(19));
  EXPECT_EQ((*records)[1].seq, 20u);
  EXPECT_EQ((*records)[1].payload, "after the tear");
}

TEST_F(EditLogTest, DropsTruncatedTailRecordHeader) {
  WriteRecords(5);
  const std::string path = OnlySegment();
  fs::resize_file(path, OffsetOf(5) + 7);
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(report.last_seq, 4u);
  EXPECT_EQ(report.dropped_tail_bytes, 7u);
  EXPECT_NE(report.dropped_tail_reason.find("truncated record header"), std::string::npos);
}

// A whole final record with other bytes than written is damage (a kill -9 leaves the page
// cache intact; a power loss leaves zeros or a shorter file), and it may have been
// acknowledged: start-up stops and names the file, the offset and the seq at stake.
TEST_F(EditLogTest, RefusesAFlippedFinalRecord) {
  WriteRecords(20);
  const std::string path = OnlySegment();
  std::string bytes = ReadFile(path);
  bytes[bytes.size() - 1] ^= 0x40;
  WriteFile(path, bytes);
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  const std::string& m = log.status().message();
  EXPECT_NE(m.find(path), std::string::npos) << m;
  EXPECT_NE(m.find("offset " + std::to_string(OffsetOf(20))), std::string::npos) << m;
  EXPECT_NE(m.find("record seq 20"), std::string::npos) << m;
  EXPECT_NE(m.find("sculptd repair"), std::string::npos) << m;
}

TEST_F(EditLogTest, DropsAFinalRecordWhoseLastBlocksAreZero) {
  WriteRecords(20);
  const std::string path = OnlySegment();
  std::string bytes = ReadFile(path);
  const uint64_t mid = OffsetOf(20) + kRecordHeaderBytes + 2;  // zeros start inside the payload
  ASSERT_LT(mid, bytes.size());
  std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(mid), bytes.end(), '\0');
  WriteFile(path, bytes + std::string(1000, '\0'));
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(report.last_seq, 19u);
  EXPECT_EQ(fs::file_size(path), OffsetOf(20));
  EXPECT_NE(report.dropped_tail_reason.find("zero-filled"), std::string::npos)
      << report.dropped_tail_reason;
}

TEST_F(EditLogTest, RefusesAMissingNewestSegment) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->Append(1, "a").ok());
    ASSERT_TRUE(log->Append(2, "b").ok());
    log->Roll();
    ASSERT_TRUE(log->Append(3, "c").ok());
  }
  auto names = SegmentFiles();
  ASSERT_EQ(names.size(), 2u);
  fs::remove(fs::path(dir_) / names[1]);
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find(names[1]), std::string::npos) << log.status();
  EXPECT_NE(log.status().message().find("from seq 3"), std::string::npos) << log.status();
}

TEST_F(EditLogTest, ContinuesAfterACrashRightAfterARoll) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->Append(1, "a").ok());
    log->Roll();
    ASSERT_TRUE(log->Append(2, "b").ok());
  }
  auto names = SegmentFiles();
  ASSERT_EQ(names.size(), 2u);
  // The new segment got its header but the crash came before its first record reached it.
  fs::resize_file(fs::path(dir_) / names[1], kSegmentHeaderBytes);
  {
    RecoveryReport report;
    auto log = OpenOrDie(Group(), &report);
    ASSERT_NE(log, nullptr);
    EXPECT_EQ(log->last_seq(), 1u);
    ASSERT_TRUE(log->Append(2, "b again").ok());
  }
  auto log = OpenOrDie(Group());
  ASSERT_NE(log, nullptr);
  auto records = log->ReadFrom(0);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 2u);
  EXPECT_EQ((*records)[1].payload, "b again");
}

TEST_F(EditLogTest, DropsZeroFilledTail) {
  WriteRecords(10);
  const std::string path = OnlySegment();
  WriteFile(path, ReadFile(path) + std::string(4096, '\0'));  // size grew, blocks never written
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(report.last_seq, 10u);
  EXPECT_EQ(report.dropped_tail_bytes, 4096u);
  EXPECT_NE(report.dropped_tail_reason.find("zero-filled"), std::string::npos);
}

TEST_F(EditLogTest, RefusesCorruptRecordInTheMiddle) {
  WriteRecords(20);
  const std::string path = OnlySegment();
  std::string bytes = ReadFile(path);
  const uint64_t offset = OffsetOf(10);
  ASSERT_GT(Payload(10).size(), 0u);
  bytes[offset + kRecordHeaderBytes + 1] ^= 0x01;
  WriteFile(path, bytes);

  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  const std::string& m = log.status().message();
  EXPECT_NE(m.find(path), std::string::npos) << m;
  EXPECT_NE(m.find("offset " + std::to_string(offset) + " "), std::string::npos) << m;
  EXPECT_NE(m.find("record seq 10"), std::string::npos) << m;
  EXPECT_NE(m.find("checksum mismatch"), std::string::npos) << m;
  EXPECT_NE(m.find("refusing to start"), std::string::npos) << m;
  EXPECT_EQ(ReadFile(path), bytes) << "a refused log is left untouched for the operator";
}

TEST_F(EditLogTest, RefusesBadLengthInTheMiddle) {
  WriteRecords(20);
  const std::string path = OnlySegment();
  std::string bytes = ReadFile(path);
  const uint64_t offset = OffsetOf(10);
  bytes[offset + 3] = static_cast<char>(0x7f);  // length ~2 GiB
  WriteFile(path, bytes);
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find("bad length"), std::string::npos) << log.status();
  EXPECT_NE(log.status().message().find("offset " + std::to_string(offset)), std::string::npos);
}

TEST_F(EditLogTest, RefusesNonIncreasingSequence) {
  auto log = OpenOrDie(Always());
  ASSERT_TRUE(log->Append(5, "a").ok());
  Status same = log->Append(5, "b");
  EXPECT_EQ(same.code(), Status::Code::kFailedPrecondition) << same;
  EXPECT_NE(same.message().find("seq=5"), std::string::npos) << same;
  EXPECT_EQ(log->Append(4, "c").code(), Status::Code::kFailedPrecondition);
  EXPECT_TRUE(log->Append(6, "d").ok());
  auto records = log->ReadFrom(0);
  ASSERT_TRUE(records.ok());
  ASSERT_EQ(records->size(), 2u);
  EXPECT_EQ((*records)[1].seq, 6u);
}

TEST_F(EditLogTest, RefusesNonIncreasingSequenceOnDisk) {
  WriteRecords(3);
  const std::string path = OnlySegment();
  const uint64_t offset = fs::file_size(path);
  WriteFile(path, ReadFile(path) + EncodeRecord(2, "replayed twice") + EncodeRecord(4, "x"));
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find("offset " + std::to_string(offset)), std::string::npos);
  EXPECT_NE(log.status().message().find("does not increase"), std::string::npos) << log.status();
}

TEST_F(EditLogTest, RefusesBadMagic) {
  WriteRecords(3);
  const std::string path = OnlySegment();
  std::string bytes = ReadFile(path);
  bytes[0] = 'X';
  WriteFile(path, bytes);
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find("bad magic"), std::string::npos) << log.status();
}

TEST_F(EditLogTest, RefusesSegmentOfAnotherFormatVersion) {
  WriteRecords(3);
  const std::string path = OnlySegment();
  std::string bytes = ReadFile(path);
  bytes[8] = 2;
  WriteFile(path, bytes);
  auto log = EditLog::Open(dir_, Group(), nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(log.status().message().find("format version 2"), std::string::npos) << log.status();
}

TEST_F(EditLogTest, RejectsOversizedPayload) {
  auto log = OpenOrDie(Group());
  Status s = log->Append(1, std::string(kMaxRecordPayload + 1, 'x'));
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(log->Append(1, "fits").ok()) << "a rejected append does not consume the seq";
}

TEST_F(EditLogTest, RejectsBadFsyncPolicy) {
  auto log = EditLog::Open(dir_, FsyncPolicy{FsyncPolicy::Mode::kGroup, 0}, nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kInvalidArgument);
  EXPECT_NE(log.status().message().find("group_ms=0"), std::string::npos) << log.status();
  EXPECT_EQ(ParseFsyncMode("always").value(), FsyncPolicy::Mode::kAlways);
  EXPECT_EQ(ParseFsyncMode("group").value(), FsyncPolicy::Mode::kGroup);
  EXPECT_EQ(ParseFsyncMode("sometimes").status().code(), Status::Code::kInvalidArgument);
}

TEST_F(EditLogTest, AlwaysPolicyIsDurableWhenAppendReturns) {
  auto log = OpenOrDie(Always());
  std::vector<uint64_t> seen;
  log->OnDurable([&](uint64_t seq) { seen.push_back(seq); });
  for (uint64_t seq = 1; seq <= 20; ++seq) {
    ASSERT_TRUE(log->Append(seq * 2, "x").ok());
    EXPECT_EQ(log->durable_seq(), seq * 2);
  }
  ASSERT_EQ(seen.size(), 20u);
  EXPECT_EQ(seen.back(), 40u);
}

TEST_F(EditLogTest, GroupPolicyCatchesUpWithinAFewPeriods) {
  constexpr int kGroupMs = 5;
  auto log = OpenOrDie(Group(kGroupMs));
  std::mutex mu;
  std::vector<uint64_t> seen;
  log->OnDurable([&](uint64_t seq) {
    std::lock_guard<std::mutex> lock(mu);
    seen.push_back(seq);
  });
  for (uint64_t seq = 1; seq <= 300; ++seq) {
    ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
    EXPECT_LE(log->durable_seq(), seq);
    if (seq % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const auto start = std::chrono::steady_clock::now();
  while (log->durable_seq() < 300 &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(2)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const auto waited = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::steady_clock::now() - start);
  EXPECT_EQ(log->durable_seq(), 300u);
  // A few periods plus the fdatasync itself; generous for a shared 2-core machine.
  EXPECT_LE(waited.count(), 20 * kGroupMs) << "durable_seq lagged " << waited.count() << " ms";
  std::lock_guard<std::mutex> lock(mu);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 300u);
  for (size_t i = 1; i < seen.size(); ++i) EXPECT_LT(seen[i - 1], seen[i]);
  EXPECT_LT(seen.size(), 300u) << "group commit should share fdatasyncs between records";
}

TEST_F(EditLogTest, SyncAdvancesDurableSeqAtOnce) {
  auto log = OpenOrDie(Group(1000));
  std::atomic<uint64_t> last_seen{0};
  log->OnDurable([&](uint64_t seq) { last_seen = seq; });
  for (uint64_t seq = 1; seq <= 10; ++seq) ASSERT_TRUE(log->Append(seq, "x").ok());
  ASSERT_TRUE(log->Sync().ok());
  EXPECT_EQ(log->durable_seq(), 10u);
  EXPECT_EQ(last_seen.load(), 10u);
}

TEST_F(EditLogTest, RollsSegmentsAtTheSizeLimit) {
  EditLogOptions options;
  options.fsync = Always();
  // Header 32 + two records of 16 + 50 bytes = 164; a third would pass 200.
  options.segment_bytes = 200;
  {
    auto log = OpenOrDie(options);
    for (uint64_t seq = 1; seq <= 10; ++seq) {
      ASSERT_TRUE(log->Append(seq, std::string(50, 'a' + seq % 26)).ok());
    }
    EXPECT_EQ(log->segment_count(), 5u);
  }
  const std::vector<std::string> names = SegmentFiles();
  ASSERT_EQ(names.size(), 5u);
  EXPECT_EQ(names[0], "log-00000000000000000001.sclog");
  EXPECT_EQ(names[1], "log-00000000000000000003.sclog");
  EXPECT_EQ(names[4], "log-00000000000000000009.sclog");
  for (const auto& n : names) EXPECT_LE(fs::file_size(fs::path(dir_) / n), 200u) << n;

  RecoveryReport report;
  auto log = OpenOrDie(options, &report);
  EXPECT_EQ(report.segments, 5u);
  EXPECT_EQ(report.records, 10u);
  auto records = log->ReadFrom(4);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 6u);
  EXPECT_EQ(records->front().seq, 5u);
  EXPECT_EQ(records->back().payload, std::string(50, 'a' + 10 % 26));
}

TEST_F(EditLogTest, RollStartsANewSegmentAtTheNextAppend) {
  auto log = OpenOrDie(Always());
  for (uint64_t seq = 1; seq <= 3; ++seq) ASSERT_TRUE(log->Append(seq, "x").ok());
  log->Roll();
  EXPECT_EQ(log->segment_count(), 1u);
  ASSERT_TRUE(log->Append(4, "y").ok());
  EXPECT_EQ(log->segment_count(), 2u);
  log->Roll();
  log->Roll();
  ASSERT_TRUE(log->Append(5, "z").ok());
  EXPECT_EQ(log->segment_count(), 3u);
  EXPECT_EQ(SegmentFiles().back(), "log-00000000000000000005.sclog");
}

TEST_F(EditLogTest, DropSegmentsBeforeRemovesOnlyFullyCoveredSegments) {
  EditLogOptions options;
  options.fsync = Always();
  options.segment_bytes = 200;  // two 50-byte records per segment: [1,2] [3,4] [5,6] [7,8] [9,10]
  {
    auto log = OpenOrDie(options);
    for (uint64_t seq = 1; seq <= 10; ++seq) {
      ASSERT_TRUE(log->Append(seq, std::string(50, 'p')).ok());
    }
    ASSERT_TRUE(log->DropSegmentsBefore(5).ok());  // [5,6] still holds seq 6
    EXPECT_EQ(log->segment_count(), 3u);
    EXPECT_EQ(log->base_seq(), 4u);
    ASSERT_TRUE(log->DropSegmentsBefore(100).ok());  // never the active segment
    EXPECT_EQ(log->segment_count(), 1u);
    EXPECT_EQ(log->base_seq(), 8u);
    ASSERT_TRUE(log->Append(11, "more").ok());
  }
  const std::vector<std::string> names = SegmentFiles();
  ASSERT_EQ(names.size(), 1u);
  EXPECT_EQ(names[0], "log-00000000000000000009.sclog");
  RecoveryReport report;
  auto log = OpenOrDie(options, &report);
  EXPECT_EQ(report.log_base_seq, 8u);
  EXPECT_EQ(report.first_seq, 9u);
  EXPECT_EQ(report.last_seq, 11u);
}

TEST_F(EditLogTest, RefusesMissingSegment) {
  EditLogOptions options;
  options.fsync = Always();
  options.segment_bytes = 200;
  {
    auto log = OpenOrDie(options);
    for (uint64_t seq = 1; seq <= 10; ++seq) {
      ASSERT_TRUE(log->Append(seq, std::string(50, 'p')).ok());
    }
  }
  fs::remove(fs::path(dir_) / "log-00000000000000000005.sclog");
  auto log = EditLog::Open(dir_, options, nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find("log-00000000000000000007.sclog"), std::string::npos);
  EXPECT_NE(log.status().message().find("segment is missing"), std::string::npos) << log.status();
}

TEST_F(EditLogTest, RefusesTruncatedRecordInAnEarlierSegment) {
  EditLogOptions options;
  options.fsync = Always();
  options.segment_bytes = 200;
  {
    auto log = OpenOrDie(options);
    for (uint64_t seq = 1; seq <= 6; ++seq) {
      ASSERT_TRUE(log->Append(seq, std::string(50, 'p')).ok());
    }
  }
  const fs::path first = fs::path(dir_) / "log-00000000000000000001.sclog";
  fs::resize_file(first, fs::file_size(first) - 10);
  auto log = EditLog::Open(dir_, options, nullptr);
  ASSERT_FALSE(log.ok());
  EXPECT_EQ(log.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(log.status().message().find(first.string()), std::string::npos) << log.status();
}

TEST_F(EditLogTest, DropsLastSegmentWithTruncatedHeader) {
  WriteRecords(3);
  // A crash while the next segment was being created.
  WriteFile((fs::path(dir_) / "log-00000000000000000004.sclog").string(), "SCLPTLOG\x01");
  RecoveryReport report;
  {
    auto log = OpenOrDie(Group(), &report);
    ASSERT_NE(log, nullptr);
    EXPECT_EQ(report.last_seq, 3u);
    EXPECT_EQ(report.dropped_tail_bytes, 9u);
    ASSERT_TRUE(log->Append(4, "again").ok());
  }
  auto log = OpenOrDie(Group());
  auto records = log->ReadFrom(3);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 1u);
  EXPECT_EQ(records->front().payload, "again");
}

TEST_F(EditLogTest, StartAfterSetsTheBaseOfAnEmptyLog) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->StartAfter(50).ok());
    EXPECT_EQ(log->Append(50, "x").code(), Status::Code::kFailedPrecondition);
    ASSERT_TRUE(log->Append(51, "x").ok());
    EXPECT_EQ(log->StartAfter(60).code(), Status::Code::kFailedPrecondition);
  }
  RecoveryReport report;
  auto log = OpenOrDie(Always(), &report);
  EXPECT_EQ(report.log_base_seq, 50u);
  EXPECT_EQ(log->base_seq(), 50u);
}

TEST_F(EditLogTest, ForEachFromStopsAtTheVisitorsError) {
  WriteRecords(10);
  auto log = OpenOrDie(Group());
  std::vector<uint64_t> seen;
  Status s = log->ForEachFrom(3, [&](const LogRecord& r) {
    seen.push_back(r.seq);
    return r.seq == 6 ? InvalidArgument("stop here") : Status::Ok();
  });
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(seen, (std::vector<uint64_t>{4, 5, 6}));
}

TEST_F(EditLogTest, IgnoresFilesThatAreNotSegments) {
  WriteRecords(3);
  WriteFile((fs::path(dir_) / "log-00000000000000000001.sclog.moved-away").string(), "junk");
  WriteFile((fs::path(dir_) / "README").string(), "junk");
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  EXPECT_EQ(report.records, 3u);
}

TEST_F(EditLogTest, RepairSaysWhatItDiscardsAndThenTheLogOpens) {
  {
    EditLogOptions options;
    options.fsync = Always();
    auto log = OpenOrDie(options);
    for (uint64_t seq = 1; seq <= 10; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
    log->Roll();
    for (uint64_t seq = 11; seq <= 20; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
  }
  auto names = SegmentFiles();
  ASSERT_EQ(names.size(), 2u);
  const std::string first = (fs::path(dir_) / names[0]).string();
  std::string bytes = ReadFile(first);
  bytes[OffsetOf(6) + kRecordHeaderBytes] ^= 0x01;  // record 6 damaged in the middle
  WriteFile(first, bytes);
  ASSERT_EQ(EditLog::Open(dir_, Group(), nullptr).status().code(), Status::Code::kDataLoss);

  auto plan = EditLog::Repair(dir_, /*dry_run=*/true);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_FALSE(plan->clean);
  ASSERT_EQ(plan->discarded.size(), 2u);
  EXPECT_NE(plan->discarded[0].find("after seq 5"), std::string::npos) << plan->discarded[0];
  EXPECT_NE(plan->discarded[0].find("seq 6..10 (5 records, 1 damaged)"), std::string::npos)
      << plan->discarded[0];
  EXPECT_NE(plan->discarded[1].find("seq 11..20 (10 records"), std::string::npos)
      << plan->discarded[1];
  EXPECT_EQ(ReadFile(first), bytes) << "a dry run changes nothing";

  auto done = EditLog::Repair(dir_, /*dry_run=*/false);
  ASSERT_TRUE(done.ok()) << done.status();
  EXPECT_TRUE(fs::exists(fs::path(dir_) / (names[1] + ".discarded")));
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(log->last_seq(), 5u);
  EXPECT_TRUE(EditLog::Repair(dir_, true)->clean);
}

TEST_F(EditLogTest, RepairAcceptsTheLossOfAMissingNewestSegment) {
  {
    auto log = OpenOrDie(Always());
    ASSERT_TRUE(log->Append(1, "a").ok());
    log->Roll();
    ASSERT_TRUE(log->Append(2, "b").ok());
  }
  auto names = SegmentFiles();
  fs::remove(fs::path(dir_) / names[1]);
  auto done = EditLog::Repair(dir_, false);
  ASSERT_TRUE(done.ok()) << done.status();
  ASSERT_EQ(done->discarded.size(), 1u);
  EXPECT_NE(done->discarded[0].find("from seq 2"), std::string::npos) << done->discarded[0];
  auto log = OpenOrDie(Group());
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(log->last_seq(), 1u);
  EXPECT_TRUE(log->Append(2, "b again").ok());
}

// A full disk: Append fails with ResourceExhausted naming the directory and the free bytes,
// nothing of the record stays, and appends succeed by themselves once space returns.
TEST_F(EditLogTest, FullDiskIsNamedAndPassesWhenSpaceReturns) {
  std::atomic<bool> full{false};
  EditLogOptions options;
  options.fsync = Always();
  options.writev_for_testing = [&full](int fd, const struct iovec* iov, int count) -> ssize_t {
    if (full.load()) {
      // Half of the first buffer gets out, then the disk is full (a partial record).
      if (iov[0].iov_len > 1) {
        struct iovec half = {iov[0].iov_base, iov[0].iov_len / 2};
        const ssize_t n = ::writev(fd, &half, 1);
        if (n > 0) return n;
      }
      errno = ENOSPC;
      return -1;
    }
    return ::writev(fd, iov, count);
  };
  {
    auto log = OpenOrDie(options);
    ASSERT_TRUE(log->Append(1, Payload(1)).ok());
    full = true;
    const Status s = log->AppendGroup(2, {Payload(2), Payload(3)});
    EXPECT_EQ(s.code(), Status::Code::kResourceExhausted) << s;
    EXPECT_NE(s.message().find("edit_log.free_bytes="), std::string::npos) << s;
    EXPECT_NE(s.message().find(dir_), std::string::npos) << s;
    EXPECT_EQ(log->last_seq(), 1u);
    EXPECT_EQ(log->Append(2, Payload(2)).code(), Status::Code::kResourceExhausted);
    full = false;
    ASSERT_TRUE(log->AppendGroup(2, {Payload(2), Payload(3)}).ok()) << "resumes by itself";
    ASSERT_TRUE(log->Append(4, Payload(4)).ok());
  }
  RecoveryReport report;
  auto log = OpenOrDie(Group(), &report);
  ASSERT_NE(log, nullptr);
  EXPECT_EQ(report.dropped_tail_bytes, 0u) << "no partial record was left behind";
  auto records = log->ReadFrom(0);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 4u);
  for (uint64_t seq = 1; seq <= 4; ++seq) EXPECT_EQ((*records)[seq - 1].payload, Payload(seq));
}

// Seeded damage anywhere in a two-segment log (bit flips, zeroed runs, truncations): Open never
// crashes; it either opens a log whose records are a prefix of what was written (a torn tail
// cut) or refuses with DataLoss / FailedPrecondition naming a file.
TEST_F(EditLogTest, SeededDamageNeverCrashesAndNeverInventsRecords) {
  {
    auto log = OpenOrDie(Always());
    for (uint64_t seq = 1; seq <= 12; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
    log->Roll();
    ASSERT_TRUE(log->AppendGroup(13, {Payload(13), Payload(14), Payload(15)}).ok());
    for (uint64_t seq = 16; seq <= 20; ++seq) ASSERT_TRUE(log->Append(seq, Payload(seq)).ok());
  }
  const auto names = SegmentFiles();
  ASSERT_EQ(names.size(), 2u);
  std::vector<std::string> originals;
  for (const auto& n : names) originals.push_back(ReadFile((fs::path(dir_) / n).string()));
  std::mt19937_64 rng(1123);
  for (int i = 0; i < 300; ++i) {
    const size_t which = rng() % 2;
    std::string bytes = originals[which];
    switch (i % 3) {
      case 0: {
        const size_t bit = rng() % (bytes.size() * 8);
        bytes[bit / 8] = static_cast<char>(bytes[bit / 8] ^ (1 << (bit % 8)));
        break;
      }
      case 1: {
        const size_t at = rng() % bytes.size();
        std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(at),
                  bytes.begin() +
                      static_cast<std::ptrdiff_t>(std::min(bytes.size(), at + 1 + rng() % 64)),
                  '\0');
        break;
      }
      default:
        bytes.resize(rng() % bytes.size());
    }
    for (size_t k = 0; k < names.size(); ++k) {
      WriteFile((fs::path(dir_) / names[k]).string(), k == which ? bytes : originals[k]);
    }
    auto log = EditLog::Open(dir_, Group(), nullptr);
    if (!log.ok()) {
      EXPECT_TRUE(log.status().code() == Status::Code::kDataLoss ||
                  log.status().code() == Status::Code::kFailedPrecondition)
          << "damage " << i << ": " << log.status();
      EXPECT_NE(log.status().message().find(dir_), std::string::npos) << log.status();
      continue;
    }
    auto records = (*log)->ReadFrom(0);
    ASSERT_TRUE(records.ok()) << "damage " << i << ": " << records.status();
    for (size_t r = 0; r < records->size(); ++r) {
      EXPECT_EQ((*records)[r].seq, r + 1) << "damage " << i;
      EXPECT_EQ((*records)[r].payload, Payload(r + 1)) << "damage " << i;
    }
    const size_t n = records->size();
    EXPECT_TRUE(n <= 12 || n >= 15) << "damage " << i << ": part of the group survived";
  }
}

}  // namespace
}  // namespace sculpt::server::store
