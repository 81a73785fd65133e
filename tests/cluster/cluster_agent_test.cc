// ClusterAgent in-process against a real etcd: it takes its scene, and when etcd stops
// answering (SIGSTOP) the fence drops within the lease TTL; when etcd returns, the member
// registers again and takes its scene back with the next epoch.
#include "cluster/cluster_agent.h"

#include <gtest/gtest.h>
#include <signal.h>

#include "cluster/processes.h"
#include "cluster/records.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::EtcdProcess;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

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

  std::unique_ptr<EtcdProcess> etcd_;
  std::unique_ptr<ClusterAgent> agent_;
};

TEST_F(ClusterAgentTest, StopsAcknowledgingWithinTheTtlWhenEtcdIsGoneAndRecovers) {
  agent_ = std::make_unique<ClusterAgent>(Config("a"), "vase", [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "").ok());
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch() == 1; }, milliseconds(3000)));
  EXPECT_EQ(agent_->RouteScene("").kind, Route::Kind::kLocal);
  EXPECT_EQ(agent_->RouteScene("vase").kind, Route::Kind::kLocal);
  EXPECT_EQ(agent_->RouteScene("other").kind, Route::Kind::kUnknown);

  const auto paused = std::chrono::steady_clock::now();
  ASSERT_EQ(kill(etcd_->process().pid(), SIGSTOP), 0);
  ASSERT_TRUE(WaitFor([&] { return !agent_->fence()->held(); }, milliseconds(4000)));
  const auto fenced_ms =
      std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now() - paused).count();
  // Never later than the lease could last in etcd; not at once either (the lease was fresh).
  EXPECT_LE(fenced_ms, 2000);
  EXPECT_GE(fenced_ms, 500);
  RecordProperty("fenced_after_ms", std::to_string(fenced_ms));
  EXPECT_EQ(agent_->fence()->Check().code(), Status::Code::kUnavailable);
  EXPECT_EQ(agent_->RouteScene("").kind, Route::Kind::kUnavailable);

  // etcd returns: either it expired the lease (the member registers again and, as the scene's
  // last owner, takes it back with epoch 2) or a keep-alive it had queued renewed it first (the
  // owner key never went away: epoch 1 holds again). Either way the member serves again.
  std::this_thread::sleep_for(milliseconds(600));
  ASSERT_EQ(kill(etcd_->process().pid(), SIGCONT), 0);
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch() >= 1; }, milliseconds(6000)))
      << "the member did not take its scene back after etcd returned";
  RecordProperty("epoch_after_outage", std::to_string(agent_->owned_epoch()));
  EXPECT_EQ(agent_->RouteScene("").kind, Route::Kind::kLocal);
}

TEST_F(ClusterAgentTest, SecondMemberRoutesToTheFirst) {
  agent_ = std::make_unique<ClusterAgent>(Config("a"), "vase", [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "127.0.0.1:2").ok());
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch() == 1; }, milliseconds(3000)));
  ClusterAgent b(Config("b"), "vase", [] { return 0u; });
  ASSERT_TRUE(b.Start("127.0.0.1:3", "").ok());
  const Route r = b.RouteScene("");
  EXPECT_EQ(r.kind, Route::Kind::kRedirect);
  EXPECT_EQ(r.scene, "vase");
  EXPECT_EQ(r.member, "a");
  EXPECT_EQ(r.tcp, "127.0.0.1:1");
  EXPECT_EQ(r.http, "127.0.0.1:2");
  EXPECT_EQ(r.epoch, 1u);
  EXPECT_EQ(b.owned_epoch(), 0u);
  EXPECT_FALSE(b.fence()->held());
  b.Stop();
}

TEST(ClusterAgentNoEtcd, RejectsStartWhenEtcdDoesNotAnswer) {
  ClusterConfig c;
  c.etcd = {"http://127.0.0.1:" + std::to_string(sculpt::testing::FreePort())};
  c.member = "a";
  ClusterAgent agent(c, "vase", [] { return 0u; });
  const Status s = agent.Start("127.0.0.1:1", "");
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
  EXPECT_NE(s.message().find("cannot register member a"), std::string::npos) << s;
  EXPECT_FALSE(agent.fence()->held());
  EXPECT_EQ(agent.RouteScene("").kind, Route::Kind::kUnavailable);
}

// Bad input between members (issue 17): owner keys that no acquisition wrote are never routed to
// — one without a lease, and one under a lease but without the epoch record an acquisition
// writes with it.
TEST_F(ClusterAgentTest, NeverRoutesToAnOwnerClaimWithoutLeaseOrEpochRecord) {
  agent_ = std::make_unique<ClusterAgent>(Config("a"), "vase", [] { return 0u; });
  ASSERT_TRUE(agent_->Start("127.0.0.1:1", "").ok());
  ASSERT_TRUE(WaitFor([&] { return agent_->owned_epoch() == 1; }, milliseconds(3000)));
  auto c = sculpt::testing::ConnectWhenReady(*etcd_);
  ASSERT_TRUE(c.ok()) << c.status();
  EtcdClient& etcd = **c;
  const Keys keys{"agent/"};
  const std::string mallory =
      EncodeOwner(OwnerRecord{"mallory", "127.0.0.1:9", "127.0.0.1:10", 5});
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

}  // namespace
}  // namespace sculpt::server::cluster
