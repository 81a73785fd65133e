// `sculpt cluster move SCENE MEMBER` (issue 17, docs/cluster.md "Moving a scene"): three members,
// sculptors at 60 Hz; the real `sculpt` binary asks to move the scene to the member that is
// neither its owner nor its standby. The owner names that member standby, fences once its copy
// caught up, releases the scene, and the member takes it over as in a failover (epoch + 1). The
// sculptors reconnect through the members they know and every stroke is acknowledged exactly
// once. Then the refusals: an unknown member, and the member that owns the scene already.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <iterator>

#include "cluster/failover_rounds.h"

namespace sculpt::server::cluster {
namespace {

using soak::kKeys;
using soak::Sculptor;
using sculpt::testing::Member;
using sculpt::testing::RunResult;
using sculpt::testing::Sculpt;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

class ClusterMoveTxnTest : public sculpt::testing::EtcdTest {};

TEST(MoveRecordTest, RoundTripsAndParsesItsKey) {
  const MoveRecord m{"c", 7, true};
  auto back = DecodeMove(EncodeMove(m));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->member, "c");
  EXPECT_EQ(back->epoch, 7u);
  EXPECT_TRUE(back->released);
  std::string scene, kind;
  ASSERT_TRUE(kKeys.ParseSceneKey(kKeys.Move("default"), &scene, &kind));
  EXPECT_EQ(scene, "default");
  EXPECT_EQ(kind, "move");
}

TEST(MoveRecordTest, RejectsMalformedMoveRecords) {
  EXPECT_FALSE(DecodeMove("not json").ok());
  EXPECT_FALSE(DecodeMove(R"({"epoch": 1})").ok());                         // no member
  EXPECT_FALSE(DecodeMove(R"({"member": "c"})").ok());                      // no epoch
  EXPECT_FALSE(DecodeMove(R"({"member": "c", "epoch": -1})").ok());         // not unsigned
  EXPECT_FALSE(DecodeMove(R"({"member": "c", "epoch": 1, "released": 1})").ok());
  const auto e = DecodeMove(R"({"member": "", "epoch": 1})");
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("member"), std::string::npos) << e.status();
  auto plain = DecodeMove(R"({"member": "c", "epoch": 1})");
  ASSERT_TRUE(plain.ok());
  EXPECT_FALSE(plain->released);
}

// A txn deletes keys only when its compares hold (the owner's release, the command's withdrawal).
TEST_F(ClusterMoveTxnTest, TxnDeletesOnlyWhenTheComparesHold) {
  auto& c = *etcd_client_;
  auto put = c.Sync(c.Put({"t/scenes/x/move", "v", 0}));
  ASSERT_TRUE(put.ok()) << put.status();
  auto kv = c.Sync(c.Get("t/scenes/x/move"));
  ASSERT_TRUE(kv.ok() && kv->has_value());
  TxnRequest stale;
  stale.compares = {{"t/scenes/x/move", Compare::Target::kModRevision, (*kv)->mod_revision - 1}};
  stale.success_deletes = {"t/scenes/x/move"};
  auto r = c.Sync(c.Txn(stale));
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_FALSE(r->succeeded);
  EXPECT_TRUE(c.Sync(c.Get("t/scenes/x/move"))->has_value());
  TxnRequest current = stale;
  current.compares[0].revision = (*kv)->mod_revision;
  current.success = {{"t/scenes/x/other", "w", 0}};
  r = c.Sync(c.Txn(current));
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->succeeded);
  EXPECT_FALSE(c.Sync(c.Get("t/scenes/x/move"))->has_value());
  EXPECT_TRUE(c.Sync(c.Get("t/scenes/x/other"))->has_value());
}

// The [cluster] lines of each member: the replication mode under test.
class ClusterMoveTest : public soak::FailoverSoakTest,
                        public ::testing::WithParamInterface<std::string> {
 protected:
  Member& StartMember(const std::string& name) {
    if (ports_.count(name) == 0) ports_[name] = sculpt::testing::FreePort();
    members_[name] = std::make_unique<Member>(
        name, etcd_->endpoint(), dir_.path(),
        "replication = \"" + GetParam() + "\"\n" + soak::SanitizerLimits(),
        std::vector<std::string>{"--http", "127.0.0.1:0"}, 2000,
        "127.0.0.1:" + std::to_string(ports_[name]));
    return *members_[name];
  }
  std::string MoveArgs(const std::string& member) {
    return "cluster move default " + member + " --etcd " + etcd_->endpoint() +
           " --prefix t/ --timeout-ms 30000";
  }
};

TEST_P(ClusterMoveTest, MovesTheSceneToAMemberAsAStandbyPromotionAndEveryStrokeIsAckedOnce) {
  for (const char* n : {"a", "b", "c"}) {
    ASSERT_NE(StartMember(n).WaitPort(), 0) << n << " did not start; see " << dir_.path();
  }
  ASSERT_TRUE(OwnerWithAFollowingStandby(milliseconds(20000)))
      << "no owner with a following standby\n" << Diagnosis();
  const OwnerRecord from = *Owner();
  const std::string standby = Standby()->member;
  // The member that neither owns nor follows the scene: the owner must name it standby first.
  std::string target;
  for (const char* n : {"a", "b", "c"}) {
    if (n != from.member && n != standby) target = n;
  }
  ASSERT_FALSE(target.empty());
  const std::vector<std::string> addresses = Addresses();
  ASSERT_EQ(addresses.size(), 3u);

  std::vector<std::unique_ptr<Sculptor>> sculptors;
  for (int i = 0; i < 2; ++i) {
    const std::string& via = addresses[i % 3];
    sculptors.push_back(std::make_unique<Sculptor>(
        i, static_cast<uint16_t>(std::stoi(via.substr(via.rfind(':') + 1))), addresses));
    ASSERT_TRUE(sculptors.back()->ok()) << "sculptor " << i << " could not join";
  }
  std::this_thread::sleep_for(milliseconds(1500));  // sculpting on the first owner
  // A sanitized owner on loaded cores had acknowledged nothing yet after 1.5 s.
  EXPECT_TRUE(WaitFor(
      [&] {
        return std::all_of(sculptors.begin(), sculptors.end(),
                           [](const auto& s) { return s->client().stats().acks > 0; });
      },
      sculpt::testing::Scaled(milliseconds(3000))));

  const auto started = Clock::now();
  const RunResult moved = Sculpt(MoveArgs(target));
  const double move_ms = std::chrono::duration<double, std::milli>(Clock::now() - started).count();
  ASSERT_EQ(moved.exit_code, 0) << moved.output << Diagnosis();
  EXPECT_NE(moved.output.find("member " + target + " owns scene default at epoch " +
                              std::to_string(from.epoch + 1)),
            std::string::npos)
      << moved.output;
  const auto to = Owner();
  ASSERT_TRUE(to.has_value());
  EXPECT_EQ(to->member, target);
  EXPECT_EQ(to->epoch, from.epoch + 1);
  // The old owner is an ordinary member now; the request is gone once the new owner saw it.
  ASSERT_TRUE(WaitFor(
      [&] {
        auto m = MemberOf(from.member);
        return m && m->owns.empty();
      },
      milliseconds(5000)));
  EXPECT_TRUE(WaitFor(
      [&] { return !etcd_client_->Sync(etcd_client_->Get(kKeys.Move("default")))->has_value(); },
      milliseconds(5000)));

  // The sculptors carry on against the new owner without any action.
  const auto after_move = Clock::now();
  EXPECT_TRUE(WaitFor(
      [&] {
        return std::all_of(sculptors.begin(), sculptors.end(),
                           [&](const auto& s) { return s->AckedSince(after_move); });
      },
      milliseconds(15000)))
      << Diagnosis();
  std::this_thread::sleep_for(milliseconds(500));
  for (auto& s : sculptors) s->Stop();
  uint64_t strokes = 0;
  for (auto& s : sculptors) {
    for (int attempt = 0; attempt < 20 && s->client().unacked() > 0; ++attempt) {
      if (!s->client().joined()) (void)s->client().Reconnect();
      (void)s->client().WaitAllAcked(sculpt::testing::Scaled(milliseconds(1000)));
    }
    EXPECT_EQ(s->client().unacked(), 0u);
    EXPECT_EQ(s->client().stats().refused, 0u) << s->refusals();
    EXPECT_GE(s->client().stats().reconnects, 1u) << "the sculptor never left the old owner";
    strokes += static_cast<uint64_t>(s->sent());
  }
  ASSERT_GT(strokes, 0u);

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(5000);
  sculpt::client::Client viewer(options);
  const std::string& tcp = to->tcp;
  ASSERT_TRUE(
      viewer.Connect("127.0.0.1", static_cast<uint16_t>(std::stoi(tcp.substr(tcp.rfind(':') + 1))))
          .ok());
  ASSERT_TRUE(viewer.Hello("sculpt-dev-viewer", v1::ROLE_VIEWER, "move-viewer", 0).ok());
  auto joined = viewer.Join("");
  ASSERT_TRUE(joined.ok()) << joined.status();
  // Every stroke applied exactly once, on the copy the new owner took over: 2 poses each.
  EXPECT_EQ(joined->info.global_seq(), 2 * strokes);
  for (const char* n : {"a", "b", "c"}) {
    std::ifstream in(dir_.path() / (std::string(n) + ".log"));
    const std::string log((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(log.find("diverged"), std::string::npos) << "member " << n << " diverged";
  }
  std::printf("{\"test\": \"cluster_move\", \"replication\": \"%s\", \"sculptors\": 2, "
              "\"rate_hz\": %d, \"from\": \"%s\", \"to\": \"%s\", \"epoch\": %llu, "
              "\"move_ms\": %.0f, \"strokes\": %llu}\n",
              GetParam().c_str(), soak::kRateHz, from.member.c_str(), target.c_str(),
              static_cast<unsigned long long>(to->epoch), move_ms,
              static_cast<unsigned long long>(strokes));
  std::fflush(stdout);

  // Refusals, each naming the member and what is allowed.
  const RunResult unknown = Sculpt(MoveArgs("zz"));
  EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
  EXPECT_NE(unknown.output.find("member \"zz\" is not a live member"), std::string::npos)
      << unknown.output;
  EXPECT_NE(unknown.output.find("members that can take scene default: "), std::string::npos)
      << unknown.output;
  const RunResult owner = Sculpt(MoveArgs(target));
  EXPECT_EQ(owner.exit_code, 2) << owner.output;
  EXPECT_NE(owner.output.find("member " + target + " already owns scene default"),
            std::string::npos)
      << owner.output;
  EXPECT_EQ(Owner()->member, target);
}

// A request the owner cannot carry out is removed with the reason in its log; a move that does
// not finish within the command's timeout is withdrawn and the owner keeps acknowledging.
TEST_P(ClusterMoveTest, RemovesRequestsItCannotCarryOutAndWithdrawsATimedOutMove) {
  for (const char* n : {"a", "b", "c"}) {
    ASSERT_NE(StartMember(n).WaitPort(), 0) << n << " did not start; see " << dir_.path();
  }
  ASSERT_TRUE(OwnerWithAFollowingStandby(milliseconds(20000)))
      << "no owner with a following standby\n" << Diagnosis();
  const OwnerRecord from = *Owner();
  std::string target;
  for (const char* n : {"a", "b", "c"}) {
    if (n != from.member) target = n;
  }
  const std::string key = kKeys.Move("default");
  auto gone = [&] { return !etcd_client_->Sync(etcd_client_->Get(key))->has_value(); };
  auto owner_log = [&] {
    std::ifstream in(dir_.path() / (from.member + ".log"));
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  // Written by hand (the command refuses both): a member that is not live, and a stale epoch.
  ASSERT_TRUE(etcd_client_->Sync(etcd_client_->Put({key, EncodeMove({"zz", from.epoch}), 0})).ok());
  EXPECT_TRUE(WaitFor(gone, milliseconds(5000)));
  EXPECT_TRUE(WaitFor(
      [&] {
        return owner_log().find("move request of scene default to member zz removed: member zz "
                                "is not a live member") != std::string::npos;
      },
      milliseconds(2000)))
      << owner_log();
  ASSERT_TRUE(
      etcd_client_->Sync(etcd_client_->Put({key, EncodeMove({target, from.epoch + 5}), 0})).ok());
  EXPECT_TRUE(WaitFor(gone, milliseconds(5000)));
  EXPECT_TRUE(WaitFor(
      [&] {
        return owner_log().find("removed: its epoch " + std::to_string(from.epoch + 5) +
                                " is stale") != std::string::npos;
      },
      milliseconds(2000)))
      << owner_log();

  const std::vector<std::string> addresses = Addresses();
  Sculptor sculptor(0, static_cast<uint16_t>(std::stoi(from.tcp.substr(from.tcp.rfind(':') + 1))),
                    addresses);
  ASSERT_TRUE(sculptor.ok());
  std::this_thread::sleep_for(milliseconds(500));
  const RunResult timed_out = Sculpt("cluster move default " + target + " --etcd " +
                                     etcd_->endpoint() + " --prefix t/ --timeout-ms 400");
  EXPECT_EQ(timed_out.exit_code, 1) << timed_out.output;
  EXPECT_NE(timed_out.output.find("member " + target +
                                  " did not take scene default over within --timeout-ms=400"),
            std::string::npos)
      << timed_out.output;
  EXPECT_NE(timed_out.output.find("the move request was removed"), std::string::npos)
      << timed_out.output;
  EXPECT_TRUE(gone());
  // The owner keeps the scene and acknowledges again (it may have fenced for the move).
  const auto after = Clock::now();
  EXPECT_TRUE(WaitFor([&] { return sculptor.AckedSince(after); }, milliseconds(10000)))
      << Diagnosis();
  const auto owner = Owner();
  ASSERT_TRUE(owner.has_value());
  EXPECT_EQ(owner->member, from.member);
  EXPECT_EQ(owner->epoch, from.epoch);
  sculptor.Stop();
  (void)sculptor.client().WaitAllAcked(milliseconds(3000));
  EXPECT_EQ(sculptor.client().unacked(), 0u);
  EXPECT_EQ(sculptor.client().stats().refused, 0u) << sculptor.refusals();
}

INSTANTIATE_TEST_SUITE_P(Replication, ClusterMoveTest, ::testing::Values("async", "sync"),
                         [](const auto& info) { return info.param; });

}  // namespace
}  // namespace sculpt::server::cluster
