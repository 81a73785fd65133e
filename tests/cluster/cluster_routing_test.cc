// sculptd members and an etcd, all started by the test on loopback (issue 17): the first member
// takes the scene, a client joining through another is redirected to it and its stroke is
// acknowledged there; the owner killed with SIGKILL loses its owner key after the lease TTL; a
// member that may not be a standby does not take the scene but says why; the standby that
// followed the owner's edit stream takes it over with the next epoch and every stroke it held.
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <mutex>
#include <thread>

#include "cluster/etcd_client.h"
#include "cluster/processes.h"
#include "cluster/records.h"
#include "integration/raw_client.h"
#include "sculpt/client/client.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::server::cluster {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::ChildProcess;
using sculpt::testing::EtcdProcess;
using sculpt::testing::Member;
using sculpt::testing::TempDir;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

constexpr int kLeaseTtlMs = 2000;
const Keys kKeys{"t/"};

class ClusterRoutingTest : public sculpt::testing::EtcdTest {
 protected:
  void TearDown() override {
    members_.clear();  // SIGKILL and reap each sculptd before etcd goes
    EtcdTest::TearDown();
  }

  Member& Start(const std::string& name, const std::string& extra = "",
                const std::vector<std::string>& args = {}) {
    members_.push_back(
        std::make_unique<Member>(name, etcd_->endpoint(), dir_.path(), extra, args));
    return *members_.back();
  }
  std::optional<OwnerRecord> Owner() {
    auto kv = etcd_client_->Sync(etcd_client_->Get(kKeys.Owner("default")));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto o = DecodeOwner((*kv)->value);
    return o.ok() ? std::optional<OwnerRecord>(*o) : std::nullopt;
  }
  std::optional<StandbyRecord> Standby() {
    auto kv = etcd_client_->Sync(etcd_client_->Get(kKeys.Standby("default")));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto s = DecodeStandby((*kv)->value);
    return s.ok() ? std::optional<StandbyRecord>(*s) : std::nullopt;
  }
  std::optional<MemberRecord> MemberOf(const std::string& name) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(kKeys.Member(name)));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto m = DecodeMember((*kv)->value);
    return m.ok() ? std::optional<MemberRecord>(*m) : std::nullopt;
  }
  std::optional<EpochRecord> Epoch() {
    auto kv = etcd_client_->Sync(etcd_client_->Get(kKeys.Epoch("default")));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto e = DecodeEpoch((*kv)->value);
    return e.ok() ? std::optional<EpochRecord>(*e) : std::nullopt;
  }
  // Waits (15 s at most) until `member` is the named standby and its copy follows the scene.
  bool StandbyFollows(const std::string& member) {
    return WaitFor(
        [&] {
          auto m = MemberOf(member);
          return Standby() && Standby()->member == member && m && m->follows == "default";
        },
        milliseconds(15000));
  }
  bool HasKey(const std::string& key) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(key));
    return kv.ok() && kv->has_value();
  }
  // Connect and Hello as a sculptor on `port`, then Join the default scene.
  // Tests join as soon as etcd shows the owner key, which the member writes a moment before it
  // has taken the answer in and granted its fence: for that moment it refuses with "being
  // acquired by this member" (UNAVAILABLE, as a client retries), and the join is made again.
  StatusOr<sculpt::client::JoinedScene> Join(sculpt::client::Client& client, uint16_t port) {
    const auto deadline = std::chrono::steady_clock::now() + milliseconds(3000);
    while (true) {
      SCULPT_RETURN_IF_ERROR(client.Connect("127.0.0.1", port));
      auto welcome = client.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "cluster-test", 0);
      if (!welcome.ok()) return welcome.status();
      auto joined = client.Join("");
      if (joined.ok() ||
          joined.status().message().find("being acquired by this member") == std::string::npos ||
          std::chrono::steady_clock::now() > deadline) {
        return joined;
      }
      std::this_thread::sleep_for(milliseconds(20));
    }
  }

  TempDir dir_{"sculpt-cluster"};
  std::vector<std::unique_ptr<Member>> members_;
};

TEST_F(ClusterRoutingTest, RedirectsToTheOwnerAndTheOwnerKeyExpiresAfterTheTtl) {
  Member& a = Start("a");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  EXPECT_EQ(Owner()->member, "a");
  EXPECT_EQ(Owner()->epoch, 1u);
  EXPECT_EQ(Owner()->tcp, "127.0.0.1:" + std::to_string(a.port()));
  // b may not be a standby: it never follows a, so it cannot take the scene over.
  Member& b = Start("b", "standby = false\n");
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  EXPECT_TRUE(HasKey(kKeys.Member("b")));
  EXPECT_EQ(Owner()->member, "a") << "the scene changed hands when b arrived";

  // Joined through b (not the owner): redirected once to a, and a acknowledges the stroke.
  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(5000);
  sculpt::client::Client client(options);
  auto joined = Join(client, b.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_EQ(client.stats().redirects, 1u);
  bool told = false;
  for (const sculpt::client::Event& e : client.DrainEvents()) {
    if (e.type == sculpt::client::Event::Type::kDisconnected &&
        e.reason.find("member a at 127.0.0.1:" + std::to_string(a.port())) != std::string::npos) {
      told = true;
    }
  }
  EXPECT_TRUE(told) << "the redirect did not name member a's address";
  sculpt::client::StrokeRequest stroke;
  stroke.poses = {{{0, 0, 22.5}, 0}, {{0, 0.5, 22.5}, 10}};
  auto seq = client.SendStroke(stroke);
  ASSERT_TRUE(seq.ok()) << seq.status();
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(5000)));
  EXPECT_EQ(client.stats().acks, 1u);
  EXPECT_EQ(client.stats().refused, 0u);

  // kill -9 of the owner: its lease is no longer kept alive, and etcd drops the owner key when
  // the TTL runs out (not before: the last keep-alive was at most TTL/4 before the kill).
  const auto killed = std::chrono::steady_clock::now();
  a.process().Kill(SIGKILL);
  ASSERT_TRUE(WaitFor([&] { return !Owner().has_value(); }, milliseconds(kLeaseTtlMs + 3000)))
      << "the dead owner's key outlived its lease";
  const auto expired_ms =
      std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now() - killed).count();
  EXPECT_GE(expired_ms, kLeaseTtlMs / 2);
  EXPECT_LE(expired_ms, kLeaseTtlMs + 1500);
  EXPECT_FALSE(HasKey(kKeys.Member("a")));
  RecordProperty("owner_key_expired_ms", std::to_string(expired_ms));

  // b has not the scene's edits, so it does not take it over (it is nobody's standby): a join
  // through b is refused with the reason, and the epoch stays a's.
  Status refused;
  ASSERT_TRUE(WaitFor(
      [&] {
        sculpt::client::Client c(options);
        refused = Join(c, b.port()).status();
        return refused.message().find("is gone") != std::string::npos;
      },
      milliseconds(3000)))
      << refused;
  EXPECT_EQ(refused.code(), Status::Code::kUnavailable) << refused;
  EXPECT_FALSE(Owner().has_value());
  ASSERT_TRUE(Epoch().has_value());
  EXPECT_EQ(Epoch()->member, "a");
  EXPECT_EQ(Epoch()->epoch, 1u);

  // A graceful stop revokes the lease: b's key goes at once, not after the TTL.
  const auto stopped = std::chrono::steady_clock::now();
  b.process().Kill(SIGTERM);
  EXPECT_FALSE(HasKey(kKeys.Member("b")));
  EXPECT_LT(std::chrono::steady_clock::now() - stopped, milliseconds(kLeaseTtlMs));
}

TEST_F(ClusterRoutingTest, RestartedOwnerTakesItsSceneBackWithTheNextEpoch) {
  Member& a = Start("a");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  EXPECT_EQ(Owner()->epoch, 1u);
  a.process().Kill(SIGKILL);
  members_.clear();
  // The same member and data directory again: its old owner key blocks it until the old lease
  // expires, then it acquires with epoch 2.
  Member& again = Start("a");
  ASSERT_NE(again.WaitPort(), 0);
  ASSERT_TRUE(WaitFor(
      [&] {
        auto o = Owner();
        return o && o->epoch == 2;
      },
      milliseconds(kLeaseTtlMs + 3000)));
  EXPECT_EQ(Owner()->tcp, "127.0.0.1:" + std::to_string(again.port()));
  EXPECT_EQ(Epoch()->epoch, 2u);
  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(5000);
  sculpt::client::Client client(options);
  auto joined = Join(client, again.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_EQ(client.stats().redirects, 0u);
}

// Failover (issue 17): a owns the scene and names b its standby; b follows a's edit stream into a
// copy of its own; a client sculpts through c (redirected to a); once b's copy holds every acked
// stroke, a is killed with SIGKILL; b takes the scene over with epoch 2 from its copy, and the
// client, joining again through c, is redirected to b and finds every stroke (state hash and
// sequence equal to what a acknowledged), and new strokes are acknowledged there.
TEST_F(ClusterRoutingTest, StandbyTakesOverWithEveryReplicatedStrokeAfterTheOwnerIsKilled) {
  // Snapshots every 10 edits: the standby's copy snapshots and drops its log as it goes, so the
  // takeover recovers from one of its snapshots and a trimmed log.
  const std::vector<std::string> snap10{"--snapshot-every", "10"};
  Member& a = Start("a", "", snap10);
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  ASSERT_EQ(Owner()->member, "a");
  // Strokes acknowledged before b follows reach b in its region load, not in its log: the load
  // carries a's resend table, so after the takeover resends of these are duplicates too.
  const uint64_t early_id = 0xea1700000000u + static_cast<uint64_t>(::getpid());
  constexpr int kEarly = 3;
  auto send_early = [&](uint16_t port, bool resend) {
    sculpt::testing::RawClient early(port);
    early.SetTimeoutMs(5000);
    ASSERT_TRUE(early.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, early_id));
    for (int i = 1; i <= kEarly; ++i) {
      v1::ClientMessage m = sculpt::testing::RawClient::PressStroke(i, {0, 0, 22.5}, 3);
      m.mutable_stroke()->set_object(early.info().objects(0).name());
      ASSERT_TRUE(early.Send(m));
      auto ack = early.ReadUntil(v1::ServerMessage::kAck);
      ASSERT_TRUE(ack.has_value()) << "no ack for early stroke " << i;
      EXPECT_EQ(ack->ack().duplicate(), resend)
          << "early stroke " << i
          << (resend ? " (acknowledged before b followed) was applied again on the new owner"
                     : " was taken for a resend");
    }
  };
  send_early(a.port(), /*resend=*/false);
  Member& b = Start("b", "", snap10);
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(WaitFor([&] { return Standby().has_value() && Standby()->member == "b"; },
                      milliseconds(5000)))
      << "a named no standby; see " << dir_.path() / "a.log";
  EXPECT_EQ(Standby()->epoch, 1u);
  // b's copy complete before the client sculpts: its log then holds every stroke of the client
  // (the early strokes are in the copy's first snapshot and the resend table that came with it).
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("b");
        return m && m->follows == "default";
      },
      milliseconds(15000)))
      << "b's copy never completed; see " << dir_.path() / "b.log";
  // c comes after b was named: a keeps its standby while it lives.
  Member& c = Start("c", "", snap10);
  ASSERT_NE(c.WaitPort(), 0) << "member c did not start; see " << dir_.path() / "c.log";

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(10000);
  sculpt::client::Client client(options);
  auto joined = Join(client, c.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_EQ(client.stats().redirects, 1u);
  constexpr int kStrokes = 12;
  for (int i = 0; i < kStrokes; ++i) {
    sculpt::client::StrokeRequest stroke;
    const double x = -6.0 + i;
    stroke.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}, {{x, 1.0, 22.5}, 20}};
    ASSERT_TRUE(client.SendStroke(stroke).ok());
  }
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(15000)));
  ASSERT_EQ(client.stats().acks, static_cast<uint64_t>(kStrokes));
  const uint64_t acked_seq = client.stats().last_global_seq;
  ASSERT_GT(acked_seq, 0u);
  // The owner's state after the last ack, as a late joiner sees it.
  // Compared voxel by voxel (RegionHash): the standby's copy is built from leaf records, whose
  // interior tiles are leaf-sized, so the tree's shape (and Sculpture::StateHash, which hashes
  // it) may differ from the owner's while every value is equal.
  std::optional<levelset::Sculpture> owner_state;
  {
    sculpt::client::Client viewer(options);
    auto v = Join(viewer, a.port());
    ASSERT_TRUE(v.ok()) << v.status();
    ASSERT_EQ(v->info.global_seq(), acked_seq);
    ASSERT_EQ(v->info.objects_size(), 1);
    auto s = levelset::Sculpture::DeserializeVdb(v->state.at(v->info.objects(0).name()));
    ASSERT_TRUE(s.ok()) << s.status();
    owner_state.emplace(std::move(s).value());
  }
  const levelset::Aabb bounds = owner_state->WorldBounds();
  const levelset::VoxelBox box =
      levelset::WorldToVoxelBox(*owner_state, bounds.min, bounds.max).Dilated(16);
  const uint64_t owner_hash = levelset::RegionHash(*owner_state, box);
  // Asynchronous replication: wait until b says its copy holds everything acknowledged.
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("b");
        return m && m->follows == "default" && m->follow_seq >= acked_seq;
      },
      milliseconds(15000)))
      << "b's standby copy did not catch up; see " << dir_.path() / "b.log";

  const auto killed = std::chrono::steady_clock::now();
  a.process().Kill(SIGKILL);
  ASSERT_TRUE(WaitFor(
      [&] {
        auto o = Owner();
        return o && o->member == "b";
      },
      milliseconds(kLeaseTtlMs + 20000)))
      << "b did not take the scene over; see " << dir_.path() / "b.log";
  const auto took_ms =
      std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now() - killed).count();
  RecordProperty("failover_owner_ms", std::to_string(took_ms));
  std::cout << "failover: " << took_ms << " ms from kill -9 to the standby owning the scene\n";
  EXPECT_EQ(Owner()->epoch, 2u);
  EXPECT_EQ(Epoch()->member, "b");
  EXPECT_EQ(Epoch()->epoch, 2u);
  // b's data directory is now its copy: a snapshot past the start, the resend table beside it,
  // and what b held before moved aside.
  const fs::path b_data = dir_.path() / "b-data";
  uint64_t newest_snapshot = 0;
  for (const auto& e : fs::directory_iterator(b_data / "snapshots")) {
    const std::string name = e.path().filename().string();
    if (name.rfind("snap-", 0) == 0 && name.size() > 25) {
      newest_snapshot = std::max<uint64_t>(newest_snapshot, std::stoull(name.substr(5, 20)));
    }
  }
  EXPECT_GE(newest_snapshot, 10u) << "the copy took no snapshot of its own";
  EXPECT_TRUE(fs::exists(b_data / "resend_table.bin"));
  EXPECT_TRUE(fs::is_directory(b_data / "superseded"));

  // The same client (same client id) through c again: redirected to b, the new owner, which
  // holds every acknowledged stroke.
  sculpt::client::Client& again = client;
  StatusOr<sculpt::client::JoinedScene> rejoined = Status(Status::Code::kUnavailable, "not yet");
  ASSERT_TRUE(WaitFor(
      [&] {
        Status s = again.Connect("127.0.0.1", c.port());
        if (s.ok()) {
          s = again.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "cluster-test",
                          again.client_id())
                  .status();
        }
        rejoined = s.ok() ? again.Join("") : StatusOr<sculpt::client::JoinedScene>(s);
        return rejoined.ok();
      },
      milliseconds(10000)))
      << rejoined.status();
  // At least the second redirect (more if c still named a for a moment: a retried join).
  EXPECT_GE(again.stats().redirects, 2u);
  ASSERT_EQ(rejoined->info.objects_size(), 1);
  EXPECT_EQ(rejoined->info.global_seq(), acked_seq);
  {
    const std::string tcp = Owner()->tcp;
    send_early(static_cast<uint16_t>(std::stoi(tcp.substr(tcp.rfind(':') + 1))), /*resend=*/true);
  }
  {
    auto s = levelset::Sculpture::DeserializeVdb(rejoined->state.at(rejoined->info.objects(0).name()));
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(levelset::RegionHash(*s, box), owner_hash)
        << "the new owner's scene differs from what the old owner acknowledged";
  }
  for (int i = 0; i < 3; ++i) {
    sculpt::client::StrokeRequest stroke;
    stroke.poses = {{{0, -3.0 + i, 22.5}, 0}, {{0.5, -3.0 + i, 22.5}, 10}};
    ASSERT_TRUE(again.SendStroke(stroke).ok());
    if (i == 0) {
      // The failover figure: kill -9 to the first stroke acknowledged by the new owner
      // (here it includes the test's own polling for the rejoin, at most 20 ms).
      ASSERT_TRUE(again.WaitAllAcked(milliseconds(10000)));
      const auto first_ack_ms = std::chrono::duration_cast<milliseconds>(
                                    std::chrono::steady_clock::now() - killed)
                                    .count();
      RecordProperty("failover_first_ack_ms", std::to_string(first_ack_ms));
      std::cout << "failover: " << first_ack_ms
                << " ms from kill -9 to the first stroke acknowledged by the new owner\n";
    }
  }
  ASSERT_TRUE(again.WaitAllAcked(milliseconds(10000)));
  EXPECT_EQ(again.stats().acks, static_cast<uint64_t>(kStrokes) + 3);
  EXPECT_EQ(again.stats().refused, 0u);
  const uint64_t new_seq = again.stats().last_global_seq;
  EXPECT_GT(new_seq, acked_seq);
  EXPECT_EQ(Owner()->epoch, 2u) << "the new strokes were acknowledged under epoch 2";
  // The new owner names a new standby among the members left, and it catches up.
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("c");
        return Standby() && Standby()->member == "c" && m && m->follow_seq >= new_seq;
      },
      milliseconds(15000)))
      << "b named no new standby, or c did not catch up; see " << dir_.path() / "c.log";
}

// Synchronous replication (issue 17): a owns the scene with replication = "sync", b is its
// standby. A client sculpts continuously; a is killed with SIGKILL right after acks arrive,
// without waiting for b to catch up. Every stroke the client saw acknowledged is on b after the
// takeover: b's scene is at least at the highest acknowledged sequence, and each acknowledged
// stroke sent again with its client_seq is answered as a duplicate (b's log has it), never
// applied anew. (With async, the strokes acked in the last few ms before the kill may be lost.)
TEST_F(ClusterRoutingTest, SyncStandbyHasEveryAcknowledgedStrokeWhenTheOwnerIsKilled) {
  // A long fallback on a: the standby never gets excused, so every ack waited for it (checked
  // in a's log below). b, once owner, has no standby left: a short one, so the resends below are
  // answered after it.
  Member& a = Start("a", "replication = \"sync\"\nsync_fallback_ms = 60000\n");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  ASSERT_EQ(Owner()->member, "a");
  Member& b = Start("b", "replication = \"sync\"\nsync_fallback_ms = 300\n");
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(StandbyFollows("b"))
      << "b's copy never completed; see " << dir_.path() / "b.log";
  {
    // Only the named standby's session may say how far a copy is durable: a subscribed viewer
    // that is not b is refused (else it could release acks nobody holds).
    sculpt::testing::RawClient forger(a.port());
    ASSERT_TRUE(forger.Enter("sculpt-dev-viewer", v1::ROLE_VIEWER));
    v1::ClientMessage sub;
    sub.mutable_subscribe()->set_object(forger.info().objects(0).name());
    sub.mutable_subscribe()->set_mode(v1::REPLICA_MODE_REPLAY);
    ASSERT_TRUE(forger.Send(sub));
    v1::ClientMessage progress;
    progress.mutable_replica_progress()->set_object(forger.info().objects(0).name());
    progress.mutable_replica_progress()->set_durable_seq(1);
    ASSERT_TRUE(forger.Send(progress));
    auto err = forger.ReadUntil(v1::ServerMessage::kError);
    ASSERT_TRUE(err.has_value()) << "a forged ReplicaProgress was not refused";
    EXPECT_EQ(err->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
    EXPECT_EQ(err->error().field(), "Hello.client_name");
    EXPECT_EQ(err->error().allowed_range(), "standby-b");
  }

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(10000);
  options.max_unacked = 1000;
  sculpt::client::Client client(options);
  std::mutex mu;
  std::map<uint64_t, uint64_t> acked;  // client_seq -> last global seq of the stroke
  client.SetEventHandler([&](const sculpt::client::Event& e) {
    if (e.type != sculpt::client::Event::Type::kAck) return;
    std::lock_guard<std::mutex> lock(mu);
    acked[e.ack.client_seq()] = e.ack.global_seq_first() + e.ack.edits() - 1;
  });
  auto joined = Join(client, a.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  const uint64_t client_id = client.client_id();
  const auto t0 = std::chrono::steady_clock::now();
  auto since = [&] {
    return std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now() - t0).count();
  };
  std::atomic<bool> stop{false};
  std::thread sender([&] {
    for (int i = 0; !stop.load() && i < 2000; ++i) {
      sculpt::client::StrokeRequest stroke;
      const double x = -6.0 + (i % 24) * 0.5;
      stroke.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}, {{x, 1.0, 22.5}, 20}};
      if (!client.SendStroke(stroke).ok()) break;
      std::this_thread::sleep_for(milliseconds(8));  // about 120 strokes a second
    }
  });
  // Right after acks arrive: the moment the 40th is in, a dies (strokes still in flight).
  const bool enough = WaitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mu);
        return acked.size() >= 40;
      },
      milliseconds(20000));
  a.process().Kill(SIGKILL);
  stop = true;
  sender.join();
  ASSERT_TRUE(enough) << "a acknowledged too little; see " << dir_.path() / "a.log";
  // Acks already on the wire at the kill are acks too: read them before counting.
  std::this_thread::sleep_for(milliseconds(200));
  client.SetEventHandler(nullptr);
  std::map<uint64_t, uint64_t> seen;
  {
    std::lock_guard<std::mutex> lock(mu);
    seen = acked;
  }
  uint64_t highest_seq = 0;
  for (const auto& [cs, gs] : seen) highest_seq = std::max(highest_seq, gs);
  std::cout << "sync failover: " << seen.size() << " strokes acknowledged before the kill ("
            << since() << " ms after the first was sent), the last at seq " << highest_seq << ", "
            << client.unacked() << " unacknowledged\n";

  ASSERT_TRUE(WaitFor(
      [&] {
        auto o = Owner();
        return o && o->member == "b";
      },
      milliseconds(kLeaseTtlMs + 20000)))
      << "b did not take the scene over; see " << dir_.path() / "b.log";
  EXPECT_EQ(Owner()->epoch, 2u);
  // b's port after its restart (the same port file, rewritten).
  uint16_t b_port = 0;
  ASSERT_TRUE(WaitFor(
      [&] {
        std::ifstream in(dir_.path() / "b.ports");
        unsigned p = 0;
        if (!(in >> p) || p == 0) return false;
        b_port = static_cast<uint16_t>(p);
        try {
          sculpt::testing::RawClient probe(b_port);  // throws while nothing listens there
          probe.SetTimeoutMs(2000);
          return probe.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR);
        } catch (const std::exception&) {
          return false;
        }
      },
      milliseconds(15000)))
      << "b does not serve the scene; see " << dir_.path() / "b.log";
  std::cout << "sync failover: b serves the scene " << since() << " ms after the start\n";

  // The same client id on b: every acknowledged stroke, sent again, is a duplicate.
  sculpt::testing::RawClient raw(b_port);
  raw.SetTimeoutMs(5000);
  ASSERT_TRUE(raw.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, client_id));
  EXPECT_GE(raw.info().global_seq(), highest_seq)
      << "b's scene is behind what a acknowledged: acknowledged strokes were lost";
  ASSERT_EQ(raw.info().objects_size(), 1);
  const std::string object = raw.info().objects(0).name();
  int lost = 0;
  for (const auto& [cs, gs] : seen) {
    v1::ClientMessage m = sculpt::testing::RawClient::PressStroke(cs, {0, 0, 22.5}, 3);
    m.mutable_stroke()->set_object(object);
    ASSERT_TRUE(raw.Send(m));
    auto ack = raw.ReadUntil(v1::ServerMessage::kAck);
    ASSERT_TRUE(ack.has_value()) << "no ack for the resend of client_seq " << cs;
    EXPECT_EQ(ack->ack().client_seq(), cs);
    if (!ack->ack().duplicate()) {
      ++lost;
      ADD_FAILURE() << "stroke client_seq " << cs << " (acknowledged at seq " << gs
                    << ") is not on the new owner: it was applied anew";
    }
  }
  EXPECT_EQ(lost, 0);
  {
    std::ifstream in(dir_.path() / "a.log");
    const std::string log((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(log.find("acknowledging asynchronously"), std::string::npos)
        << "a fell back to async before the kill: the test proves nothing";
    EXPECT_NE(log.find("is the standby of scene default"), std::string::npos);
  }
  std::cout << "sync failover: " << seen.size() << " resends checked " << since()
            << " ms after the start\n";
}

// Synchronous replication with real processes: while the standby is stopped (SIGSTOP) the owner
// acknowledges nothing until cluster.sync_fallback_ms has passed, then falls back to async and
// says so; once the standby runs again and catches up, acks wait for it again.
TEST_F(ClusterRoutingTest, SyncOwnerHoldsAcksWhileItsStandbyIsStoppedThenFallsBack) {
  constexpr int kFallbackMs = 1500;
  Member& a = Start(
      "a", "replication = \"sync\"\nsync_fallback_ms = " + std::to_string(kFallbackMs) + "\n");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  Member& b = Start("b", "replication = \"sync\"\n");
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(StandbyFollows("b"))
      << "b's copy never completed; see " << dir_.path() / "b.log";
  auto a_log = [&] {
    std::ifstream in(dir_.path() / "a.log");
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(10000);
  sculpt::client::Client client(options);
  auto joined = Join(client, a.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  auto stroke_at = [](double x) {
    sculpt::client::StrokeRequest s;
    s.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}};
    return s;
  };
  auto timed_ack_ms = [&](double x) -> int64_t {
    const auto t = std::chrono::steady_clock::now();
    if (!client.SendStroke(stroke_at(x)).ok() || !client.WaitAllAcked(milliseconds(20000))) {
      return -1;
    }
    return std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now() - t).count();
  };
  const int64_t running = timed_ack_ms(-3);
  ASSERT_GE(running, 0);
  EXPECT_LT(running, kFallbackMs / 2)
      << "with its standby running, a stroke waited for the fallback";

  ASSERT_TRUE(b.process().Pause()) << "not stopped within 5 s";
  const int64_t stopped = timed_ack_ms(-2);
  ASSERT_GE(stopped, 0) << "no ack even after the fall-back; see " << dir_.path() / "a.log";
  EXPECT_GE(stopped, kFallbackMs - 100) << "acknowledged although the standby could not have it";
  EXPECT_NE(a_log().find("acknowledging asynchronously"), std::string::npos);
  // Fallen back: no waiting for the stopped standby.
  const int64_t fallen = timed_ack_ms(-1);
  ASSERT_GE(fallen, 0);
  EXPECT_LT(fallen, kFallbackMs / 2);
  std::cout << "sync: ack " << running << " ms with the standby running, " << stopped
            << " ms once it was stopped (fallback " << kFallbackMs << " ms), then " << fallen
            << " ms fallen back\n";

  ASSERT_EQ(::kill(b.process().pid(), SIGCONT), 0);
  EXPECT_TRUE(WaitFor(
      [&] { return a_log().find("acknowledgements wait for it (sync)") != std::string::npos; },
      milliseconds(15000)))
      << "a never returned to sync after b caught up; see " << dir_.path() / "a.log";
}

// replication = "none": the owner names no standby, so nobody follows its scene, and a standby
// key left from an earlier setting is removed.
TEST_F(ClusterRoutingTest, ReplicationNoneNamesNoStandby) {
  // A standby record from before (as an async owner would have left it).
  ASSERT_TRUE(etcd_client_
                  ->Sync(etcd_client_->Put(
                      {kKeys.Standby("default"), EncodeStandby(StandbyRecord{"b", 1}), 0}))
                  .ok());
  Member& a = Start("a", "replication = \"none\"\n");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  Member& b = Start("b", "replication = \"none\"\n");
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  EXPECT_EQ(Owner()->member, "a");
  EXPECT_TRUE(WaitFor([&] { return !Standby().has_value(); }, milliseconds(5000)))
      << "a kept the standby key under replication = none";
  // Several ticks later a still names nobody and b follows nothing.
  std::this_thread::sleep_for(milliseconds(2 * kLeaseTtlMs));
  EXPECT_FALSE(Standby().has_value());
  auto m = MemberOf("b");
  ASSERT_TRUE(m.has_value());
  EXPECT_TRUE(m->follows.empty()) << "b follows " << m->follows;
}

// The owner replaces a standby that leaves: a owns, b follows; b stops; a names c, which catches
// up with everything a acknowledged.
TEST_F(ClusterRoutingTest, OwnerNamesANewStandbyWhenItsStandbyLeaves) {
  Member& a = Start("a");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  Member& b = Start("b");
  ASSERT_NE(b.WaitPort(), 0);
  ASSERT_TRUE(WaitFor([&] { return Standby() && Standby()->member == "b"; }, milliseconds(5000)));
  Member& c = Start("c");
  ASSERT_NE(c.WaitPort(), 0);
  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(10000);
  sculpt::client::Client client(options);
  auto joined = Join(client, a.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  for (int i = 0; i < 4; ++i) {
    sculpt::client::StrokeRequest stroke;
    stroke.poses = {{{-2.0 + i, 0, 22.5}, 0}, {{-2.0 + i, 0.5, 22.5}, 10}};
    ASSERT_TRUE(client.SendStroke(stroke).ok());
  }
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(10000)));
  const uint64_t acked_seq = client.stats().last_global_seq;
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("b");
        return m && m->follow_seq >= acked_seq;
      },
      milliseconds(15000)))
      << "b did not catch up; see " << dir_.path() / "b.log";
  const auto c_record = MemberOf("c");
  ASSERT_TRUE(c_record.has_value());
  EXPECT_TRUE(c_record->follows.empty()) << "c follows while b is the standby";
  b.process().Kill(SIGTERM);
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf("c");
        return Standby() && Standby()->member == "c" && m && m->follows == "default" &&
               m->follow_seq >= acked_seq;
      },
      milliseconds(15000)))
      << "a did not name c, or c did not catch up; see " << dir_.path() / "c.log";
  EXPECT_EQ(Owner()->member, "a");
  EXPECT_EQ(Owner()->epoch, 1u);
}


// etcd unavailable (issue 17): the owner keeps acknowledging while its lease can still be alive,
// then refuses every stroke with an error that says why and where to go, and closes the
// connection; the client reconnects and resends, and once etcd answers again the owner serves
// again. Every stroke is applied exactly once (the scene's sequence grows by exactly the poses
// sent), and nothing acknowledged is lost (a kill -9 and restart still has all of it).
TEST_F(ClusterRoutingTest, EtcdOutageStopsAcksWithinTheTtlLosesNothingAndRecovers) {
  using Clock = std::chrono::steady_clock;
  auto ms_since = [](Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  };
  Member& a = Start("a");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(2000);
  sculpt::client::Client client(options);
  auto joined = Join(client, a.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  const uint64_t initial_seq = joined->info.global_seq();

  // One 2-pose stroke every 40 ms; every ack and refusal with the time it was seen. A closed
  // connection is reconnected (the client resends what is pending) as an application would.
  struct Seen {
    double ms;
    bool ack;
    std::string message;  // refusals
  };
  std::vector<Seen> seen;
  const Clock::time_point t0 = Clock::now();
  double paused_ms = -1, resumed_ms = -1, first_ack_after_resume_ms = -1;
  uint64_t max_acked_seq = 0;
  int sent = 0, disconnects = 0;
  bool reconnect = false;
  auto drain = [&] {
    for (const sculpt::client::Event& e : client.DrainEvents()) {
      const double ms = ms_since(t0);
      if (e.type == sculpt::client::Event::Type::kAck) {
        seen.push_back({ms, true, {}});
        if (e.ack.edits() > 0) {  // a duplicate's ack names no sequences
          max_acked_seq = std::max(max_acked_seq, e.ack.global_seq_first() + e.ack.edits() - 1);
        }
        if (resumed_ms >= 0 && first_ack_after_resume_ms < 0) first_ack_after_resume_ms = ms;
      } else if (e.type == sculpt::client::Event::Type::kError) {
        seen.push_back({ms, false, e.error.message()});
      } else if (e.type == sculpt::client::Event::Type::kDisconnected) {
        ++disconnects;
        reconnect = true;
      }
    }
  };
  auto step = [&] {
    sculpt::client::StrokeRequest stroke;
    const double y = (sent % 20) * 0.4;
    stroke.poses = {{{0, y, 22.5}, 0}, {{0, y + 0.3, 22.5}, 10}};
    ASSERT_TRUE(client.SendStroke(stroke).ok());
    ++sent;
    std::this_thread::sleep_for(milliseconds(40));
    drain();
    if (reconnect && client.Reconnect().ok()) reconnect = false;
  };
  while (ms_since(t0) < 1000) step();
  paused_ms = ms_since(t0);
  ASSERT_TRUE(etcd_->process().Pause()) << "not stopped within 5 s";
  while (ms_since(t0) < paused_ms + kLeaseTtlMs + 1500) step();
  resumed_ms = ms_since(t0);
  ASSERT_EQ(kill(etcd_->process().pid(), SIGCONT), 0);
  while (first_ack_after_resume_ms < 0 && ms_since(t0) < resumed_ms + 10000) step();
  for (int k = 0; k < 10; ++k) step();
  auto timeline = [&] {
    std::string t = "paused " + std::to_string(static_cast<int>(paused_ms)) + " ms, resumed " +
                    std::to_string(static_cast<int>(resumed_ms)) + " ms, sent " +
                    std::to_string(sent) + ", disconnects " + std::to_string(disconnects) + ":";
    for (const Seen& x : seen) {
      t += " " + std::to_string(static_cast<int>(x.ms)) + (x.ack ? "a" : "r");
    }
    return t;
  };
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(10000))) << timeline();
  drain();

  int acked_before = 0, acked_fenced = 0, refused = 0;
  std::string refusal;
  for (const Seen& x : seen) {
    if (x.ack && x.ms < paused_ms) ++acked_before;
    // The fence runs out no later than the lease could: TTL after the last answered keep-alive,
    // which was before the pause. 300 ms for an ack already on its way.
    if (x.ack && x.ms > paused_ms + kLeaseTtlMs + 300 && x.ms < resumed_ms) ++acked_fenced;
    if (!x.ack && refusal.empty()) refusal = x.message;
    refused += x.ack ? 0 : 1;
  }
  RecordProperty("first_ack_after_etcd_returned_ms",
                 std::to_string(static_cast<int>(first_ack_after_resume_ms - resumed_ms)));
  EXPECT_GT(acked_before, 10) << timeline();
  EXPECT_EQ(acked_fenced, 0) << "acknowledged after its lease could have expired: " << timeline();
  EXPECT_GT(refused, 0) << "no stroke was refused while etcd was gone: " << timeline();
  EXPECT_GT(disconnects, 0) << "a refusal for ownership did not close the connection";
  EXPECT_NE(refusal.find("not its owner now"), std::string::npos) << refusal;
  EXPECT_NE(refusal.find("reconnect through any member"), std::string::npos) << refusal;
  ASSERT_GE(first_ack_after_resume_ms, 0) << "no ack within 10 s after etcd returned; see "
                                          << dir_.path() / "a.log";

  // Exactly once, and durable: kill -9 and restart on the same data directory; once a owns the
  // scene again it holds every pose of every stroke sent, each once.
  a.process().Kill(SIGKILL);
  Member& again = Start("a");
  ASSERT_NE(again.WaitPort(), 0) << "a did not restart; see " << dir_.path() / "a.log";
  uint64_t recovered = 0;
  ASSERT_TRUE(WaitFor(
      [&] {
        sculpt::client::Client viewer(options);
        auto j = Join(viewer, again.port());
        if (!j.ok()) return false;
        recovered = j->info.global_seq();
        return true;
      },
      milliseconds(15000)))
      << "a did not take its scene back; see " << dir_.path() / "a.log";
  EXPECT_GE(recovered, max_acked_seq);
  EXPECT_EQ(recovered, initial_seq + 2 * static_cast<uint64_t>(sent)) << timeline();
}

// Fencing (issue 17): an owner paused past its lease (SIGSTOP) while a client's strokes wait in
// its socket loses the scene to its standby; resumed (SIGCONT), it acknowledges none of them,
// sequences none of them, and the client, reconnecting through it, is sent to the new owner,
// which applies each exactly once.
TEST_F(ClusterRoutingTest, PausedOwnerAcknowledgesNothingAfterItsLeaseIsGone) {
  Member& a = Start("a");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Owner().has_value(); }, milliseconds(5000)));
  Member& b = Start("b");
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(StandbyFollows("b"))
      << "b did not become a's standby; see " << dir_.path() / "b.log";

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(5000);
  sculpt::client::Client client(options);
  auto joined = Join(client, a.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  const uint64_t initial_seq = joined->info.global_seq();
  auto stroke_at = [](int i) {
    sculpt::client::StrokeRequest stroke;
    const double x = -4.0 + i;
    stroke.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}};
    return stroke;
  };
  constexpr int kBefore = 5, kDuring = 3;
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
    ASSERT_TRUE(client.SendStroke(stroke_at(i)).ok());  // they wait in the paused owner's socket
  }
  ASSERT_TRUE(WaitFor(
      [&] {
        auto o = Owner();
        return o && o->member == "b";
      },
      milliseconds(15000)))
      << "b did not take the scene over; see " << dir_.path() / "b.log";
  EXPECT_EQ(Owner()->epoch, 2u);
  ASSERT_EQ(kill(a.process().pid(), SIGCONT), 0);

  // a reads the waiting strokes at once and refuses each: its lease ran out while it was paused.
  int acks_from_a = 0, refusals = 0;
  bool disconnected = false;
  const auto until = std::chrono::steady_clock::now() + milliseconds(5000);
  while (!disconnected && std::chrono::steady_clock::now() < until) {
    auto e = client.NextEvent(milliseconds(100));
    if (!e) continue;
    acks_from_a += e->type == sculpt::client::Event::Type::kAck ? 1 : 0;
    refusals += e->type == sculpt::client::Event::Type::kError ? 1 : 0;
    disconnected = e->type == sculpt::client::Event::Type::kDisconnected;
  }
  EXPECT_EQ(acks_from_a, 0) << "the paused owner acknowledged after its lease was gone";
  EXPECT_GT(refusals, 0);
  ASSERT_TRUE(disconnected) << "the refusal did not close the connection";
  EXPECT_EQ(client.unacked(), static_cast<size_t>(kDuring));

  // Reconnecting through a (the member it knew) is redirected to b, which applies them.
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
  sculpt::client::Client viewer(options);
  auto v = Join(viewer, a.port());  // redirected to b
  ASSERT_TRUE(v.ok()) << v.status();
  EXPECT_EQ(v->info.global_seq(), initial_seq + 2 * (kBefore + kDuring))
      << "a stroke the paused owner held was applied twice or not at all";
}

}  // namespace
}  // namespace sculpt::server::cluster
