// ClusterAgent in-process against a real etcd: it takes its scene, and when etcd stops
// answering (SIGSTOP) the fence drops within the lease TTL; when etcd returns, the member
// registers again and takes its scene back with the next epoch.
#include "cluster/cluster_agent.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <thread>

#include "cluster/processes.h"
#include "cluster/records.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::EtcdProcess;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

// One hosted scene, "vase", with no data directory of its own (these agents never promote).
std::vector<HostedScene> Vase() { return {HostedScene{"vase", "", nullptr, nullptr, {}}}; }

// Scenes hosted in-process without a Scene behind them (sequence 0).
std::vector<HostedScene> Hosted(const std::vector<std::string>& names) {
  std::vector<HostedScene> out;
  for (const std::string& n : names) out.push_back({n, "", [] { return uint64_t{0}; }, nullptr, {}});
  return out;
}

class ClusterAgentTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!sculpt::testing::HaveEtcd()) GTEST_SKIP() << sculpt::testing::kNoEtcd;
    etcd_ = std::make_unique<EtcdProcess>();
    auto c = sculpt::testing::ConnectWhenReady(*etcd_);
    ASSERT_TRUE(c.ok()) << c.status();
  }
  void TearDown() override {
    if (etcd_) kill(etcd_->process().pid(), SIGCONT);
    agent_.reset();
    etcd_.reset();
  }
  ClusterConfig Config(const std::string& member) const {
    ClusterConfig c;
    c.etcd = {etcd_->endpoint()};
    c.member = member;
    c.prefix = "agent/";
    return c;
  }

  /// Replaces agent_ by member a hosting p and q, and starts it.
  Status StartHostingPAndQ() {
    agent_ = std::make_unique<ClusterAgent>(Config("a"), Hosted({"p", "q"}), [] { return 0u; });
    return agent_->Start("127.0.0.1:1", "");
  }
  /// Whether agent_ comes to own p and q at `epoch` within `within`.
  bool OwnsPAndQ(uint64_t epoch, milliseconds within) {
    return WaitFor(
        [&] { return agent_->owned_epoch("p") == epoch && agent_->owned_epoch("q") == epoch; },
        within);
  }

  std::unique_ptr<EtcdProcess> etcd_;
  std::unique_ptr<ClusterAgent> agent_;
};

TEST_F(ClusterAgentTest, StopsAcknowledgingWithinTheTtlWhenEtcdIsGoneAndRecovers) {
  agent_ = std::make_unique<ClusterAgent>(Config("a"), Vase(), [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "").ok());
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch("vase") == 1; }, milliseconds(3000)));
  EXPECT_EQ(agent_->RouteScene("").kind, Route::Kind::kLocal);
  EXPECT_EQ(agent_->RouteScene("vase").kind, Route::Kind::kLocal);
  EXPECT_EQ(agent_->RouteScene("other").kind, Route::Kind::kUnknown);

  const auto paused = std::chrono::steady_clock::now();
  ASSERT_TRUE(etcd_->process().Pause()) << "not stopped within 5 s";
  ASSERT_TRUE(WaitFor([&] { return !agent_->fence("vase")->held(); }, milliseconds(4000)));
  const auto fenced_ms =
      std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now() - paused).count();
  // Never later than the lease could last in etcd; not at once either (the lease was fresh).
  EXPECT_LE(fenced_ms, 2000);
  EXPECT_GE(fenced_ms, 500);
  RecordProperty("fenced_after_ms", std::to_string(fenced_ms));
  EXPECT_EQ(agent_->fence("vase")->Check().code(), Status::Code::kUnavailable);
  EXPECT_EQ(agent_->RouteScene("").kind, Route::Kind::kUnavailable);

  // etcd returns: either it expired the lease (the member registers again and, as the scene's
  // last owner, takes it back with epoch 2) or a keep-alive it had queued renewed it first (the
  // owner key never went away: epoch 1 holds again). Either way the member serves again.
  std::this_thread::sleep_for(milliseconds(600));
  ASSERT_EQ(kill(etcd_->process().pid(), SIGCONT), 0);
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch("vase") >= 1; }, milliseconds(6000)))
      << "the member did not take its scene back after etcd returned";
  RecordProperty("epoch_after_outage", std::to_string(agent_->owned_epoch("vase")));
  EXPECT_EQ(agent_->RouteScene("").kind, Route::Kind::kLocal);
}

TEST_F(ClusterAgentTest, SecondMemberRoutesToTheFirst) {
  agent_ = std::make_unique<ClusterAgent>(Config("a"), Vase(), [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "127.0.0.1:2").ok());
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch("vase") == 1; }, milliseconds(3000)));
  ClusterAgent b(Config("b"), Vase(), [] { return 0u; });
  ASSERT_TRUE(b.Start("127.0.0.1:3", "").ok());
  const Route r = b.RouteScene("");
  EXPECT_EQ(r.kind, Route::Kind::kRedirect);
  EXPECT_EQ(r.scene, "vase");
  EXPECT_EQ(r.member, "a");
  EXPECT_EQ(r.tcp, "127.0.0.1:1");
  EXPECT_EQ(r.http, "127.0.0.1:2");
  EXPECT_EQ(r.epoch, 1u);
  EXPECT_EQ(b.owned_epoch("vase"), 0u);
  EXPECT_FALSE(b.fence("vase")->held());
  b.Stop();
}

TEST(ClusterAgentNoEtcd, RejectsStartWhenEtcdDoesNotAnswer) {
  ClusterConfig c;
  c.etcd = {"http://127.0.0.1:" + std::to_string(sculpt::testing::FreePort())};
  c.member = "a";
  ClusterAgent agent(c, Vase(), [] { return 0u; });
  const Status s = agent.Start("127.0.0.1:1", "");
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
  EXPECT_NE(s.message().find("cannot register member a"), std::string::npos) << s;
  EXPECT_FALSE(agent.fence("vase")->held());
  EXPECT_EQ(agent.RouteScene("").kind, Route::Kind::kUnavailable);
}

// Bad input between members (issue 17): owner keys that no acquisition wrote are never routed to
// — one without a lease, and one under a lease but without the epoch record an acquisition
// writes with it.
TEST_F(ClusterAgentTest, NeverRoutesToAnOwnerClaimWithoutLeaseOrEpochRecord) {
  agent_ = std::make_unique<ClusterAgent>(Config("a"), Vase(), [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "").ok());
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch("vase") == 1; }, milliseconds(3000)));
  auto c = sculpt::testing::ConnectWhenReady(*etcd_);
  ASSERT_TRUE(c.ok()) << c.status();
  EtcdClient& etcd = **c;
  const Keys keys{"agent/"};
  const std::string mallory = EncodeOwner(OwnerRecord{"mallory", "127.0.0.1:9", "127.0.0.1:10", 5});
  ASSERT_TRUE(etcd.Sync(etcd.Put({keys.Owner("pot"), mallory, 0})).ok());
  auto lease = etcd.Sync(etcd.Grant(milliseconds(10000)));
  ASSERT_TRUE(lease.ok()) << lease.status();
  ASSERT_TRUE(etcd.Sync(etcd.Put({keys.Owner("urn"), mallory, lease->id})).ok());
  // Both scenes are in the agent's table from its next refresh on (unknown before).
  ASSERT_TRUE(WaitFor(
      [&] {
        return agent_->RouteScene("pot").kind != Route::Kind::kUnknown &&
               agent_->RouteScene("urn").kind != Route::Kind::kUnknown;
      },
      milliseconds(3000)));
  for (const char* scene : {"pot", "urn"}) {
    const Route r = agent_->RouteScene(scene);
    EXPECT_EQ(r.kind, Route::Kind::kUnavailable) << scene;
    EXPECT_NE(r.member, "mallory") << scene;
  }
  // Its own scene is untouched.
  EXPECT_EQ(agent_->RouteScene("vase").kind, Route::Kind::kLocal);
}

// Several scenes per member (issue 17's "three members, six scenes"): two members hosting the
// same four scenes, started together, own two each (placement spreads the new scenes in one
// pass that both compute alike); each routes the other's scenes to it, and a scene's fence is
// held only on its owner.
TEST_F(ClusterAgentTest, TwoMembersFourScenesOwnTwoEachAndRedirectToEachOther) {
  const std::vector<std::string> names = {"p", "q", "r", "s"};
  agent_ = std::make_unique<ClusterAgent>(Config("a"), Hosted(names), [] { return 0u; });
  ClusterAgent b(Config("b"), Hosted(names), [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "127.0.0.1:2").ok());
  ASSERT_TRUE(b.Start("127.0.0.1:3", "127.0.0.1:4").ok());
  auto owned_by = [&](ClusterAgent& m) {
    std::vector<std::string> out;
    for (const std::string& n : names) {
      if (m.owned_epoch(n) != 0) out.push_back(n);
    }
    return out;
  };
  ASSERT_TRUE(WaitFor([&] { return owned_by(*agent_).size() + owned_by(b).size() == 4; },
                      milliseconds(5000)))
      << "a owns " << owned_by(*agent_).size() << ", b owns " << owned_by(b).size();
  // Which two depends on which member's tick read the other's acquisitions first (both compute
  // the same picks from the same records); two each does not.
  const std::vector<std::string> of_a = owned_by(*agent_);
  EXPECT_EQ(of_a.size(), 2u);
  EXPECT_EQ(owned_by(b).size(), 2u);
  auto a_owns_scene = [&](const std::string& n) {
    return std::find(of_a.begin(), of_a.end(), n) != of_a.end();
  };
  // Routing reads the table of the last refresh: each member has read the other's keys by then.
  ASSERT_TRUE(WaitFor(
      [&] {
        for (const std::string& n : names) {
          ClusterAgent& other = a_owns_scene(n) ? b : *agent_;
          if (other.RouteScene(n).kind != Route::Kind::kRedirect) return false;
        }
        return true;
      },
      milliseconds(3000)));
  for (const std::string& n : names) {
    const bool a_owns = a_owns_scene(n);
    ClusterAgent& owner = a_owns ? *agent_ : b;
    ClusterAgent& other = a_owns ? b : *agent_;
    EXPECT_EQ(owner.RouteScene(n).kind, Route::Kind::kLocal) << n;
    EXPECT_EQ(owner.owned_epoch(n), 1u) << n;
    EXPECT_TRUE(owner.fence(n)->held()) << n;
    EXPECT_EQ(owner.fence(n)->epoch(), 1u) << n;
    EXPECT_FALSE(other.fence(n)->held()) << n;
    EXPECT_EQ(other.owned_epoch(n), 0u) << n;
    const Route r = other.RouteScene(n);
    EXPECT_EQ(r.kind, Route::Kind::kRedirect) << n;
    EXPECT_EQ(r.scene, n);
    EXPECT_EQ(r.member, a_owns ? "a" : "b") << n;
    EXPECT_EQ(r.tcp, a_owns ? "127.0.0.1:1" : "127.0.0.1:3") << n;
    EXPECT_EQ(r.epoch, 1u) << n;
  }
  // A JoinScene naming no scene means the first hosted one; a scene nobody hosts has a fence
  // that is never held.
  EXPECT_EQ(b.RouteScene("").scene, "p");
  EXPECT_EQ(agent_->RouteScene("").scene, "p");
  EXPECT_EQ(agent_->RouteScene("").kind,
            a_owns_scene("p") ? Route::Kind::kLocal : Route::Kind::kRedirect);
  EXPECT_EQ(b.RouteScene("").kind,
            a_owns_scene("p") ? Route::Kind::kRedirect : Route::Kind::kLocal);
  EXPECT_FALSE(agent_->fence("elsewhere")->held());
  EXPECT_EQ(agent_->owned_epoch("elsewhere"), 0u);
  // The member records say it: every hosted scene offered, the owned ones with their sequence.
  auto c = sculpt::testing::ConnectWhenReady(*etcd_);
  ASSERT_TRUE(c.ok()) << c.status();
  ASSERT_TRUE(WaitFor(
      [&] {
        auto kv = (*c)->Sync((*c)->Get(Keys{"agent/"}.Member("a")));
        if (!kv.ok() || !kv->has_value()) return false;
        auto m = DecodeMember((*kv)->value);
        if (!m.ok() || m->owns != of_a || m->offers != names) return false;
        for (const std::string& n : names) {
          if ((m->Owning(n) != nullptr) != a_owns_scene(n)) return false;
        }
        return true;
      },
      milliseconds(3000)));
  b.Stop();
}

// The "three members, six scenes" at the agent level: three members hosting the same six
// scenes, started together, own two each; every member routes each scene it does not own to its
// owner.
TEST_F(ClusterAgentTest, ThreeMembersSixScenesOwnTwoEach) {
  const std::vector<std::string> names = {"s1", "s2", "s3", "s4", "s5", "s6"};
  std::vector<std::unique_ptr<ClusterAgent>> agents;
  for (const char* m : {"a", "b", "c"}) {
    agents.push_back(std::make_unique<ClusterAgent>(Config(m), Hosted(names), [] { return 0u; }));
  }
  for (size_t i = 0; i < agents.size(); ++i) {
    ASSERT_TRUE(agents[i]->Start("127.0.0.1:" + std::to_string(10 + i), "").ok());
  }
  auto owner_of = [&](const std::string& n) -> int {
    for (size_t i = 0; i < agents.size(); ++i) {
      if (agents[i]->owned_epoch(n) == 1) return static_cast<int>(i);
    }
    return -1;
  };
  ASSERT_TRUE(WaitFor(
      [&] {
        return std::all_of(names.begin(), names.end(),
                           [&](const std::string& n) { return owner_of(n) >= 0; });
      },
      milliseconds(6000)));
  std::vector<int> per_member(agents.size(), 0);
  for (const std::string& n : names) ++per_member[owner_of(n)];
  EXPECT_EQ(per_member, (std::vector<int>{2, 2, 2}));
  ASSERT_TRUE(WaitFor(
      [&] {
        for (const std::string& n : names) {
          for (size_t i = 0; i < agents.size(); ++i) {
            if (static_cast<int>(i) == owner_of(n)) continue;
            const Route r = agents[i]->RouteScene(n);
            if (r.kind != Route::Kind::kRedirect ||
                r.tcp != "127.0.0.1:" + std::to_string(10 + owner_of(n))) {
              return false;
            }
          }
        }
        return true;
      },
      milliseconds(3000)))
      << "some member does not redirect some scene to its owner";
  for (auto& agent : agents) agent->Stop();
}

// The lease resume a promotion's restart relies on (docs/cluster.md, "Lease resume"): a member
// owning two scenes is replaced by a new agent (as execv replaces the process image) with the
// resume token in the environment; the new agent keeps the lease and owns the same scenes at the
// same epochs at once — no acquisition, the epoch records untouched — and keeps the lease alive
// past its TTL. The other member never takes them over.
TEST_F(ClusterAgentTest, ARestartedAgentResumesItsLeaseAndItsScenesAtTheSameEpochs) {
  const std::vector<std::string> names = {"p", "q", "r", "s"};
  agent_ = std::make_unique<ClusterAgent>(Config("a"), Hosted(names), [] { return 0u; });
  ClusterAgent b(Config("b"), Hosted(names), [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "").ok());
  ASSERT_TRUE(b.Start("127.0.0.1:3", "").ok());
  // Two each (a places new scenes one tick after it registered, and b registers within that
  // tick); which two depends on timing, so the test goes by what a owns.
  std::vector<std::string> of_a;
  ASSERT_TRUE(WaitFor(
      [&] {
        of_a.clear();
        size_t owned = 0;
        for (const std::string& n : names) {
          if (agent_->owned_epoch(n) == 1) of_a.push_back(n);
          owned += agent_->owned_epoch(n) == 1 || b.owned_epoch(n) == 1;
        }
        return owned == names.size();
      },
      milliseconds(5000)));
  ASSERT_EQ(of_a.size(), 2u);
  const std::string p = of_a[0], r = of_a[1];
  auto c = sculpt::testing::ConnectWhenReady(*etcd_);
  ASSERT_TRUE(c.ok()) << c.status();
  EtcdClient& etcd = **c;
  const Keys keys{"agent/"};
  auto read = [&](const std::string& key) {
    auto kv = etcd.Sync(etcd.Get(key));
    return kv.ok() && kv->has_value() ? **kv : KeyValue{};
  };
  const KeyValue p_epoch = read(keys.Epoch(p));
  const KeyValue r_epoch = read(keys.Epoch(r));
  const KeyValue p_owner = read(keys.Owner(p));
  ASSERT_NE(p_owner.lease, 0);

  const std::string token = agent_->ResumeToken();
  ASSERT_EQ(token.substr(0, token.find(':')), std::to_string(p_owner.lease));
  ASSERT_EQ(setenv(kResumeLeaseEnv, token.c_str(), 1), 0);
  agent_->Abandon();
  EXPECT_FALSE(agent_->fence(p)->held());
  agent_ = std::make_unique<ClusterAgent>(Config("a"), Hosted(names), [] { return 0u; });
  const auto restarted = std::chrono::steady_clock::now();
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "").ok());
  EXPECT_EQ(getenv(kResumeLeaseEnv), nullptr) << "read once, not passed on";
  EXPECT_EQ(agent_->ResumeToken(), token) << "the same lease";
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch(p) == 1 && agent_->owned_epoch(r) == 1; },
                      milliseconds(1500)))
      << "the restarted agent did not resume its scenes at epoch 1";
  RecordProperty("resumed_after_ms",
                 std::to_string(std::chrono::duration_cast<milliseconds>(
                                    std::chrono::steady_clock::now() - restarted)
                                    .count()));
  // Past the lease's TTL: the new agent keeps it alive, and nothing changed hands meanwhile.
  const auto until = std::chrono::steady_clock::now() + milliseconds(2600);
  while (std::chrono::steady_clock::now() < until) {
    EXPECT_EQ(b.owned_epoch(p), 0u);
    EXPECT_EQ(b.owned_epoch(r), 0u);
    const Route route = b.RouteScene(p);
    EXPECT_TRUE(route.kind == Route::Kind::kRedirect && route.member == "a" && route.epoch == 1)
        << static_cast<int>(route.kind) << " " << route.member << " " << route.epoch;
    std::this_thread::sleep_for(milliseconds(100));
  }
  EXPECT_EQ(agent_->owned_epoch(p), 1u);
  EXPECT_EQ(agent_->owned_epoch(r), 1u);
  EXPECT_TRUE(agent_->fence(p)->held());
  EXPECT_EQ(agent_->fence(r)->epoch(), 1u);
  EXPECT_EQ(agent_->RouteScene(r).kind, Route::Kind::kLocal);
  // No epoch bump: the epoch records were not written again, the owner key is the same one.
  EXPECT_EQ(read(keys.Epoch(p)).mod_revision, p_epoch.mod_revision);
  EXPECT_EQ(read(keys.Epoch(r)).mod_revision, r_epoch.mod_revision);
  EXPECT_EQ(read(keys.Owner(p)).create_revision, p_owner.create_revision);
  EXPECT_EQ(read(keys.Owner(p)).lease, p_owner.lease);
  for (const std::string& n : names) {
    if (n != p && n != r) {
      EXPECT_EQ(b.owned_epoch(n), 1u) << n;
    }
  }
  b.Stop();
}

// The resume is refused when the token is not this process's (another PID: the image that held
// the lease may still run) — the member then registers a new lease and takes its scenes back
// with the next epoch only once the old lease has expired — and when the lease is gone.
TEST_F(ClusterAgentTest, ResumeIsRefusedForAnotherProcessAndForAGoneLease) {
  ASSERT_TRUE(StartHostingPAndQ().ok());
  ASSERT_TRUE(OwnsPAndQ(1, milliseconds(4000)));
  std::string token = agent_->ResumeToken();
  const std::string lease = token.substr(0, token.find(':'));
  ASSERT_EQ(setenv(kResumeLeaseEnv, (lease + ":" + std::to_string(getpid() + 1)).c_str(), 1), 0);
  agent_->Abandon();
  const auto abandoned = std::chrono::steady_clock::now();
  ASSERT_TRUE(StartHostingPAndQ().ok());
  EXPECT_EQ(getenv(kResumeLeaseEnv), nullptr);
  EXPECT_NE(agent_->ResumeToken().substr(0, lease.size() + 1), lease + ":") << "a new lease";
  // The old owner keys live on under the old lease: not owned here until it expires.
  std::this_thread::sleep_for(milliseconds(800));
  EXPECT_EQ(agent_->owned_epoch("p"), 0u);
  EXPECT_EQ(agent_->RouteScene("p").kind, Route::Kind::kUnavailable);
  ASSERT_TRUE(OwnsPAndQ(2, milliseconds(6000)))
      << "the member did not take its scenes back with epoch 2 after the old lease expired";
  EXPECT_GE(std::chrono::steady_clock::now() - abandoned, milliseconds(1000));

  // The right process, but the lease revoked meanwhile: a new lease, the scenes at epoch 3.
  token = agent_->ResumeToken();
  auto c = sculpt::testing::ConnectWhenReady(*etcd_);
  ASSERT_TRUE(c.ok()) << c.status();
  ASSERT_EQ(setenv(kResumeLeaseEnv, token.c_str(), 1), 0);
  agent_->Abandon();
  ASSERT_TRUE((*c)->Sync((*c)->Revoke(std::stoll(token.substr(0, token.find(':'))))).ok());
  ASSERT_TRUE(StartHostingPAndQ().ok());
  EXPECT_NE(agent_->ResumeToken(), token);
  ASSERT_TRUE(OwnsPAndQ(3, milliseconds(4000)));
}

// A promotion's restart opens its scenes before the agent starts, which may take longer than the
// TTL: the keeper holds the resumed lease meanwhile, and the restarted agent then owns its scenes
// again at the same epochs. Without it (no token of this process) nothing is kept.
TEST_F(ClusterAgentTest, ALeaseIsKeptAliveWhileTheRestartedProcessOpensItsScenes) {
  ASSERT_TRUE(StartHostingPAndQ().ok());
  ASSERT_TRUE(OwnsPAndQ(1, milliseconds(4000)));
  const std::string token = agent_->ResumeToken();
  ASSERT_EQ(setenv(kResumeLeaseEnv, (token.substr(0, token.find(':')) + ":" +
                                     std::to_string(getpid() + 1)).c_str(), 1), 0);
  EXPECT_EQ(ResumedLeaseKeeper::StartIfResuming(Config("a")), nullptr) << "another process's";
  ASSERT_EQ(setenv(kResumeLeaseEnv, token.c_str(), 1), 0);
  agent_->Abandon();
  auto keeper = ResumedLeaseKeeper::StartIfResuming(Config("a"));
  ASSERT_NE(keeper, nullptr);
  // Three TTLs of "opening scenes" (the default TTL is 2 s).
  std::this_thread::sleep_for(milliseconds(6000));
  EXPECT_GE(keeper->kept(), 4u);
  keeper.reset();
  EXPECT_NE(getenv(kResumeLeaseEnv), nullptr) << "left for the agent's Start";
  ASSERT_TRUE(StartHostingPAndQ().ok());
  EXPECT_EQ(agent_->ResumeToken(), token) << "the lease was not kept";
  ASSERT_TRUE(OwnsPAndQ(1, milliseconds(4000)))
      << "the scenes did not come back at epoch 1 under the kept lease";
  EXPECT_EQ(ResumedLeaseKeeper::StartIfResuming(Config("a")), nullptr) << "Start removed it";
}

}  // namespace
}  // namespace sculpt::server::cluster
