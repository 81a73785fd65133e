// kill -9 of sculptd at random moments while a client streams strokes, 20 times: after every
// restart each acknowledged stroke is in the log, and the recovered state equals a replay of
// the log from scratch.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mount.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <random>
#include <set>
#include <thread>

#include "sculpt/codec/stroke.h"

#include "integration/raw_client.h"
#include "scene/scene.h"
#include "store/edit_log.h"

extern char** environ;

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;

class Daemon {
 public:
  Daemon(const fs::path& data, const fs::path& port_file,
         const std::vector<std::string>& extra_args = {})
      : port_file_(port_file) {
    fs::remove(port_file_);
    const std::string bin = std::string(SCULPT_BIN_DIR) + "/sculptd";
    std::vector<std::string> args = {bin,      "serve",       "--listen",
                                     "127.0.0.1:0", "--data",  data.string(),
                                     "--port-file", port_file.string(), "--fsync",
                                     "group",   "--snapshot-every", "300"};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    // sculptd's log goes next to the data directory (kept when the test fails).
    const std::string log = (data.parent_path() / "sculptd.log").string();
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    EXPECT_EQ(posix_spawn(&pid_, bin.c_str(), &fa, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&fa);
  }
  uint16_t WaitPort() {
    for (int i = 0; i < 500; ++i) {
      std::ifstream in(port_file_);
      unsigned p = 0;
      if (in >> p && p > 0) return static_cast<uint16_t>(p);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return 0;
  }
  void Kill(int sig) {
    if (pid_ <= 0) return;
    kill(pid_, sig);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  ~Daemon() { Kill(SIGKILL); }

 private:
  fs::path port_file_;
  pid_t pid_ = -1;
};

// Drives an in-process Scene: submits one stroke and waits for its outcome (acknowledged once
// durable).
StrokeOutcome SubmitAndWait(Scene& scene, uint64_t client_id, const v1::ClientMessage& m) {
  auto limits = scene.LimitsFor(m.stroke().object());
  EXPECT_TRUE(limits.ok()) << limits.status();
  auto stroke = codec::DecodeStroke(m.stroke(), *limits);
  EXPECT_TRUE(stroke.ok()) << stroke.status();
  std::promise<StrokeOutcome> p;
  scene.Submit(client_id, std::move(stroke).value(),
               [&p](const StrokeOutcome& o) { p.set_value(o); });
  return p.get_future().get();
}

// Offsets of the records in one log segment, in file order.
std::vector<uint64_t> RecordOffsets(const fs::path& segment) {
  std::ifstream in(segment, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<uint64_t> offsets;
  uint64_t at = store::kSegmentHeaderBytes;
  while (at + store::kRecordHeaderBytes <= bytes.size()) {
    offsets.push_back(at);
    uint32_t len = 0;
    std::memcpy(&len, bytes.data() + at, 4);  // little-endian host
    at += store::kRecordHeaderBytes + (len & ~store::kGroupContinues);
  }
  return offsets;
}

// sculptd killed between two poses of a stroke (simulated by cutting the log there): recovery
// applies none of the stroke, the client's resend is applied whole and once, and a second
// resend is a duplicate.
TEST(CrashTest, KillBetweenTwoPosesOfAStrokeAppliesNoneAndTheResendAppliesAll) {
  const fs::path data =
      fs::temp_directory_path() / ("sculptd_torn_stroke_" + std::to_string(getpid()));
  fs::remove_all(data);
  ServerConfig config;
  config.data_dir = data.string();
  constexpr uint64_t kClient = 77;
  const v1::ClientMessage first = RawClient::PressStroke(1, {0, 0, 13.3}, 4);
  const v1::ClientMessage second = RawClient::PressStroke(2, {2, 1, 13.0}, 4);
  uint64_t before_second = 0;
  uint64_t after_second = 0;
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    ASSERT_EQ(SubmitAndWait(**scene, kClient, first).edits, 4u);
    before_second = (*scene)->StateHash("clay");
    ASSERT_EQ(SubmitAndWait(**scene, kClient, second).edits, 4u);
    after_second = (*scene)->StateHash("clay");
  }
  ASSERT_NE(before_second, after_second);
  std::vector<fs::path> segments;
  for (const auto& e : fs::directory_iterator(data / "log")) segments.push_back(e.path());
  ASSERT_EQ(segments.size(), 1u);
  const std::vector<uint64_t> offsets = RecordOffsets(segments[0]);
  ASSERT_EQ(offsets.size(), 8u);
  fs::resize_file(segments[0], offsets[6]);  // poses 0 and 1 of the second stroke survive
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_EQ((*scene)->StateHash("clay"), before_second) << "part of the stroke was applied";
    const StrokeOutcome resend = SubmitAndWait(**scene, kClient, second);
    EXPECT_TRUE(resend.status.ok()) << resend.status;
    EXPECT_FALSE(resend.duplicate);
    EXPECT_EQ(resend.edits, 4u);
    EXPECT_EQ((*scene)->StateHash("clay"), after_second);
    const StrokeOutcome again = SubmitAndWait(**scene, kClient, second);
    EXPECT_TRUE(again.duplicate);
    EXPECT_EQ(again.edits, 0u);
  }
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_EQ((*scene)->StateHash("clay"), after_second);
    EXPECT_TRUE(SubmitAndWait(**scene, kClient, second).duplicate);
  }
  fs::remove_all(data);
}

std::vector<fs::path> Segments(const fs::path& log_dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(log_dir)) {
    if (e.path().extension() == ".sclog") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The bounded log: after snapshots every 8 edits the log holds only the tail, a restart gives
// the same state and still recognises a resend of a stroke whose records were dropped; the
// same holds for a crash between a snapshot and the trim (no segment dropped yet) and during
// the trim (only the oldest dropped), emulated by putting back the segment files as they were.
TEST(CrashTest, TrimmedLogRestartsToTheSameStateAndRecognisesOldResends) {
  const fs::path root = fs::temp_directory_path() / ("sculptd_trim_" + std::to_string(getpid()));
  fs::remove_all(root);
  const fs::path data = root / "data";
  const fs::path stash = root / "stash";
  fs::create_directories(stash);
  ServerConfig config;
  config.data_dir = data.string();
  config.snapshot_every_edits = 8;
  config.snapshot_every_seconds = 0;
  constexpr uint64_t kClient = 91;
  constexpr uint64_t kEarlyClient = 92;
  constexpr int kStrokes = 16;
  auto stroke = [](int i) {
    const double a = 0.4 * i;
    return RawClient::PressStroke(static_cast<uint64_t>(i),
                                  {12.5 * std::cos(a), 12.5 * std::sin(a), 3.0 * std::sin(2 * a)},
                                  4);
  };
  uint64_t hash = 0;
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    // An early client whose every record is dropped: only the resend table knows its strokes.
    ASSERT_EQ(SubmitAndWait(**scene, kEarlyClient, stroke(101)).edits, 4u);
    for (int i = 1; i <= kStrokes; ++i) {
      ASSERT_EQ(SubmitAndWait(**scene, kClient, stroke(i)).edits, 4u) << i;
      (*scene)->Flush();  // the snapshot round (and its trim) has finished
      for (const fs::path& seg : Segments(data / "log")) {
        fs::copy_file(seg, stash / seg.filename(), fs::copy_options::overwrite_existing);
      }
    }
    hash = (*scene)->StateHash("clay");
  }
  const std::vector<fs::path> kept = Segments(data / "log");
  const std::vector<fs::path> all = Segments(stash);
  EXPECT_LE(kept.size(), 3u) << "the log is trimmed after snapshots";
  ASSERT_GT(all.size(), kept.size() + 1);
  {
    store::RecoveryReport report;
    auto log = store::EditLog::Open((data / "log").string(), store::FsyncPolicy{}, &report);
    ASSERT_TRUE(log.ok()) << log.status();
    EXPECT_GT((*log)->base_seq(), 0u);
    EXPECT_LT(report.records, 4u * kStrokes / 2);
  }
  const fs::path pristine = root / "pristine";
  fs::copy(data, pristine, fs::copy_options::recursive);
  // What the restart must find in every case: the same state, every old stroke a duplicate.
  auto check = [&](const std::string& what) {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << what << ": " << scene.status();
    EXPECT_EQ((*scene)->StateHash("clay"), hash) << what;
    for (int i : {1, kStrokes / 2, kStrokes}) {
      const StrokeOutcome o = SubmitAndWait(**scene, kClient, stroke(i));
      EXPECT_TRUE(o.duplicate) << what << ": resend of stroke " << i;
      EXPECT_EQ(o.edits, 0u) << what;
    }
    EXPECT_TRUE(SubmitAndWait(**scene, kEarlyClient, stroke(101)).duplicate) << what;
  };
  check("after the trim");
  const size_t dropped = all.size() - kept.size();
  for (size_t put_back : {dropped, dropped / 2}) {
    fs::remove_all(data);
    fs::copy(pristine, data, fs::copy_options::recursive);
    // Crash before the trim (every dropped segment still there) or during it (the oldest gone).
    for (size_t k = dropped - put_back; k < dropped; ++k) {
      fs::copy_file(all[k], data / "log" / all[k].filename());
    }
    check(put_back == dropped ? "crash between snapshot and trim" : "crash during the trim");
  }
  // A damaged newest snapshot after the trim: named in the start-up summary, and the previous
  // snapshot plus the longer tail (kept by the trim for this) gives the same state.
  fs::remove_all(data);
  fs::copy(pristine, data, fs::copy_options::recursive);
  std::vector<fs::path> snaps;
  for (const auto& e : fs::directory_iterator(data / "snapshots")) snaps.push_back(e.path());
  std::sort(snaps.begin(), snaps.end());
  ASSERT_GE(snaps.size(), 2u);
  {
    std::fstream f(snaps.back(), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(100);
    f.put('\x5a');
  }
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_NE((*scene)->recovery_summary().find(snaps.back().string()), std::string::npos)
        << (*scene)->recovery_summary();
    EXPECT_EQ((*scene)->StateHash("clay"), hash);
  }
  fs::remove_all(root);
}

// A full disk (a 2 MiB tmpfs, so root only; skipped otherwise): the stroke is refused with
// RESOURCE_EXHAUSTED naming the directory and the free bytes, nothing of it is applied, and the
// same stroke succeeds once space is freed, without a restart.
TEST(CrashTest, FullDiskRefusesNamedAndResumesWhenSpaceReturns) {
  const fs::path mnt = fs::temp_directory_path() / ("sculptd_full_" + std::to_string(getpid()));
  fs::create_directories(mnt);
  if (::mount("tmpfs", mnt.c_str(), "tmpfs", 0, "size=2m") != 0) {
    fs::remove(mnt);
    GTEST_SKIP() << "cannot mount a small tmpfs here (" << std::strerror(errno) << ")";
  }
  struct Unmount {
    fs::path at;
    ~Unmount() {
      ::umount2(at.c_str(), MNT_DETACH);
      std::error_code ec;
      fs::remove_all(at, ec);
    }
  } unmount{mnt};
  ServerConfig config;
  config.data_dir = (mnt / "data").string();
  config.snapshot_every_edits = 0;
  config.snapshot_every_seconds = 0;
  auto scene = Scene::Open(config);
  ASSERT_TRUE(scene.ok()) << scene.status();
  constexpr uint64_t kClient = 5;
  ASSERT_EQ(SubmitAndWait(**scene, kClient, RawClient::PressStroke(1, {0, 0, 13.3})).edits, 4u);
  {
    // Fill the disk.
    std::ofstream filler(mnt / "filler", std::ios::binary);
    const std::string block(4096, 'x');
    while (filler.write(block.data(), block.size())) {
    }
  }
  uint64_t seq = 2;
  StrokeOutcome refused;
  for (; seq < 200; ++seq) {
    refused = SubmitAndWait(**scene, kClient, RawClient::PressStroke(seq, {0, 0.1 * seq, 13.3}));
    if (!refused.status.ok()) break;
  }
  ASSERT_LT(seq, 200u) << "the disk never filled";
  EXPECT_EQ(refused.status.code(), Status::Code::kResourceExhausted) << refused.status;
  const Status::Violation* fe = refused.status.violation();
  ASSERT_NE(fe, nullptr) << refused.status;
  EXPECT_EQ(fe->field, "edit_log.free_bytes");
  EXPECT_FALSE(fe->value.empty());
  EXPECT_NE(refused.status.message().find((mnt / "data" / "log").string()), std::string::npos)
      << refused.status;
  const uint64_t hash_refused = (*scene)->StateHash("clay");
  fs::remove(mnt / "filler");
  const StrokeOutcome retried =
      SubmitAndWait(**scene, kClient, RawClient::PressStroke(seq, {0, 0.1 * seq, 13.3}));
  ASSERT_TRUE(retried.status.ok()) << retried.status;
  EXPECT_FALSE(retried.duplicate);
  EXPECT_EQ(retried.edits, 4u);
  EXPECT_NE((*scene)->StateHash("clay"), hash_refused);
  const uint64_t live = (*scene)->StateHash("clay");
  scene->reset();
  auto again = Scene::Open(config);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ((*again)->StateHash("clay"), live);
}

// Damage in the middle of the log stops start-up with the file, the offset and the seqs at
// stake; `sculptd repair --dry-run` lists what a repair gives up without changing anything;
// `sculptd repair` then lets the scene start from the edits before the damage.
TEST(CrashTest, DamagedLogStopsStartUpAndRepairSaysWhatItDiscards) {
  const fs::path data =
      fs::temp_directory_path() / ("sculptd_repair_" + std::to_string(getpid()));
  fs::remove_all(data);
  ServerConfig config;
  config.data_dir = data.string();
  uint64_t after_first = 0;
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    for (uint64_t i = 1; i <= 3; ++i) {
      ASSERT_EQ(SubmitAndWait(**scene, 3, RawClient::PressStroke(i, {0, 0.5 * i, 13.3}, 4)).edits,
                4u);
      if (i == 1) after_first = (*scene)->StateHash("clay");
    }
  }
  const std::vector<fs::path> segments = Segments(data / "log");
  ASSERT_EQ(segments.size(), 1u);
  const std::vector<uint64_t> offsets = RecordOffsets(segments[0]);
  ASSERT_EQ(offsets.size(), 12u);
  {
    std::fstream f(segments[0], std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(offsets[5] + store::kRecordHeaderBytes));
    const char c = static_cast<char>(f.get());
    f.seekp(static_cast<std::streamoff>(offsets[5] + store::kRecordHeaderBytes));
    f.put(static_cast<char>(c ^ 0x10));  // a pose of the second stroke
  }
  auto refused = Scene::Open(config);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(refused.status().message().find(segments[0].string()), std::string::npos);
  EXPECT_NE(refused.status().message().find("offset " + std::to_string(offsets[5])),
            std::string::npos)
      << refused.status();
  EXPECT_NE(refused.status().message().find("sculptd repair"), std::string::npos);

  auto run = [](const std::string& args) {
    const std::string cmd = std::string(SCULPT_BIN_DIR) + "/sculptd repair " + args + " 2>&1";
    std::string out;
    FILE* p = ::popen(cmd.c_str(), "r");
    char buf[512];
    while (p != nullptr && std::fgets(buf, sizeof(buf), p) != nullptr) out += buf;
    const int rc = p != nullptr ? ::pclose(p) : -1;
    return std::make_pair(rc, out);
  };
  const auto before = fs::file_size(segments[0]);
  const auto [dry_rc, dry] = run("--data " + data.string() + " --dry-run");
  EXPECT_EQ(dry_rc, 0) << dry;
  EXPECT_NE(dry.find("would"), std::string::npos) << dry;
  EXPECT_NE(dry.find("cut " + segments[0].string() + " at offset " + std::to_string(offsets[4])),
            std::string::npos)
      << dry;  // back to the start of the damaged stroke's group
  EXPECT_NE(dry.find("after seq 4"), std::string::npos) << dry;
  EXPECT_NE(dry.find("seq 5..12 (8 records, 1 damaged)"), std::string::npos) << dry;
  EXPECT_EQ(fs::file_size(segments[0]), before) << "a dry run changes nothing";
  const auto [rc, done] = run("--data " + data.string());
  EXPECT_EQ(rc, 0) << done;
  auto scene = Scene::Open(config);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ((*scene)->StateHash("clay"), after_first);
  EXPECT_EQ((*scene)->global_seq(), 4u);
  scene->reset();
  fs::remove_all(data);
}

TEST(CrashTest, KillNineTwentyTimesLosesNoAcknowledgedEdit) {
  const fs::path dir = fs::temp_directory_path() / ("sculptd_crash_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path data = dir / "data";
  std::mt19937 rng(20261121);
  std::uniform_int_distribution<int> life_ms(30, 250);
  constexpr uint64_t kClientId = 4242;
  std::set<uint64_t> acked;
  uint64_t next_seq = 1;
  double max_startup_s = 0;
  for (int round = 0; round < 20; ++round) {
    const auto start = std::chrono::steady_clock::now();
    Daemon d(data, dir / "port");
    const uint16_t port = d.WaitPort();
    ASSERT_NE(port, 0) << "round " << round << ": sculptd did not start";
    // Start-up (recovery included) stays short however many rounds came before: the log is
    // trimmed after snapshots, and a long replay is followed by a prompt snapshot.
    const double startup_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_LE(startup_s, 2.0) << "round " << round;
    max_startup_s = std::max(max_startup_s, startup_s);
    RawClient c(port);
    ASSERT_TRUE(c.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, kClientId)) << round;
    // Stream from a reader thread's point of view: write strokes back to back, collect acks
    // until the kill cuts the connection.
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::milliseconds(life_ms(rng));
    std::thread killer([&] {
      std::this_thread::sleep_until(deadline);
      d.Kill(SIGKILL);
    });
    c.SetTimeoutMs(100);
    while (std::chrono::steady_clock::now() < deadline) {
      const double a = 0.013 * static_cast<double>(next_seq);
      if (!c.Send(RawClient::PressStroke(next_seq, {12.8 * std::cos(a), 12.8 * std::sin(a),
                                                    6 * std::sin(3 * a)},
                                         2))) {
        break;
      }
      ++next_seq;
      while (auto m = c.Read()) {
        if (m->has_ack()) acked.insert(m->ack().client_seq());
        if (m->has_ack() || m->has_error()) break;
      }
    }
    killer.join();
    while (auto m = c.Read()) {
      if (m->has_ack()) acked.insert(m->ack().client_seq());
    }
  }
  ASSERT_GT(acked.size(), 50u);

  std::printf("[ figures  ] %zu strokes acknowledged, slowest start-up %.3f s\n", acked.size(),
              max_startup_s);

  // Every acknowledged stroke the log still holds (those after the trimmed part) is in it with
  // both of its poses; the log stays bounded.
  std::map<uint64_t, int> poses_logged;
  {
    store::RecoveryReport report;
    auto log = store::EditLog::Open((data / "log").string(), store::FsyncPolicy{}, &report);
    ASSERT_TRUE(log.ok()) << log.status();
    EXPECT_LE(report.segments, 5u) << "the log is trimmed after snapshots";
    ASSERT_TRUE((*log)
                    ->ForEachFrom(0,
                                  [&](const store::LogRecord& r) {
                                    v1::EditRecord e;
                                    EXPECT_TRUE(e.ParseFromString(r.payload));
                                    if (e.client_id() == kClientId) ++poses_logged[e.client_seq()];
                                    return Status::Ok();
                                  })
                    .ok());
  }
  ASSERT_FALSE(poses_logged.empty());
  const uint64_t first_logged = poses_logged.begin()->first;
  for (uint64_t s : acked) {
    if (s >= first_logged) {
      EXPECT_EQ(poses_logged[s], 2) << "acknowledged stroke " << s;
    }
  }

  // The recovered state (newest snapshot + tail) equals the previous snapshot plus the longer
  // tail (what a damaged newest snapshot falls back to), and the newest acknowledged stroke's
  // resend is recognised.
  ServerConfig config;
  config.data_dir = data.string();
  uint64_t recovered = 0;
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    recovered = (*scene)->StateHash("clay");
    const StrokeOutcome o =
        SubmitAndWait(**scene, kClientId, RawClient::PressStroke(*acked.rbegin(), {0, 0, 13}, 2));
    EXPECT_TRUE(o.duplicate);
  }
  std::vector<fs::path> snaps;
  for (const auto& e : fs::directory_iterator(data / "snapshots")) snaps.push_back(e.path());
  std::sort(snaps.begin(), snaps.end());
  ASSERT_GE(snaps.size(), 1u);
  if (snaps.size() >= 2) {
    fs::remove(snaps.back());
  } else {
    auto log = store::EditLog::Open((data / "log").string(), store::FsyncPolicy{}, nullptr);
    ASSERT_TRUE(log.ok()) << log.status();
    ASSERT_EQ((*log)->base_seq(), 0u) << "one snapshot left and the log before it dropped";
    fs::remove(snaps.back());
  }
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_EQ((*scene)->StateHash("clay"), recovered);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sculpt::server

namespace sculpt::server {
namespace {

// One sculptd hosting two scenes (docs/scenes.md), killed with SIGKILL: each scene comes back
// from its own data directory with every acknowledged stroke, none in the other.
TEST(CrashTest, KillNineOfAProcessHostingTwoScenesRecoversEachFromItsOwnDirectory) {
  const fs::path dir =
      fs::temp_directory_path() / ("sculptd_crash_scenes_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path data = dir / "data";
  constexpr int kPoses = 4;
  auto sculpt = [](uint16_t port, const std::string& scene, int strokes) {
    v1::JoinScene join;
    join.set_scene(scene);
    RawClient c(port);
    if (!c.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, RawClient::kAutoId, join)) return -1;
    int acked = 0;
    for (int i = 1; i <= strokes; ++i) {
      c.Send(RawClient::PressStroke(i, {0, 0, 12.3}, kPoses));
      if (c.ReadUntil(v1::ServerMessage::kAck)) ++acked;
    }
    return acked;
  };
  auto seq_of = [](uint16_t port, const std::string& scene) -> int64_t {
    v1::JoinScene join;
    join.set_scene(scene);
    RawClient c(port);
    if (!c.Enter("sculpt-dev-viewer", v1::ROLE_VIEWER, RawClient::kAutoId, join)) return -1;
    EXPECT_EQ(c.info().scene(), scene);
    return static_cast<int64_t>(c.info().global_seq());
  };
  {
    Daemon d(data, dir / "port", {"--also-scene", "b", "--http", "off"});
    const uint16_t port = d.WaitPort();
    ASSERT_NE(port, 0) << "sculptd did not start";
    ASSERT_EQ(sculpt(port, "b", 3), 3);
    ASSERT_EQ(sculpt(port, "default", 1), 1);
    d.Kill(SIGKILL);
  }
  EXPECT_TRUE(fs::is_directory(data / "scenes" / "b" / "log"));
  Daemon d(data, dir / "port", {"--also-scene", "b", "--http", "off"});
  const uint16_t port = d.WaitPort();
  ASSERT_NE(port, 0) << "sculptd did not restart";
  EXPECT_EQ(seq_of(port, "b"), 3 * kPoses);
  EXPECT_EQ(seq_of(port, "default"), 1 * kPoses);
  d.Kill(SIGTERM);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sculpt::server
