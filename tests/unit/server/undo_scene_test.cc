// Per-author undo and redo through the scene's commit pipeline (issue 15): logged, acknowledged
// once durable, de-duplicated, recovered after a restart, and equal to a scene that never had
// the undone stroke.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "integration/raw_client.h"
#include "net/wire_acks.h"
#include "net/wire_info.h"
#include "scene/scene.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

class UndoSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() /
            ("sculpt_undo_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(base_);
    config_.fsync = "group";
    config_.group_commit_ms = 2;
    config_.scene.objects.front().radius = 12;
    scene_ = Open("a");
  }
  void TearDown() override {
    scene_.reset();
    fs::remove_all(base_);
  }

  std::unique_ptr<Scene> Open(const std::string& dir) {
    ServerConfig c = config_;
    c.data_dir = (base_ / dir).string();
    auto s = Scene::Open(c);
    EXPECT_TRUE(s.ok()) << s.status();
    return s.ok() ? std::move(s).value() : nullptr;
  }

  // A 3-pose press near the top of the sphere, at x offset `dx`.
  static StrokeOutcome Press(Scene& scene, uint64_t client, uint64_t seq, double dx) {
    const v1::ClientMessage m = testing::RawClient::PressStroke(seq, {dx, 0, 11.2}, 3, 2.0);
    auto limits = scene.LimitsFor("clay");
    EXPECT_TRUE(limits.ok());
    auto stroke = codec::DecodeStroke(m.stroke(), *limits);
    EXPECT_TRUE(stroke.ok()) << stroke.status();
    std::promise<StrokeOutcome> p;
    scene.Submit(client, std::move(stroke).value(), [&p](const StrokeOutcome& o) { p.set_value(o); });
    return p.get_future().get();
  }

  static v1::UndoAck Undo(Scene& scene, uint64_t client, uint64_t seq, bool redo = false) {
    v1::UndoRequest r;
    r.set_client_seq(seq);
    r.set_object("clay");
    r.set_redo(redo);
    return UndoWire(scene, client, r);
  }

  // The scene's undo as the session answers it: decoded at the edge, the outcome as its ack.
  static v1::UndoAck UndoWire(Scene& scene, uint64_t client, const v1::UndoRequest& r) {
    auto command = codec::DecodeUndo(r);
    EXPECT_TRUE(command.ok()) << command.status();
    std::promise<v1::UndoAck> p;
    scene.Undo(client, std::move(command).value(),
               [&p](const UndoCommandOutcome& o) { p.set_value(ToWireAck(o)); });
    return p.get_future().get();
  }

  static v1::HistoryAnswer History(Scene& scene, const std::string& object = "clay",
                                   const std::string& author = "", uint32_t limit = 50) {
    codec::HistoryQuery q;
    q.request_id = 99;
    q.object = object;
    q.author = author;
    q.limit = limit;
    std::promise<v1::HistoryAnswer> p;
    scene.History(q, [&p](const HistoryOutcome& o) { p.set_value(ToWireAnswer(o)); });
    return p.get_future().get();
  }

  // One stroke of any kind as a client sends it: `poses` poses from `from` to `to`.
  struct Edit {
    uint64_t client = 0;
    uint64_t seq = 0;
    v1::EditKind kind = v1::EDIT_KIND_PRESS;
    Vec3 from, to;
    int poses = 3;
    double radius = 2.0;
    double amount = 0.5;
  };
  static StrokeOutcome Submit(Scene& scene, const Edit& e) {
    v1::Stroke s;
    s.set_client_seq(e.seq);
    s.set_object("clay");
    s.set_kind(e.kind);
    s.set_tool(v1::TOOL_KIND_SPHERE);
    s.mutable_tool_size()->set_x(static_cast<float>(e.radius));
    s.set_speed(60);
    s.set_amount(static_cast<float>(e.amount));
    s.mutable_origin()->set_x(static_cast<float>(e.from.x));
    s.mutable_origin()->set_y(static_cast<float>(e.from.y));
    s.mutable_origin()->set_z(static_cast<float>(e.from.z));
    const Vec3 origin{s.origin().x(), s.origin().y(), s.origin().z()};
    std::vector<codec::Pose> p;
    for (int i = 0; i < e.poses; ++i) {
      const double t = e.poses == 1 ? 0 : double(i) / (e.poses - 1);
      p.push_back({e.from + (e.to - e.from) * t, uint32_t(8 * i)});
    }
    s.set_pose_count(static_cast<uint32_t>(e.poses));
    s.set_poses(codec::PackPoses(p, origin, 0.5).value());
    auto limits = scene.LimitsFor("clay");
    EXPECT_TRUE(limits.ok());
    auto stroke = codec::DecodeStroke(s, *limits);
    EXPECT_TRUE(stroke.ok()) << stroke.status();
    if (!stroke.ok()) return {};
    std::promise<StrokeOutcome> done;
    scene.Submit(e.client, std::move(stroke).value(),
                 [&done](const StrokeOutcome& o) { done.set_value(o); });
    StrokeOutcome out = done.get_future().get();
    EXPECT_TRUE(out.status.ok()) << out.status;
    return out;
  }
  // A scene in directory `dir` that got `edits` in order and nothing else: the log without the
  // edits an undo took back, replayed afresh.
  std::unique_ptr<Scene> Fresh(const std::string& dir, const std::vector<Edit>& edits) {
    auto s = Open(dir);
    if (!s) return s;
    for (const Edit& e : edits) Submit(*s, e);
    return s;
  }
  // Volume and reference volume bit for bit, and the state hash.
  static void ExpectSameObject(Scene& a, Scene& b, const std::string& where) {
    EXPECT_EQ(a.StateHash("clay"), b.StateHash("clay")) << where;
    const v1::ObjectInfo ia = ToWireSceneInfo(a.Info()).objects(0);
    const v1::ObjectInfo ib = ToWireSceneInfo(b.Info()).objects(0);
    EXPECT_EQ(ia.volume(), ib.volume()) << where;
    EXPECT_EQ(ia.reference_volume(), ib.reference_volume()) << where;
  }

  fs::path base_;
  ServerConfig config_;
  std::unique_ptr<Scene> scene_;
};

TEST_F(UndoSceneTest, UndoKeepsTheOtherSculptorsOverlappingStrokeAndEqualsAReplayWithoutIt) {
  constexpr uint64_t kA = 11, kB = 22;
  ASSERT_TRUE(Press(*scene_, kA, 1, 0.0).status.ok());
  const uint64_t after_a = scene_->StateHash("clay");
  ASSERT_TRUE(Press(*scene_, kB, 1, 1.5).status.ok());  // overlaps A's
  const uint64_t after_b = scene_->StateHash("clay");

  const v1::UndoAck undo = Undo(*scene_, kA, 1);
  ASSERT_TRUE(undo.accepted()) << undo.error().ShortDebugString();
  EXPECT_EQ(undo.target_seq(), 3u) << "A's stroke ends at seq 3";
  EXPECT_EQ(undo.replayed(), 1u) << "B's overlapping stroke is replayed";
  ASSERT_EQ(undo.replayed_by_size(), 1);
  EXPECT_EQ(undo.replayed_by(0).author(), std::to_string(kB));
  EXPECT_EQ(undo.undo_depth(), 0u);
  EXPECT_EQ(undo.redo_depth(), 1u);
  const uint64_t undone = scene_->StateHash("clay");
  EXPECT_NE(undone, after_b);

  // A scene that only ever got B's stroke.
  auto fresh = Open("fresh");
  ASSERT_TRUE(fresh);
  ASSERT_TRUE(Press(*fresh, kB, 1, 1.5).status.ok());
  EXPECT_EQ(fresh->StateHash("clay"), undone) << "undo differs from a replay without A's stroke";
  EXPECT_NE(fresh->StateHash("clay"), after_a);

  // Redo puts A's stroke back: nobody touched the region since, so the state is exact.
  const v1::UndoAck redo = Undo(*scene_, kA, 2, /*redo=*/true);
  ASSERT_TRUE(redo.accepted()) << redo.error().ShortDebugString();
  EXPECT_EQ(scene_->StateHash("clay"), after_b);
}

TEST_F(UndoSceneTest, NothingToUndoAndOtherAuthorsStrokesAreRefusedByName) {
  const v1::UndoAck none = Undo(*scene_, 11, 1);
  EXPECT_FALSE(none.accepted());
  EXPECT_EQ(none.error().code(), v1::ERROR_CODE_FAILED_PRECONDITION) << none.ShortDebugString();
  ASSERT_TRUE(Press(*scene_, 11, 1, 0.0).status.ok());
  const uint64_t h = scene_->StateHash("clay");
  // Client 22 made nothing: it cannot take back 11's stroke.
  const v1::UndoAck other = Undo(*scene_, 22, 1);
  EXPECT_FALSE(other.accepted());
  EXPECT_EQ(scene_->StateHash("clay"), h);
  const v1::UndoAck redo = Undo(*scene_, 11, 2, /*redo=*/true);
  EXPECT_FALSE(redo.accepted()) << "nothing was undone";
  EXPECT_EQ(redo.error().code(), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(redo.error().field(), "UndoRequest.redo");
  EXPECT_EQ(scene_->StateHash("clay"), h);
}

TEST_F(UndoSceneTest, AResentUndoIsADuplicateAndTakesBackNothingMore) {
  ASSERT_TRUE(Press(*scene_, 11, 1, 0.0).status.ok());
  const uint64_t first = scene_->StateHash("clay");
  ASSERT_TRUE(Press(*scene_, 11, 2, 3.0).status.ok());
  ASSERT_TRUE(Undo(*scene_, 11, 1).accepted());
  EXPECT_EQ(scene_->StateHash("clay"), first);
  const v1::UndoAck again = Undo(*scene_, 11, 1);
  EXPECT_TRUE(again.accepted());
  EXPECT_TRUE(again.duplicate());
  EXPECT_EQ(scene_->StateHash("clay"), first) << "the resend undid a second stroke";
  EXPECT_EQ(scene_->UndoDepth("clay", 11), std::make_pair(size_t{1}, size_t{1}));
}

TEST_F(UndoSceneTest, RecoveryReplaysUndoAndRedoToTheSameState) {
  ASSERT_TRUE(Press(*scene_, 11, 1, 0.0).status.ok());
  ASSERT_TRUE(Press(*scene_, 22, 1, 1.5).status.ok());
  const uint64_t both = scene_->StateHash("clay");
  ASSERT_TRUE(Undo(*scene_, 11, 1).accepted());
  const uint64_t undone = scene_->StateHash("clay");
  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  EXPECT_EQ(scene_->StateHash("clay"), undone);
  // The history came back with the log: the redo after the restart returns the exact state.
  const v1::UndoAck redo = Undo(*scene_, 11, 2, /*redo=*/true);
  ASSERT_TRUE(redo.accepted()) << redo.error().ShortDebugString();
  EXPECT_EQ(scene_->StateHash("clay"), both);
}

TEST_F(UndoSceneTest, AlternatingUndoAndRedoDoesNotDrift) {
  ASSERT_TRUE(Press(*scene_, 11, 1, 0.0).status.ok());
  ASSERT_TRUE(Press(*scene_, 22, 1, 1.0).status.ok());
  const uint64_t both = scene_->StateHash("clay");
  uint64_t undone = 0;
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(Undo(*scene_, 11, 2 * i + 1).accepted()) << i;
    if (i == 0) undone = scene_->StateHash("clay");
    EXPECT_EQ(scene_->StateHash("clay"), undone) << "undo " << i << " drifted";
    ASSERT_TRUE(Undo(*scene_, 11, 2 * i + 2, /*redo=*/true).accepted()) << i;
    EXPECT_EQ(scene_->StateHash("clay"), both) << "redo " << i << " drifted";
  }
}


// Hard case: the undone stroke's region later got 30 overlapping strokes of four kinds from three
// other sculptors. The undo replays them without it; the object is bit-identical (hash, volume,
// reference volume) to a scene that got only the 30.
TEST_F(UndoSceneTest, UndoUnderThirtyOverlappingStrokesFromThreeOthersEqualsAFreshReplay) {
  constexpr uint64_t kA = 11;
  const uint64_t others[3] = {22, 33, 44};
  const v1::EditKind kinds[4] = {v1::EDIT_KIND_PRESS, v1::EDIT_KIND_ADD, v1::EDIT_KIND_SMOOTH,
                                 v1::EDIT_KIND_SUBTRACT};
  const Edit a{kA, 1, v1::EDIT_KIND_PRESS, {-2, 0, 11.5}, {2, 0.5, 11.2}, 4, 2.0};
  ASSERT_TRUE(Submit(*scene_, a).status.ok());
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> jitter(-2.0, 2.0);
  std::vector<Edit> later;
  uint64_t seqs[3] = {0, 0, 0};
  for (int i = 0; i < 30; ++i) {
    const uint64_t who = others[i % 3];
    later.push_back({who, ++seqs[i % 3], kinds[i % 4], {jitter(rng), jitter(rng), 11.8},
                     {jitter(rng), jitter(rng), 11.4}, 3, 1.5, 0.5});
    ASSERT_TRUE(Submit(*scene_, later.back()).status.ok()) << i;
  }
  const v1::UndoAck undo = Undo(*scene_, kA, 1);
  ASSERT_TRUE(undo.accepted()) << undo.error().ShortDebugString();
  EXPECT_EQ(undo.target_seq(), 4u) << "A's stroke: seqs 1..4";
  EXPECT_GE(undo.replayed(), 20u) << "most of the 30 overlap A's stroke or read its volume";
  ASSERT_EQ(undo.replayed_by_size(), 3) << undo.ShortDebugString();
  uint32_t sum = 0;
  for (const v1::ReplayedEdits& r : undo.replayed_by()) sum += r.edits();
  EXPECT_EQ(sum, undo.replayed());
  auto fresh = Fresh("fresh", later);
  ASSERT_TRUE(fresh);
  ExpectSameObject(*scene_, *fresh, "undo under 30 later strokes vs the log without A's");
}

// Hard case: undo across a snapshot and a log trim, and after a restart. The same edits go to
// three data directories: `a` is restarted gracefully, `crashed` is a copy of a taken while it
// ran (as after kill -9 once every ack was durable), `control` never restarts. A's first stroke
// is older than both snapshot rounds, so its records are no longer in the log: only the history
// kept beside the snapshot can take it back. Every undo and redo gives the same object in the
// three, and the result equals a fresh replay without A's strokes.
TEST_F(UndoSceneTest, UndoAcrossASnapshotAndALogTrimAndAfterARestartEqualsNoRestart) {
  config_.snapshot_every_edits = 0;  // snapshots only when asked
  config_.snapshot_every_seconds = 0;
  scene_ = Open("a");
  auto control = Open("control");
  ASSERT_TRUE(scene_ && control);
  constexpr uint64_t kA = 11, kB = 22, kC = 33;
  const Edit a1{kA, 1, v1::EDIT_KIND_PRESS, {-1, 0, 11.5}, {1, 0.5, 11.2}, 3};
  const Edit b1{kB, 1, v1::EDIT_KIND_PRESS, {0, -1, 11.5}, {0.5, 1, 11.2}, 3};
  const Edit c1{kC, 1, v1::EDIT_KIND_ADD, {1, 1, 11.8}, {-1, 1, 11.8}, 3, 1.5};
  const Edit a2{kA, 2, v1::EDIT_KIND_PRESS, {1, -1, 11.5}, {-0.5, 0, 11.2}, 3};
  const Edit b2{kB, 2, v1::EDIT_KIND_SMOOTH, {-1, 0, 11.6}, {1, 0, 11.6}, 3, 2.0, 1.0};
  for (Scene* s : {scene_.get(), control.get()}) {
    Submit(*s, a1);
    Submit(*s, b1);
  }
  scene_->FlushAndSnapshot();  // round 1
  for (Scene* s : {scene_.get(), control.get()}) {
    Submit(*s, c1);
    Submit(*s, a2);
  }
  scene_->FlushAndSnapshot();  // round 2: the log before round 1 goes
  for (Scene* s : {scene_.get(), control.get()}) Submit(*s, b2);
  scene_->Flush();

  // The log no longer holds A's first stroke (seqs 1..3).
  uint64_t oldest_segment = UINT64_MAX;
  for (const auto& f : fs::directory_iterator(base_ / "a" / "log")) {
    uint64_t first = 0;
    if (std::sscanf(f.path().filename().c_str(), "log-%" SCNu64 ".sclog", &first) == 1) {
      oldest_segment = std::min(oldest_segment, first);
    }
  }
  ASSERT_NE(oldest_segment, UINT64_MAX);
  EXPECT_GT(oldest_segment, 3u) << "the log was not trimmed past A's first stroke";

  fs::copy(base_ / "a", base_ / "crashed", fs::copy_options::recursive);
  scene_.reset();
  scene_ = Open("a");
  auto crashed = Open("crashed");
  ASSERT_TRUE(scene_ && crashed);
  ExpectSameObject(*scene_, *control, "after the restart");
  ExpectSameObject(*crashed, *control, "after the crash");
  EXPECT_EQ(scene_->UndoDepth("clay", kA), std::make_pair(size_t{2}, size_t{0}))
      << "the history did not survive the restart";

  Scene* all[3] = {scene_.get(), crashed.get(), control.get()};
  v1::UndoAck acks[3];
  for (int i = 0; i < 3; ++i) acks[i] = Undo(*all[i], kA, 1);  // a2
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(acks[i].accepted()) << i << " " << acks[i].error().ShortDebugString();
    EXPECT_EQ(acks[i].target_seq(), acks[2].target_seq()) << i;
    EXPECT_EQ(acks[i].replayed(), acks[2].replayed()) << i;
  }
  for (int i = 0; i < 3; ++i) acks[i] = Undo(*all[i], kA, 2);  // a1, before both snapshots
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(acks[i].accepted()) << i << " " << acks[i].error().ShortDebugString();
    EXPECT_EQ(acks[i].target_seq(), 3u) << i;
  }
  ExpectSameObject(*scene_, *control, "both of A's strokes undone after the restart");
  ExpectSameObject(*crashed, *control, "both of A's strokes undone after the crash");
  auto fresh = Fresh("fresh", {b1, c1, b2});
  ASSERT_TRUE(fresh);
  ExpectSameObject(*scene_, *fresh, "the log without A's strokes");

  for (Scene* s : all) ASSERT_TRUE(Undo(*s, kA, 3, /*redo=*/true).accepted());
  ExpectSameObject(*scene_, *control, "redo after the restart");
  ExpectSameObject(*crashed, *control, "redo after the crash");
  auto fresh2 = Fresh("fresh2", {a1, b1, c1, b2});
  ASSERT_TRUE(fresh2);
  ExpectSameObject(*scene_, *fresh2, "the log without A's second stroke");
}

// The history is kept per snapshot round: when the newest snapshot is damaged and start-up falls
// back to the previous one (and the longer log tail), the history kept with that one is loaded,
// and what was undoable before it still is. Each round's history file is written after its
// snapshot, off the compute thread.
TEST_F(UndoSceneTest, AFallbackToTheOlderSnapshotLoadsTheHistoryKeptWithIt) {
  config_.snapshot_every_edits = 0;  // snapshots only when asked
  config_.snapshot_every_seconds = 0;
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  constexpr uint64_t kA = 11, kB = 22;
  const Edit a1{kA, 1, v1::EDIT_KIND_PRESS, {-1, 0, 11.5}, {1, 0.5, 11.2}, 3};
  const Edit b1{kB, 1, v1::EDIT_KIND_PRESS, {0, -1, 11.5}, {0.5, 1, 11.2}, 3};
  const Edit a2{kA, 2, v1::EDIT_KIND_PRESS, {1, -1, 11.5}, {-0.5, 0, 11.2}, 3};
  Submit(*scene_, a1);
  scene_->FlushAndSnapshot();  // round 1, at seq 3
  Submit(*scene_, b1);
  Submit(*scene_, a2);
  scene_->FlushAndSnapshot();  // round 2, at seq 9
  EXPECT_TRUE(fs::exists(base_ / "a" / "history" / "clay.3.bin"));
  EXPECT_TRUE(fs::exists(base_ / "a" / "history" / "clay.9.bin"));
  scene_.reset();

  // Damage round 2's snapshot: start-up skips it for round 1's plus the log after seq 3.
  fs::path newest;  // file names carry the seq zero-padded: the largest is round 2's
  for (const auto& f : fs::directory_iterator(base_ / "a" / "snapshots")) {
    if (f.path().filename().string().find("clay") != std::string::npos &&
        (newest.empty() || f.path().filename() > newest.filename())) {
      newest = f.path();
    }
  }
  ASSERT_FALSE(newest.empty()) << "no snapshot file of round 2";
  {
    std::fstream f(newest, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(fs::file_size(newest) / 2));
    f.put('\x5a');
  }
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  auto fresh = Fresh("fresh", {a1, b1, a2});
  ASSERT_TRUE(fresh);
  ExpectSameObject(*scene_, *fresh, "after the fallback");
  // a1 is older than round 1: only the history kept with round 1's snapshot can take it back.
  EXPECT_EQ(scene_->UndoDepth("clay", kA), std::make_pair(size_t{2}, size_t{0}));
  ASSERT_TRUE(Undo(*scene_, kA, 1).accepted());
  const v1::UndoAck second = Undo(*scene_, kA, 2);
  ASSERT_TRUE(second.accepted()) << second.error().ShortDebugString();
  EXPECT_EQ(second.target_seq(), 3u);
  auto without_a = Fresh("without_a", {b1});
  ASSERT_TRUE(without_a);
  ExpectSameObject(*scene_, *without_a, "both of A's strokes undone after the fallback");
}

// Hard case: two authors undo at the same time in the same region (both requests queued before
// either is answered). Both are taken back and the object equals the log without both strokes.
TEST_F(UndoSceneTest, TwoAuthorsUndoingAtTheSameTimeInTheSameRegion) {
  constexpr uint64_t kA = 11, kB = 22, kC = 33;
  const std::vector<Edit> edits = {
      {kA, 1, v1::EDIT_KIND_PRESS, {-1, 0, 11.5}, {1, 0.5, 11.2}, 3},
      {kB, 1, v1::EDIT_KIND_PRESS, {0, -1, 11.5}, {0.5, 1, 11.2}, 3},
      {kC, 1, v1::EDIT_KIND_ADD, {1, 1, 11.8}, {-1, 1, 11.8}, 3, 1.5},
      {kA, 2, v1::EDIT_KIND_SMOOTH, {-1, 0, 11.6}, {1, 0, 11.6}, 3, 2.0, 1.0},
      {kB, 2, v1::EDIT_KIND_SUBTRACT, {0.5, -0.5, 12}, {-0.5, 0.5, 12}, 3, 1.2},
      {kC, 2, v1::EDIT_KIND_PRESS, {0, 0, 11.5}, {0.5, -0.5, 11.3}, 3}};
  for (const Edit& e : edits) ASSERT_TRUE(Submit(*scene_, e).status.ok());

  auto both = [&](uint64_t seq) {
    v1::UndoRequest r;
    r.set_client_seq(seq);
    r.set_object("clay");
    v1::UndoAck a, b;
    std::thread ta([&] { a = UndoWire(*scene_, kA, r); });
    std::thread tb([&] { b = UndoWire(*scene_, kB, r); });
    ta.join();
    tb.join();
    return std::make_pair(a, b);
  };
  const auto [a1, b1] = both(1);  // A's smooth and B's subtract
  ASSERT_TRUE(a1.accepted()) << a1.error().ShortDebugString();
  ASSERT_TRUE(b1.accepted()) << b1.error().ShortDebugString();
  EXPECT_EQ(a1.target_seq(), 12u);
  EXPECT_EQ(b1.target_seq(), 15u);
  auto fresh = Fresh("fresh", {edits[0], edits[1], edits[2], edits[5]});
  ASSERT_TRUE(fresh);
  ExpectSameObject(*scene_, *fresh, "both second strokes undone at once");

  const auto [a2, b2] = both(2);  // their first presses
  ASSERT_TRUE(a2.accepted() && b2.accepted());
  EXPECT_EQ(a2.target_seq(), 3u);
  EXPECT_EQ(b2.target_seq(), 6u);
  auto fresh2 = Fresh("fresh2", {edits[2], edits[5]});
  ASSERT_TRUE(fresh2);
  ExpectSameObject(*scene_, *fresh2, "all of A's and B's strokes undone");
}

// Hard case: A's press cuts the tip off a bar, and the island is removed; others then work by the
// cut. A's undo brings the tip back, the reference volume no longer counts the removal, and the
// object equals the log without A's press; the redo cuts it off again.
TEST_F(UndoSceneTest, UndoOfAStrokeThatCutOffAnIslandWhichWasRemoved) {
  ObjectConfig& bar = config_.scene.objects.front();
  bar.primitive = "capsule";
  bar.center = {-10, 0, 0};
  bar.end = {10, 0, 0};
  bar.radius = 1.5;
  config_.scene.effects.islands = "remove_small";
  config_.scene.effects.min_island_volume = 125;  // the 3-unit tip is ~35
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  constexpr uint64_t kA = 11, kB = 22, kC = 33;
  double reference0 = ToWireSceneInfo(scene_->Info()).objects(0).reference_volume();
  const Edit cut{kA, 1, v1::EDIT_KIND_PRESS, {7, 0, -3}, {7, 0, 3}, 5, 2.0};
  const StrokeOutcome o = Submit(*scene_, cut);
  ASSERT_TRUE(o.status.ok());
  ASSERT_GE(o.last.islands_removed, 1) << "the press did not cut the tip off";
  EXPECT_LT(ToWireSceneInfo(scene_->Info()).objects(0).reference_volume(), reference0);
  auto sample = [](Scene& s, Vec3 p) {
    double v = 0;
    EXPECT_TRUE(s.Inspect("clay", [&](const levelset::Sculpture& x) { v = x.SampleWorld(p); }));
    return v;
  };
  EXPECT_GT(sample(*scene_, {9.5, 0, 0}), 0.0) << "the tip is gone";
  const std::vector<Edit> later = {
      {kB, 1, v1::EDIT_KIND_ADD, {5.5, 0, 1.5}, {5.5, 0, -1.5}, 4, 1.25},
      {kC, 1, v1::EDIT_KIND_PRESS, {-5, 1.5, 0}, {-5, 1, 0}, 3}};
  for (const Edit& e : later) ASSERT_TRUE(Submit(*scene_, e).status.ok());
  const uint64_t with_cut = scene_->StateHash("clay");

  const v1::UndoAck undo = Undo(*scene_, kA, 1);
  ASSERT_TRUE(undo.accepted()) << undo.error().ShortDebugString();
  EXPECT_GE(undo.replayed(), 1u);
  EXPECT_LT(sample(*scene_, {9.5, 0, 0}), 0.0) << "the tip did not come back";
  auto fresh = Fresh("fresh", later);
  ASSERT_TRUE(fresh);
  ExpectSameObject(*scene_, *fresh, "undo of the cut vs the log without it");

  ASSERT_TRUE(Undo(*scene_, kA, 2, /*redo=*/true).accepted());
  EXPECT_GT(sample(*scene_, {9.5, 0, 0}), 0.0) << "the redo did not cut the tip off again";
  EXPECT_EQ(scene_->StateHash("clay"), with_cut) << "redo differs from before the undo";
}

uint64_t WallMs() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

// The history view: the object's edits newest first with author, kind, commit time, sequence and
// whether each is undone; filtered by author, cut at the limit; the same after a restart that
// replays the log and after one that loads the history kept with a snapshot.
TEST_F(UndoSceneTest, HistoryListsEditsNewestFirstWithAuthorKindTimeAndUndone) {
  constexpr uint64_t kA = 11, kB = 22;
  const uint64_t t0 = WallMs();
  ASSERT_TRUE(
      Submit(*scene_, {kA, 1, v1::EDIT_KIND_PRESS, {-1, 0, 11.5}, {1, 0, 11.2}, 3}).status.ok());
  ASSERT_TRUE(
      Submit(*scene_, {kB, 1, v1::EDIT_KIND_ADD, {0, 1, 11.8}, {0, -1, 11.8}, 4, 1.5}).status.ok());
  ASSERT_TRUE(
      Submit(*scene_, {kA, 2, v1::EDIT_KIND_SMOOTH, {-1, 0, 11.6}, {1, 0, 11.6}, 2, 2.0, 1.0})
          .status.ok());
  const uint64_t t1 = WallMs();
  ASSERT_TRUE(Undo(*scene_, kA, 1).accepted());  // A's smooth

  const v1::HistoryAnswer all = History(*scene_);
  ASSERT_FALSE(all.has_error()) << all.error().ShortDebugString();
  EXPECT_EQ(all.request_id(), 99u);
  EXPECT_EQ(all.object(), "clay");
  EXPECT_EQ(all.matching(), 3u);
  EXPECT_EQ(all.held(), 3u);
  ASSERT_EQ(all.entries_size(), 3);
  const uint64_t seqs[3] = {9, 7, 3};
  const char* authors[3] = {"11", "22", "11"};
  const v1::EditKind kinds[3] = {v1::EDIT_KIND_SMOOTH, v1::EDIT_KIND_ADD, v1::EDIT_KIND_PRESS};
  const uint32_t poses[3] = {2, 4, 3};
  for (int i = 0; i < 3; ++i) {
    const v1::HistoryEntry& e = all.entries(i);
    EXPECT_EQ(e.seq(), seqs[i]) << i;
    EXPECT_EQ(e.author(), authors[i]) << i;
    EXPECT_EQ(e.kind(), kinds[i]) << i;
    EXPECT_EQ(e.poses(), poses[i]) << i;
    EXPECT_FALSE(e.sweep()) << i;
    EXPECT_GE(e.time_ms(), t0) << i;
    EXPECT_LE(e.time_ms(), t1) << i;
    EXPECT_EQ(e.undone(), i == 0) << i;
    EXPECT_EQ(e.undoable(), i != 0) << i;
  }
  EXPECT_LE(all.entries(1).time_ms(), all.entries(0).time_ms());

  const v1::HistoryAnswer b = History(*scene_, "clay", "22");
  ASSERT_EQ(b.entries_size(), 1);
  EXPECT_EQ(b.entries(0).seq(), 7u);
  EXPECT_EQ(b.matching(), 1u);
  EXPECT_EQ(b.held(), 3u);
  const v1::HistoryAnswer two = History(*scene_, "clay", "", 2);
  ASSERT_EQ(two.entries_size(), 2);
  EXPECT_EQ(two.entries(1).seq(), 7u);
  EXPECT_EQ(two.matching(), 3u);
  EXPECT_EQ(History(*scene_, "clay", "nobody").entries_size(), 0);

  // Recovery replays the log through the history with each stroke's logged commit time, then a
  // snapshot keeps the history (times included) beside the object.
  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const v1::HistoryAnswer replayed = History(*scene_);
  EXPECT_EQ(replayed.SerializeAsString(), all.SerializeAsString())
      << replayed.ShortDebugString() << "\nvs\n"
      << all.ShortDebugString();
  scene_->FlushAndSnapshot();
  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const v1::HistoryAnswer loaded = History(*scene_);
  EXPECT_EQ(loaded.SerializeAsString(), all.SerializeAsString())
      << loaded.ShortDebugString() << "\nvs\n"
      << all.ShortDebugString();
}

TEST_F(UndoSceneTest, HistoryOfAnUnknownObjectIsNotFound) {
  const v1::HistoryAnswer a = History(*scene_, "marble");
  ASSERT_TRUE(a.has_error());
  EXPECT_EQ(a.error().code(), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(a.error().field(), "HistoryRequest.object");
  EXPECT_EQ(a.error().value(), "marble");
  EXPECT_EQ(a.entries_size(), 0);
  EXPECT_EQ(a.request_id(), 99u);
}

}  // namespace
}  // namespace sculpt::server
