// Fencing by epoch (issue 17, docs/cluster.md "Fencing"): the owner writes its ownership epoch
// into every stroke record it logs and stamps every EditBroadcast and LeafDelta it sends; a
// standby takes only frames of the epoch etcd names for the owner it follows and logs them with
// that epoch. The first tests run the real server in-process with a fence granted by the test
// (no etcd) and a real StandbyFollower on loopback, so each epoch is chosen, not raced for; the
// last runs two sculptd members and etcd through a paused owner's failover.
#include <gtest/gtest.h>
#include <signal.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "cluster/ownership_fence.h"
#include "cluster/processes.h"
#include "cluster/records.h"
#include "cluster/scene_router.h"
#include "cluster/standby_follower.h"
#include "integration/in_process_server.h"
#include "integration/raw_client.h"
#include "scene/commit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/skin/skin.h"
#include "sculpt/v1/sculpt.pb.h"
#include "store/edit_log.h"
#include "store/recovery.h"

namespace sculpt::server::cluster {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

struct Logged {
  uint64_t seq = 0;
  uint64_t epoch = 0;
  bool stroke = false;
  std::string payload;
};

// The epoch a record of any kind carries (field 16 of its message; 0 when absent).
uint64_t EpochOf(const std::string& payload) {
  auto decoded = codec::DecodeLogRecord(0, payload);
  EXPECT_TRUE(decoded.ok()) << decoded.status();
  return decoded.ok() ? codec::RecordEpoch(*decoded) : 0;
}

// Every record of the edit log of `data_dir`, read back with the store's reader, with the epoch
// each carries.
std::vector<Logged> ReadLog(const fs::path& data_dir) {
  store::RecoveryReport report;
  auto log =
      store::EditLog::Open((data_dir / store::kLogSubdir).string(), store::FsyncPolicy{}, &report);
  EXPECT_TRUE(log.ok()) << log.status();
  if (!log.ok()) return {};
  auto records = (*log)->ReadFrom(0);
  EXPECT_TRUE(records.ok()) << records.status();
  if (!records.ok()) return {};
  std::vector<Logged> out;
  for (const store::LogRecord& r : *records) {
    auto decoded = DecodeLogRecord(r.seq, r.payload);
    EXPECT_TRUE(decoded.ok()) << decoded.status();
    Logged l;
    l.seq = r.seq;
    l.epoch = EpochOf(r.payload);
    l.stroke = decoded.ok() && std::holds_alternative<codec::StrokePoseRecord>(decoded->record);
    l.payload = r.payload;
    out.push_back(std::move(l));
  }
  return out;
}

// Snapshot sequences in a data directory (snap-<20-digit seq>...).
std::vector<uint64_t> SnapshotSeqs(const fs::path& data_dir) {
  std::vector<uint64_t> seqs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(data_dir / store::kSnapshotSubdir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("snap-", 0) == 0 && name.size() >= 25) {
      seqs.push_back(std::stoull(name.substr(5, 20)));
    }
  }
  return seqs;
}

TEST(RecordEpochTest, StrokeAndTaggedRecordsCarryTheEpochAndZeroAddsNothing) {
  codec::StrokePoseRecord pose;
  pose.global_seq = 5;
  pose.client_id = 9;
  pose.client_seq = 2;
  pose.object = "clay";
  pose.pose_count = 1;
  const std::string plain = codec::EncodeLogRecord(pose);
  std::string with = plain;
  codec::AppendRecordEpoch(&with, 0);
  EXPECT_EQ(with, plain) << "epoch 0 must leave the bytes as they were";
  codec::AppendRecordUser(&with, "ada");
  codec::AppendRecordEpoch(&with, 12);
  EXPECT_EQ(EpochOf(with), 12u);
  EXPECT_EQ(EpochOf(plain), 0u);
  auto decoded = DecodeLogRecord(5, with);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  const auto& back = std::get<codec::StrokePoseRecord>(decoded->record);
  EXPECT_EQ(back.user, "ada");
  EXPECT_EQ(back.client_seq, 2u);

  codec::UndoRecord undo;
  undo.global_seq = 6;
  undo.client_id = 9;
  const std::string tagged = codec::EncodeLogRecord(undo);
  std::string tagged_with = tagged;
  codec::AppendRecordEpoch(&tagged_with, 0);
  EXPECT_EQ(tagged_with, tagged) << "epoch 0 must leave a tagged record as it was";
  codec::AppendRecordEpoch(&tagged_with, 12);
  EXPECT_EQ(EpochOf(tagged_with), 12u);
  EXPECT_EQ(EpochOf(tagged), 0u);
  EXPECT_EQ(tagged_with[0], tagged[0]) << "still an undo";
}

// A region load names its book files by path; the standby writes only these (untrusted input
// from another member: nothing outside the copy's skins/ and models/).
TEST(BookFilePathTest, TakesSkinAndModelFilesOnly) {
  for (const char* ok : {"skins/profile.pb", "skins/profile.history", "models/part.json",
                         "models/part.history", "skins/a-b_c.1.pb"}) {
    EXPECT_TRUE(IsBookFilePath(ok)) << ok;
  }
  for (const char* bad :
       {"skins/../x.pb", "../skins/x.pb", "skins/.hidden.pb", "skins/x.json", "models/x.pb",
        "snapshots/x.pb", "skins/x", "skins/.pb", "x.pb", "skins/a b.pb", "skins/a/b.pb", "",
        "/skins/x.pb", "log/seg.history"}) {
    EXPECT_FALSE(IsBookFilePath(bad)) << bad;
  }
  EXPECT_FALSE(IsBookFilePath("skins/" + std::string(200, 'a') + ".pb")) << "over 200 characters";
}

// This member ("a") owns the scene and names "b" its standby.
class FixedRouter : public SceneRouter {
 public:
  Route RouteScene(const std::string& scene) const override {
    Route r;
    r.kind = Route::Kind::kLocal;
    r.scene = scene;
    r.member = "a";
    r.epoch = 7;
    r.standby = "b";
    return r;
  }
};

class EpochFenceTest : public ::testing::Test {
 protected:
  // The owner in cluster mode (no agent: the test grants its fence at `epoch`), or a single
  // process (epoch 0: no cluster settings, no fence).
  void StartOwner(uint64_t epoch) {
    if (epoch != 0) {
      auto& c = server_.config().cluster;
      c.etcd = {"http://127.0.0.1:9"};  // read by nobody: no agent runs here
      c.member = "a";
    }
    ASSERT_TRUE(server_.Start());
    if (epoch == 0) return;
    server_.server().set_router(&router_);
    fence_->Grant(epoch, OwnershipFence::Clock::now() + std::chrono::hours(1));
    server_.scene().set_ownership_fence(fence_);
  }
  // A standby "b" following the owner, told by "etcd" that the owner holds `epoch`.
  // The copy snapshots every `snapshot_every_records` records it logs.
  std::unique_ptr<StandbyFollower> Follow(uint64_t epoch,
                                          uint64_t snapshot_every_records = 5000) {
    FollowerOptions fo;
    fo.data_dir = standby_data_.string();
    fo.scene = "default";
    fo.member = "b";
    fo.token = server_.config().viewer_token;
    fo.owner_tcp = "127.0.0.1:" + std::to_string(server_.port());
    fo.owner_epoch = epoch;
    fo.stale_epoch_refusals = refusals_;
    fo.snapshot_every_records = snapshot_every_records;
    // The scene as the owner hosts it: the copy keeps its skins and models.
    fo.books = {.skins = server_.config().scene.skins,
                .objects = server_.config().scene.objects,
                .undo_depth = server_.config().limits.undo_depth};
    return std::make_unique<StandbyFollower>(std::move(fo));
  }
  // One acknowledged stroke of `poses` poses; returns the scene's sequence after it.
  uint64_t Sculpt(uint64_t client_seq, int poses = 3) {
    if (!sculptor_) {
      sculptor_ = std::make_unique<RawClient>(server_.port());
      EXPECT_TRUE(sculptor_->Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, 77));
    }
    EXPECT_TRUE(
        sculptor_->Send(RawClient::PressStroke(client_seq, {-3.0 + client_seq, 0, 22.5}, poses)));
    auto ack = sculptor_->ReadUntil(v1::ServerMessage::kAck);
    EXPECT_TRUE(ack.has_value()) << "no ack for stroke " << client_seq;
    return ack ? ack->ack().global_seq_first() + ack->ack().edits() - 1 : 0;
  }
  // Undoes the sculptor's newest edit on `object` (an object's strokes, or a skin's ball edits:
  // a tagged record in the log); returns the answer, or an empty one.
  v1::UndoAck Undo(uint64_t client_seq, const std::string& object) {
    v1::ClientMessage m;
    m.mutable_undo()->set_client_seq(client_seq);
    m.mutable_undo()->set_object(object);
    EXPECT_TRUE(sculptor_->Send(m));
    auto a = sculptor_->ReadUntil(v1::ServerMessage::kUndoAck);
    EXPECT_TRUE(a.has_value()) << "no answer to the undo of " << object;
    EXPECT_TRUE(!a || a->undo_ack().accepted()) << (a ? a->DebugString() : "");
    return a ? a->undo_ack() : v1::UndoAck{};
  }
  bool UndoStroke(uint64_t client_seq) { return Undo(client_seq, "clay").accepted(); }
  // A ball edit of the sculptor's on skin "profile" (moves or adds ball `index`); returns its
  // answer, or an empty one.
  v1::SkinAck EditBall(uint64_t client_seq, v1::SkinBallOp op, uint32_t index, double x, double y) {
    v1::ClientMessage m;
    v1::SkinBallEdit* e = m.mutable_skin_ball_edit();
    e->set_client_seq(client_seq);
    e->set_skin("profile");
    e->set_op(op);
    e->set_index(index);
    e->mutable_ball()->set_x(x);
    e->mutable_ball()->set_y(y);
    e->mutable_ball()->set_r(2.5);
    EXPECT_TRUE(sculptor_->Send(m));
    auto a = sculptor_->ReadUntil(v1::ServerMessage::kSkinAck);
    EXPECT_TRUE(a.has_value()) << "no answer to ball edit " << client_seq;
    EXPECT_TRUE(!a || a->skin_ack().accepted()) << (a ? a->DebugString() : "");
    return a ? a->skin_ack() : v1::SkinAck{};
  }
  // A replay replica (a viewer), subscribed to the object; returns its region load.
  std::optional<v1::ServerMessage> Subscribe(RawClient& c) {
    EXPECT_TRUE(c.Enter("sculpt-dev-viewer", v1::ROLE_VIEWER));
    v1::ClientMessage s;
    s.mutable_subscribe()->set_object("clay");
    s.mutable_subscribe()->set_mode(v1::REPLICA_MODE_REPLAY);
    EXPECT_TRUE(c.Send(s));
    return c.ReadUntil(v1::ServerMessage::kLeafDelta);
  }
  fs::path Copy() {
    auto copy = CurrentStandbyCopy(standby_data_.string(), "default");
    return copy ? fs::path(*copy) : fs::path();
  }

  sculpt::testing_support::InProcessServer server_{"epoch_fence"};
  FixedRouter router_;
  std::shared_ptr<OwnershipFence> fence_ = std::make_shared<OwnershipFence>("default");
  std::shared_ptr<std::atomic<uint64_t>> refusals_ = std::make_shared<std::atomic<uint64_t>>(0);
  std::unique_ptr<RawClient> sculptor_;
  fs::path standby_data_ = server_.dir() / "b-data";
};

TEST_F(EpochFenceTest, OwnerAndStandbyCopyLogEveryStrokeRecordWithTheOwnersEpoch) {
  StartOwner(7);
  RawClient replica(server_.port());
  auto load = Subscribe(replica);
  ASSERT_TRUE(load.has_value());
  EXPECT_EQ(load->leaf_delta().epoch(), 7u) << "the region load does not carry the epoch";
  auto follower = Follow(7);
  ASSERT_TRUE(
      WaitFor([&] { return follower->ready() || follower->finished(); }, milliseconds(10000)));
  ASSERT_TRUE(follower->ready()) << follower->failure();
  uint64_t seq = 0;
  constexpr int kStrokes = 3, kPoses = 3;
  for (int i = 1; i <= kStrokes; ++i) seq = Sculpt(i, kPoses);
  ASSERT_GT(seq, 0u);
  auto broadcast = replica.ReadUntil(v1::ServerMessage::kEdit);
  ASSERT_TRUE(broadcast.has_value());
  EXPECT_EQ(broadcast->edit().epoch(), 7u) << "the broadcast does not carry the epoch";
  ASSERT_TRUE(WaitFor([&] { return follower->durable_seq() >= seq; }, milliseconds(10000)))
      << "the copy holds seq " << follower->durable_seq() << " of " << seq << "; "
      << follower->failure();
  EXPECT_EQ(follower->stale_epoch_refusals(), 0u);
  follower.reset();

  uint64_t copy_epoch = 0;
  ASSERT_TRUE(CurrentStandbyCopy(standby_data_.string(), "default", &copy_epoch).has_value());
  EXPECT_EQ(copy_epoch, 7u);
  const std::vector<Logged> copied = ReadLog(Copy());
  ASSERT_EQ(copied.size(), static_cast<size_t>(kStrokes * kPoses));
  for (const Logged& l : copied) {
    EXPECT_TRUE(l.stroke) << "seq " << l.seq;
    EXPECT_EQ(l.epoch, 7u) << "the copy logged seq " << l.seq << " without the owner's epoch";
  }
  EXPECT_EQ(copied.back().seq, seq);

  server_.Stop();
  const std::vector<Logged> owned = ReadLog(server_.config().data_dir);
  size_t strokes = 0;
  for (const Logged& l : owned) {
    if (!l.stroke) continue;
    ++strokes;
    EXPECT_EQ(l.epoch, 7u) << "the owner logged seq " << l.seq << " without its epoch";
  }
  EXPECT_EQ(strokes, static_cast<size_t>(kStrokes * kPoses));
}

TEST_F(EpochFenceTest, SingleProcessLogsAndSendsNoEpoch) {
  StartOwner(0);
  RawClient replica(server_.port());
  auto load = Subscribe(replica);
  ASSERT_TRUE(load.has_value());
  EXPECT_EQ(load->leaf_delta().epoch(), 0u);
  const uint64_t seq = Sculpt(1, 3);
  ASSERT_GT(seq, 0u);
  auto broadcast = replica.ReadUntil(v1::ServerMessage::kEdit);
  ASSERT_TRUE(broadcast.has_value());
  EXPECT_EQ(broadcast->edit().epoch(), 0u);
  ASSERT_TRUE(UndoStroke(1));  // a tagged record too
  server_.Stop();
  const std::vector<Logged> owned = ReadLog(server_.config().data_dir);
  ASSERT_EQ(owned.size(), 4u);
  for (const Logged& l : owned) {
    EXPECT_EQ(l.stroke, l.seq <= 3) << "seq " << l.seq;
    EXPECT_EQ(l.epoch, 0u);
    // Absent from the bytes, not written as 0: the record serializes back to the same bytes
    // (a present field 16, even 0, would not survive the round trip).
    if (l.stroke) {
      v1::EditRecord r;
      ASSERT_TRUE(r.ParseFromString(l.payload));
      EXPECT_EQ(r.SerializeAsString(), l.payload) << "seq " << l.seq;
    } else {
      ASSERT_EQ(l.payload[0], '\x04');
      v1::UndoRecord r;
      ASSERT_TRUE(r.ParseFromString(l.payload.substr(1)));
      EXPECT_EQ('\x04' + r.SerializeAsString(), l.payload) << "seq " << l.seq;
    }
    EXPECT_EQ(l.payload.find("\x80\x01"), std::string::npos) << "field 16's tag in seq " << l.seq;
  }
}

// Undo records (tagged, logged through the same commit pipeline as every kind but a stroke)
// carry the epoch too, and the history view shows it, live and after a restart.
TEST_F(EpochFenceTest, EveryRecordKindIsLoggedWithTheEpochAndTheHistoryShowsIt) {
  StartOwner(7);
  Sculpt(1);
  Sculpt(2);
  ASSERT_TRUE(UndoStroke(1));
  const auto history = [this] {
    RawClient c(server_.port());
    EXPECT_TRUE(c.Enter("sculpt-dev-viewer", v1::ROLE_VIEWER));
    v1::ClientMessage q;
    q.mutable_history()->set_request_id(1);
    q.mutable_history()->set_object("clay");
    EXPECT_TRUE(c.Send(q));
    auto a = c.ReadUntil(v1::ServerMessage::kHistory);
    EXPECT_TRUE(a.has_value());
    return a ? a->history() : v1::HistoryAnswer{};
  };
  const v1::HistoryAnswer live = history();
  ASSERT_EQ(live.entries_size(), 2) << live.DebugString();
  for (const v1::HistoryEntry& e : live.entries()) EXPECT_EQ(e.epoch(), 7u) << e.DebugString();

  server_.Stop();
  const std::vector<Logged> owned = ReadLog(server_.config().data_dir);
  size_t undos = 0;
  for (const Logged& l : owned) {
    EXPECT_EQ(l.epoch, 7u) << "seq " << l.seq << " logged without the owner's epoch";
    if (!l.stroke) {
      ++undos;
      EXPECT_EQ(l.payload[0], '\x04') << "seq " << l.seq << " is not an undo";
    }
  }
  EXPECT_EQ(undos, 1u);

  // Restarted under a newer ownership: the recovered entries keep the epoch they were logged
  // under, and a new stroke shows the new one.
  sculptor_.reset();
  ASSERT_TRUE(server_.Start());
  server_.server().set_router(&router_);
  fence_->Grant(8, OwnershipFence::Clock::now() + std::chrono::hours(1));
  server_.scene().set_ownership_fence(fence_);
  const v1::HistoryAnswer recovered = history();
  ASSERT_EQ(recovered.entries_size(), 2) << recovered.DebugString();
  for (const v1::HistoryEntry& e : recovered.entries()) EXPECT_EQ(e.epoch(), 7u);
  Sculpt(3);
  const v1::HistoryAnswer after = history();
  ASSERT_EQ(after.entries_size(), 3) << after.DebugString();
  EXPECT_EQ(after.entries(0).epoch(), 8u) << "newest first";
  EXPECT_EQ(after.entries(1).epoch(), 7u);

  // `sculpt history` prints it: a JSON key and the end of the state column.
  const std::string server = "--server 127.0.0.1:" + std::to_string(server_.port());
  const auto json = sculpt::testing::Sculpt("history " + server + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.output;
  const auto j = nlohmann::json::parse(json.output.substr(json.output.find('{')));
  ASSERT_EQ(j["entries"].size(), 3u) << json.output;
  EXPECT_EQ(j["entries"][0]["epoch"], 8) << json.output;
  EXPECT_EQ(j["entries"][2]["epoch"], 7) << json.output;
  const auto table = sculpt::testing::Sculpt("history " + server + " --limit 1");
  ASSERT_EQ(table.exit_code, 0) << table.output;
  EXPECT_NE(table.output.find("done, undoable, epoch 8\n"), std::string::npos) << table.output;
}

// Under sync the standby's copy holds every edit the owner acknowledges, whatever its kind:
// ball edits and undos (no voxels change, so no broadcast carries them) reach it as the owner
// logged them (LogRecords), and the skin as the owner held it when the copy was loaded comes
// with the region load (its book files). A server started on the copy, as a promotion starts
// one, has the owner's skin, the author's undo and redo depths and its resend table.
TEST_F(EpochFenceTest, StandbyCopyHoldsBallEditsAndUndosAndRecoversTheSkinAndItsHistory) {
  SkinConfig skin;
  skin.name = "profile";
  skin.chord_tolerance = 0.05;
  skin.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
  server_.config().scene.skins = {skin};
  server_.config().cluster.replication = "sync";
  // Before the copy exists the owner acknowledges alone after this; once the copy holds
  // everything, the scene is synchronous again.
  server_.config().cluster.sync_fallback_ms = 300;
  StartOwner(7);
  Sculpt(1);
  EditBall(1, v1::SKIN_BALL_OP_MOVE, 1, -6, 2);  // before the copy: in its region load
  auto follower = Follow(7);
  ASSERT_TRUE(
      WaitFor([&] { return follower->ready() || follower->finished(); }, milliseconds(10000)));
  ASSERT_TRUE(follower->ready()) << follower->failure();
  ASSERT_TRUE(WaitFor([&] { return !server_.scene().acks().fallen_back(); }, milliseconds(5000)))
      << "the scene did not become synchronous again once the copy held everything";

  EditBall(2, v1::SKIN_BALL_OP_MOVE, 3, 6, -2);
  const uint64_t moved = server_.scene().global_seq();
  EXPECT_FALSE(server_.scene().acks().fallen_back());
  EXPECT_GE(follower->durable_seq(), moved) << "a ball edit acknowledged before the copy held it";
  EditBall(3, v1::SKIN_BALL_OP_ADD, 5, 18, 0);
  const uint64_t undone = Undo(1, "profile").global_seq();  // takes back the add
  ASSERT_GT(undone, moved);
  EXPECT_GE(follower->durable_seq(), undone) << "an undo acknowledged before the copy held it";
  const uint64_t last = Sculpt(2);
  ASSERT_TRUE(WaitFor([&] { return follower->durable_seq() >= last; }, milliseconds(10000)));
  EXPECT_EQ(follower->stale_epoch_refusals(), 0u);
  auto owner_skin = server_.scene().SkinCopy("profile");
  ASSERT_TRUE(owner_skin.ok()) << owner_skin.status();
  const auto owner_depth = server_.scene().UndoDepth("profile", 77);
  EXPECT_EQ(owner_depth, std::make_pair(size_t{2}, size_t{1}));
  follower.reset();
  sculptor_.reset();
  server_.Stop();

  // The copy logged the ball edits and the undo after its load, as the owner did, with the
  // owner's epoch.
  size_t ball_edits = 0, undos = 0;
  for (const Logged& l : ReadLog(Copy())) {
    EXPECT_EQ(l.epoch, 7u) << "seq " << l.seq;
    ball_edits += !l.stroke && l.payload[0] == '\x03' ? 1 : 0;
    undos += !l.stroke && l.payload[0] == '\x04' ? 1 : 0;
  }
  EXPECT_EQ(ball_edits, 2u);
  EXPECT_EQ(undos, 1u);

  sculpt::testing_support::InProcessServer promoted{"epoch_fence_promoted"};
  promoted.config().data_dir = Copy().string();
  promoted.config().scene.skins = {skin};
  ASSERT_TRUE(promoted.Start());
  auto copy_skin = promoted.scene().SkinCopy("profile");
  ASSERT_TRUE(copy_skin.ok()) << copy_skin.status();
  ASSERT_EQ(copy_skin->balls().size(), owner_skin->balls().size());
  ASSERT_EQ(copy_skin->balls().size(), 5u);
  for (size_t i = 0; i < copy_skin->balls().size(); ++i) {
    const skin::OrientedBall& a = owner_skin->balls()[i];
    const skin::OrientedBall& b = copy_skin->balls()[i];
    EXPECT_EQ(a.c.x, b.c.x) << "ball " << i;
    EXPECT_EQ(a.c.y, b.c.y) << "ball " << i;
    EXPECT_EQ(a.r, b.r) << "ball " << i;
    EXPECT_EQ(a.theta, b.theta) << "ball " << i;
  }
  EXPECT_EQ(copy_skin->balls()[1].c.y, 2.0) << "the edit from before the copy's load";
  EXPECT_EQ(copy_skin->balls()[3].c.y, -2.0) << "the edit shipped after it";
  EXPECT_EQ(promoted.scene().UndoDepth("profile", 77), owner_depth);
  // A resend of a ball edit the owner acknowledged is recognised by the copy.
  RawClient again(promoted.port());
  ASSERT_TRUE(again.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, 77));
  v1::ClientMessage resend;
  resend.mutable_skin_ball_edit()->set_client_seq(3);
  resend.mutable_skin_ball_edit()->set_skin("profile");
  resend.mutable_skin_ball_edit()->set_op(v1::SKIN_BALL_OP_ADD);
  resend.mutable_skin_ball_edit()->set_index(5);
  resend.mutable_skin_ball_edit()->mutable_ball()->set_x(18);
  resend.mutable_skin_ball_edit()->mutable_ball()->set_r(2.5);
  ASSERT_TRUE(again.Send(resend));
  auto dup = again.ReadUntil(v1::ServerMessage::kSkinAck);
  ASSERT_TRUE(dup.has_value());
  EXPECT_TRUE(dup->skin_ack().duplicate()) << dup->DebugString();
  EXPECT_EQ(promoted.scene().SkinCopy("profile")->balls().size(), 5u);
}

// The copy's snapshots carry the stroke undo history the owner's would at their sequence: the
// owner's history as of the region load (LeafDelta.object_history), then every stroke the copy
// replays and every undo the owner ships it recorded as the owner's Apply records them. A
// server started on the copy after it snapshotted past every stroke (as a promotion starts
// one) gives the author the owner's undo depth, and each undo the state the owner's gives.
TEST_F(EpochFenceTest, StandbyCopySnapshotsCarryTheStrokeUndoHistory) {
  server_.config().cluster.replication = "sync";
  server_.config().cluster.sync_fallback_ms = 300;
  StartOwner(7);
  Sculpt(1);  // before the copy: in its region load and the history sent with it
  auto follower = Follow(7, /*snapshot_every_records=*/3);  // a snapshot after every stroke
  ASSERT_TRUE(
      WaitFor([&] { return follower->ready() || follower->finished(); }, milliseconds(10000)));
  ASSERT_TRUE(follower->ready()) << follower->failure();
  ASSERT_TRUE(WaitFor([&] { return !server_.scene().acks().fallen_back(); }, milliseconds(5000)));
  Sculpt(2);
  Sculpt(3);
  ASSERT_TRUE(UndoStroke(4));  // takes back stroke 3: shipped to the copy as the owner logged it
  Sculpt(5);
  const uint64_t last = Sculpt(6);
  ASSERT_TRUE(WaitFor([&] { return follower->durable_seq() >= last; }, milliseconds(10000)));
  EXPECT_FALSE(server_.scene().acks().fallen_back());
  follower.reset();
  const std::vector<uint64_t> snaps = SnapshotSeqs(Copy());
  ASSERT_FALSE(snaps.empty());
  ASSERT_EQ(*std::max_element(snaps.begin(), snaps.end()), last)
      << "the copy did not snapshot after the last stroke: the test would replay its log";

  // What the owner gives: the author's depths, then the state after each of its undos (the
  // strokes 6, 5, 2 and 1, the oldest from before the copy's load), then nothing to undo.
  const auto owner_depth = server_.scene().UndoDepth("clay", 77);
  ASSERT_EQ(owner_depth, std::make_pair(size_t{4}, size_t{0}));
  // Compared voxel by voxel over the whole sphere (radius 24) and its halo: the copy is built
  // from leaf records, so its tree's shape (Sculpture::StateHash) may differ with equal values.
  const double dx = server_.config().scene.voxel_size;
  const int reach = static_cast<int>(std::ceil(32 / dx));
  const levelset::VoxelBox clay{{-reach, -reach, -reach}, {reach, reach, reach}};
  const uint64_t owner_before = server_.scene().RegionHash("clay", clay);
  std::vector<uint64_t> owner_undone;
  for (uint64_t client_seq = 7; client_seq <= 10; ++client_seq) {
    ASSERT_TRUE(UndoStroke(client_seq));
    owner_undone.push_back(server_.scene().RegionHash("clay", clay));
  }
  EXPECT_EQ(std::set<uint64_t>(owner_undone.begin(), owner_undone.end()).size(), 4u)
      << "each undo changes the object";
  sculptor_.reset();
  server_.Stop();

  sculpt::testing_support::InProcessServer promoted{"epoch_fence_promoted_undo"};
  promoted.config().data_dir = Copy().string();
  ASSERT_TRUE(promoted.Start());
  EXPECT_EQ(promoted.scene().RegionHash("clay", clay), owner_before);
  EXPECT_EQ(promoted.scene().UndoDepth("clay", 77), owner_depth)
      << "the copy's snapshot holds another stroke undo history than the owner's";
  RawClient author(promoted.port());
  ASSERT_TRUE(author.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, 77));
  for (uint64_t i = 0; i < owner_undone.size(); ++i) {
    v1::ClientMessage m;
    m.mutable_undo()->set_client_seq(7 + i);
    m.mutable_undo()->set_object("clay");
    ASSERT_TRUE(author.Send(m));
    auto a = author.ReadUntil(v1::ServerMessage::kUndoAck);
    ASSERT_TRUE(a.has_value());
    ASSERT_TRUE(a->undo_ack().accepted()) << "undo " << i + 1 << ": " << a->DebugString();
    EXPECT_EQ(promoted.scene().RegionHash("clay", clay), owner_undone[i]) << "after undo " << i + 1;
  }
  v1::ClientMessage more;
  more.mutable_undo()->set_client_seq(11);
  more.mutable_undo()->set_object("clay");
  ASSERT_TRUE(author.Send(more));
  auto none = author.ReadUntil(v1::ServerMessage::kUndoAck);
  ASSERT_TRUE(none.has_value());
  EXPECT_FALSE(none->undo_ack().accepted()) << "an undo beyond the owner's history";
}

// A member whose fence holds a lower epoch than one its log already holds (a stale owner: the
// agent never grants one, the test does) logs nothing and acknowledges nothing; the log stays
// one that starts, and a later, higher epoch is served again.
TEST_F(EpochFenceTest, RefusesToLogUnderAnEpochLowerThanTheLogs) {
  StartOwner(7);
  const uint64_t before = Sculpt(1);
  ASSERT_GT(before, 0u);
  fence_->Grant(6, OwnershipFence::Clock::now() + std::chrono::hours(1));
  ASSERT_TRUE(sculptor_->Send(RawClient::PressStroke(2, {-1.0, 0, 22.5}, 3)));
  auto refused = sculptor_->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(refused.has_value()) << "a stroke under epoch 6 after epoch 7 was not refused";
  const std::string why = refused->error().message();
  EXPECT_NE(why.find("epoch 6, lower than epoch 7"), std::string::npos) << why;
  EXPECT_EQ(server_.scene().global_seq(), before) << "the stale stroke was sequenced";
  fence_->Grant(8, OwnershipFence::Clock::now() + std::chrono::hours(1));
  const uint64_t after = Sculpt(3);
  EXPECT_EQ(after, before + 3) << "epoch 8 is not served after the refusal";
  sculptor_.reset();
  server_.Stop();
  const std::vector<Logged> logged = ReadLog(server_.config().data_dir);
  ASSERT_EQ(logged.size(), 6u);
  for (const Logged& l : logged) {
    EXPECT_EQ(l.epoch, l.seq <= before ? 7u : 8u) << "seq " << l.seq;
  }
  EXPECT_TRUE(server_.Start()) << "the log no longer starts";
}

// A log in which a stale owner wrote after a newer ownership (here appended by hand, since the
// live path refuses to: a record of epoch 6 after epoch 7) is refused at start-up, naming the
// record; nothing is cut off it.
TEST_F(EpochFenceTest, RefusesToStartOnALogWhoseEpochsGoBackwards) {
  StartOwner(7);
  const uint64_t before = Sculpt(1);
  ASSERT_GT(before, 0u);
  sculptor_.reset();
  server_.Stop();
  std::vector<Logged> logged = ReadLog(server_.config().data_dir);
  ASSERT_FALSE(logged.empty());
  ASSERT_TRUE(logged.back().stroke);
  v1::EditRecord stale;
  ASSERT_TRUE(stale.ParseFromString(logged.back().payload));
  stale.set_epoch(6);
  {
    store::RecoveryReport report;
    auto log = store::EditLog::Open((fs::path(server_.config().data_dir) / store::kLogSubdir).string(),
                                    store::FsyncPolicy{}, &report);
    ASSERT_TRUE(log.ok()) << log.status();
    ASSERT_TRUE((*log)->Append(before + 1, stale.SerializeAsString()).ok());
    ASSERT_TRUE((*log)->Sync().ok());
  }
  logged = ReadLog(server_.config().data_dir);
  ASSERT_EQ(logged.back().epoch, 6u);
  const ::testing::AssertionResult restarted = server_.Start();
  ASSERT_FALSE(restarted) << "started on a log whose epochs go backwards";
  const std::string why = restarted.message();
  EXPECT_NE(why.find("record seq " + std::to_string(before + 1) + " has epoch 6, lower than " +
                     "epoch 7 of seq 1 before it"),
            std::string::npos)
      << why;
  EXPECT_NE(why.find("stale owner"), std::string::npos) << why;
  EXPECT_EQ(ReadLog(server_.config().data_dir).size(), logged.size()) << "the refusal cut the log";
}

TEST_F(EpochFenceTest, RejectsARegionLoadOfAnotherEpochThanEtcdNames) {
  StartOwner(7);
  Sculpt(1);
  auto follower = Follow(6);  // etcd names epoch 6; the owner at the address sends epoch 7
  ASSERT_TRUE(WaitFor([&] { return follower->finished(); }, milliseconds(10000)));
  EXPECT_FALSE(follower->ready());
  const std::string why = follower->failure();
  EXPECT_NE(why.find("LeafDelta"), std::string::npos) << why;
  EXPECT_NE(why.find("of epoch 7"), std::string::npos) << why;
  EXPECT_NE(why.find("holds epoch 6"), std::string::npos) << why;
  EXPECT_NE(why.find("scene default"), std::string::npos) << why;
  EXPECT_EQ(follower->stale_epoch_refusals(), 1u);
  EXPECT_EQ(refusals_->load(), 1u);
  EXPECT_EQ(follower->durable_seq(), 0u);
  follower.reset();
  EXPECT_FALSE(CurrentStandbyCopy(standby_data_.string(), "default").has_value())
      << "the refused load made a copy";
}

TEST_F(EpochFenceTest, RejectsABroadcastOfAnEpochEtcdDoesNotNameAndKeepsNothingOfIt) {
  StartOwner(7);
  auto follower = Follow(7);
  ASSERT_TRUE(
      WaitFor([&] { return follower->ready() || follower->finished(); }, milliseconds(10000)));
  ASSERT_TRUE(follower->ready()) << follower->failure();
  const uint64_t before = Sculpt(1);
  ASSERT_TRUE(WaitFor([&] { return follower->durable_seq() >= before; }, milliseconds(10000)));
  // The member at the address now sends under epoch 8, which etcd does not name for the owner the
  // standby follows (7). (A lower epoch cannot be sent: the owner refuses to log under an epoch
  // below its log's, RefusesToLogUnderAnEpochLowerThanTheLogs.)
  fence_->Grant(8, OwnershipFence::Clock::now() + std::chrono::hours(1));
  const uint64_t stale = Sculpt(2);
  ASSERT_GT(stale, before);
  ASSERT_TRUE(WaitFor([&] { return follower->finished(); }, milliseconds(10000)))
      << "the standby kept following a stream of another epoch";
  const std::string why = follower->failure();
  EXPECT_NE(why.find("EditBroadcast at seq " + std::to_string(before + 1)), std::string::npos)
      << why;
  EXPECT_NE(why.find("of epoch 8"), std::string::npos) << why;
  EXPECT_NE(why.find("holds epoch 7"), std::string::npos) << why;
  EXPECT_EQ(follower->stale_epoch_refusals(), 1u);
  EXPECT_EQ(refusals_->load(), 1u);
  EXPECT_EQ(follower->durable_seq(), before);
  follower.reset();

  // Nothing of the refused stroke in the copy: its log ends before it, every record of epoch 7,
  // and no snapshot (the copy's state on disk) past it.
  const std::vector<Logged> copied = ReadLog(Copy());
  ASSERT_FALSE(copied.empty());
  EXPECT_EQ(copied.back().seq, before);
  for (const Logged& l : copied) EXPECT_EQ(l.epoch, 7u) << "seq " << l.seq;
  for (uint64_t s : SnapshotSeqs(Copy())) EXPECT_LE(s, before);
  // The owner logged it, under the epoch it held then.
  server_.Stop();
  size_t at8 = 0;
  for (const Logged& l : ReadLog(server_.config().data_dir)) {
    EXPECT_EQ(l.epoch, l.seq > before ? 8u : 7u) << "seq " << l.seq;
    at8 += l.seq > before ? 1 : 0;
  }
  EXPECT_EQ(at8, static_cast<size_t>(stale - before));
}

TEST_F(EpochFenceTest, StopsTakingTheOwnersStreamOnceEtcdNamesAnotherEpoch) {
  StartOwner(7);
  auto follower = Follow(7);
  ASSERT_TRUE(
      WaitFor([&] { return follower->ready() || follower->finished(); }, milliseconds(10000)));
  ASSERT_TRUE(follower->ready()) << follower->failure();
  const uint64_t before = Sculpt(1);
  ASSERT_TRUE(WaitFor([&] { return follower->durable_seq() >= before; }, milliseconds(10000)));
  follower->Supersede(8);  // what the member's agent does when etcd's epoch moves on
  EXPECT_EQ(follower->expected_epoch(), 8u);
  ASSERT_TRUE(WaitFor([&] { return follower->finished(); }, milliseconds(5000)));
  EXPECT_NE(follower->failure().find("etcd names epoch 8"), std::string::npos)
      << follower->failure();
  Sculpt(2);  // the old owner goes on: nothing of it reaches the copy
  EXPECT_EQ(follower->durable_seq(), before);
  follower.reset();
  const std::vector<Logged> copied = ReadLog(Copy());
  ASSERT_FALSE(copied.empty());
  EXPECT_EQ(copied.back().seq, before);
}

// Two members and etcd: a owns at epoch 1, b follows; a is paused past its TTL, b takes the
// scene over at epoch 2 and a, resumed, refuses the strokes that waited for it. Every stroke
// record a logged carries epoch 1 and a logged none of the waiting strokes; b's log (its copy,
// promoted) holds a's strokes under epoch 1 and the resent ones once, under epoch 2.
class EpochFenceClusterTest : public sculpt::testing::EtcdTest {
 protected:
  void TearDown() override {
    members_.clear();
    EtcdTest::TearDown();
  }
  sculpt::testing::Member& Start(const std::string& name, const std::string& extra = "") {
    members_.push_back(
        std::make_unique<sculpt::testing::Member>(name, etcd_->endpoint(), dir_.path(), extra));
    return *members_.back();
  }
  sculpt::testing::TempDir dir_{"sculpt-epoch-fence"};
  std::vector<std::unique_ptr<sculpt::testing::Member>> members_;
};

TEST_F(EpochFenceClusterTest, PausedOwnersStaleStrokesAreLoggedNowhereAndEpochsAreInTheLogs) {
  // The logs are read at the end: no snapshot may let a stop drop a segment. Under ASan b's
  // recovery replayed a's 8 records in more than a second (kMaxTailApplySeconds), so b
  // snapshotted at seq 8 by cost, and its stop's snapshot then dropped the segment holding them.
  const std::string no_snapshots =
      "[server]\nsnapshot_every_edits = 0\nsnapshot_every_seconds = 0\n";
  auto& a = Start("a", no_snapshots);
  ASSERT_NE(a.WaitPort(), 0) << "see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return OwnerOf("default").has_value(); }, milliseconds(5000)));
  auto& b = Start("b", no_snapshots);
  ASSERT_NE(b.WaitPort(), 0) << "see " << dir_.path() / "b.log";
  ASSERT_TRUE(WaitFor(
      [&] {
        auto s = StandbyOf("default");
        auto m = MemberOf("b");
        return s && s->member == "b" && m && m->follows == "default";
      },
      milliseconds(15000)))
      << "b did not follow a; see " << dir_.path() / "b.log";

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(5000);
  sculpt::client::Client client(options);
  ASSERT_TRUE(client.Connect("127.0.0.1", a.port()).ok());
  ASSERT_TRUE(client.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "epoch-test", 0).ok());
  auto joined = client.Join("");
  ASSERT_TRUE(joined.ok()) << joined.status();
  auto stroke_at = [](int i) {
    sculpt::client::StrokeRequest stroke;
    const double x = -4.0 + i;
    stroke.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}};
    return stroke;
  };
  constexpr int kBefore = 4, kDuring = 3;
  for (int i = 0; i < kBefore; ++i) ASSERT_TRUE(client.SendStroke(stroke_at(i)).ok());
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(10000)));
  const uint64_t acked_seq = client.stats().last_global_seq;
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("b");
        return m && m->follow_seq >= acked_seq;
      },
      milliseconds(10000)))
      << "b's copy did not catch up; see " << dir_.path() / "b.log";
  (void)client.DrainEvents();

  ASSERT_TRUE(a.process().Pause()) << "not stopped within 5 s";
  for (int i = kBefore; i < kBefore + kDuring; ++i) {
    ASSERT_TRUE(client.SendStroke(stroke_at(i)).ok());
  }
  const auto owner = AwaitOwner("default", "b", milliseconds(15000));
  ASSERT_TRUE(owner.has_value()) << "b did not take the scene over; see " << dir_.path() / "b.log";
  EXPECT_EQ(owner->epoch, 2u);
  ASSERT_EQ(kill(a.process().pid(), SIGCONT), 0);
  // a refuses the waiting strokes and closes; the client rejoins (redirected to b) and resends.
  int acks_from_a = 0;
  bool disconnected = false;
  const auto until = std::chrono::steady_clock::now() + milliseconds(5000);
  while (!disconnected && std::chrono::steady_clock::now() < until) {
    auto e = client.NextEvent(milliseconds(100));
    if (!e) continue;
    acks_from_a += e->type == sculpt::client::Event::Type::kAck ? 1 : 0;
    disconnected = e->type == sculpt::client::Event::Type::kDisconnected;
  }
  EXPECT_EQ(acks_from_a, 0) << "the paused owner acknowledged after its lease was gone";
  ASSERT_TRUE(disconnected) << "the refusal did not close the connection";
  Status again;
  ASSERT_TRUE(WaitFor(
      [&] {
        again = client.Reconnect();
        return again.ok();
      },
      milliseconds(10000)))
      << again;
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(10000)));
  EXPECT_EQ(client.stats().acks, static_cast<uint64_t>(kBefore + kDuring));
  const uint64_t final_seq = client.stats().last_global_seq;
  EXPECT_EQ(final_seq, acked_seq + 2 * kDuring);

  a.process().Kill(SIGTERM);
  b.process().Kill(SIGTERM);
  size_t a_strokes = 0;
  for (const Logged& l : ReadLog(dir_.path() / "a-data")) {
    if (!l.stroke) continue;
    ++a_strokes;
    EXPECT_EQ(l.epoch, 1u) << "a logged seq " << l.seq;
    EXPECT_LE(l.seq, acked_seq) << "a logged a stroke after its lease was gone";
  }
  EXPECT_EQ(a_strokes, static_cast<size_t>(2 * kBefore));
  size_t b_at1 = 0, b_at2 = 0;
  for (const Logged& l : ReadLog(dir_.path() / "b-data")) {
    if (!l.stroke) continue;
    EXPECT_EQ(l.epoch, l.seq > acked_seq ? 2u : 1u) << "b logged seq " << l.seq;
    (l.seq > acked_seq ? b_at2 : b_at1)++;
  }
  EXPECT_EQ(b_at1, static_cast<size_t>(2 * kBefore)) << "a's strokes, as b's copy logged them";
  EXPECT_EQ(b_at2, static_cast<size_t>(2 * kDuring)) << "the resent strokes, once, at epoch 2";
}

// The member's agent: once etcd's epoch for the scene moves past the one its standby follows,
// the follow ends at its next tick (here the epoch record is rewritten behind the owner's back,
// so no new owner is honoured and the standby waits instead of following anyone).
TEST_F(EpochFenceClusterTest, StandbyStopsFollowingWhenEtcdsEpochMovesOn) {
  auto& a = Start("a");
  ASSERT_NE(a.WaitPort(), 0) << "see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return OwnerOf("default").has_value(); }, milliseconds(5000)));
  auto& b = Start("b");
  ASSERT_NE(b.WaitPort(), 0) << "see " << dir_.path() / "b.log";
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("b");
        return m && m->follows == "default";
      },
      milliseconds(15000)))
      << "b did not follow a; see " << dir_.path() / "b.log";
  const std::string b_log = (dir_.path() / "b.log").string();
  auto logged = [&](const std::string& text) {
    std::ifstream in(b_log);
    const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return all.find(text) != std::string::npos;
  };
  EXPECT_FALSE(logged("etcd names epoch 2"));
  const Keys keys{"t/"};
  auto put =
      etcd_client_->Sync(etcd_client_->Put({keys.Epoch("default"), EncodeEpoch({2, "x"}), 0}));
  ASSERT_TRUE(put.ok()) << put.status();
  EXPECT_TRUE(WaitFor([&] { return logged("etcd names epoch 2 for its owner now, not epoch 1"); },
                      milliseconds(5000)))
      << "b went on following the owner of epoch 1; see " << b_log;
}

}  // namespace
}  // namespace sculpt::server::cluster
