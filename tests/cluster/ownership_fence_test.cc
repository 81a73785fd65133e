// Fencing (issue 17): the OwnershipFence, and a Scene that consults it before sequencing and
// before acknowledging an edit.
#include "cluster/ownership_fence.h"

#include <gtest/gtest.h>

#include <future>

#include "cluster/processes.h"
#include "integration/raw_client.h"
#include "scene/scene.h"

namespace sculpt::server::cluster {
namespace {

using Clock = OwnershipFence::Clock;
using std::chrono::milliseconds;

TEST(OwnershipFenceTest, RefusesBeforeAnyGrant) {
  OwnershipFence f("vase");
  const Status s = f.Check();
  EXPECT_EQ(s.code(), Status::Code::kUnavailable);
  EXPECT_NE(s.message().find("scene vase"), std::string::npos) << s;
  EXPECT_NE(s.message().find("never acquired"), std::string::npos) << s;
  EXPECT_EQ(f.epoch(), 0u);
}

TEST(OwnershipFenceTest, HoldsUntilTheDeadlineOnly) {
  OwnershipFence f("vase");
  const auto t0 = Clock::now();
  f.Grant(3, t0 + milliseconds(2000));
  EXPECT_TRUE(f.Check(t0).ok());
  EXPECT_TRUE(f.Check(t0 + milliseconds(1999)).ok());
  const Status late = f.Check(t0 + milliseconds(2000));
  EXPECT_EQ(late.code(), Status::Code::kUnavailable);
  EXPECT_NE(late.message().find("epoch 3 not confirmed"), std::string::npos) << late;
  EXPECT_EQ(f.epoch(), 3u);
}

TEST(OwnershipFenceTest, KeepAliveExtendsTheDeadline) {
  OwnershipFence f("vase");
  const auto t0 = Clock::now();
  f.Grant(1, t0 + milliseconds(100));
  f.Extend(t0 + milliseconds(5000));
  EXPECT_TRUE(f.Check(t0 + milliseconds(4000)).ok());
}

TEST(OwnershipFenceTest, RevokeStopsAtOnceAndKeepAliveCannotRevive) {
  OwnershipFence f("vase");
  const auto t0 = Clock::now();
  f.Grant(2, t0 + milliseconds(60000));
  f.Revoke();
  const Status s = f.Check(t0);
  EXPECT_EQ(s.code(), Status::Code::kUnavailable);
  EXPECT_NE(s.message().find("epoch 2 lost"), std::string::npos) << s;
  f.Extend(t0 + milliseconds(60000));  // a keep-alive answered late
  EXPECT_FALSE(f.Check(t0).ok());
  f.Grant(3, t0 + milliseconds(60000));  // acquired again, new epoch
  EXPECT_TRUE(f.Check(t0).ok());
}

// A real Scene in a temporary data directory, fenced.
class FencedSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_.data_dir = (dir_.path() / "data").string();
    config_.group_commit_ms = 2;
    auto s = Scene::Open(config_);
    ASSERT_TRUE(s.ok()) << s.status();
    scene_ = std::move(s).value();
    scene_->set_ownership_fence(fence_);
  }
  void TearDown() override {
    scene_->ObserveCommitsForTesting(nullptr);
    scene_.reset();
  }

  StrokeOutcome Press(uint64_t client_seq) {
    v1::ClientMessage m = sculpt::testing::RawClient::PressStroke(client_seq, {0, 0, 22.5}, 3);
    auto limits = scene_->LimitsFor("clay");
    EXPECT_TRUE(limits.ok());
    auto stroke = codec::DecodeStroke(m.stroke(), *limits);
    EXPECT_TRUE(stroke.ok()) << stroke.status();
    std::promise<StrokeOutcome> p;
    scene_->Submit(7, std::move(stroke).value(), [&p](const StrokeOutcome& o) { p.set_value(o); });
    return p.get_future().get();
  }

  sculpt::testing::TempDir dir_{"sculpt-fenced-scene"};
  ServerConfig config_;
  std::shared_ptr<OwnershipFence> fence_ = std::make_shared<OwnershipFence>("default");
  std::unique_ptr<Scene> scene_;
};

TEST_F(FencedSceneTest, AcknowledgesWhileOwner) {
  fence_->Grant(1, Clock::now() + milliseconds(60000));
  const StrokeOutcome out = Press(1);
  EXPECT_TRUE(out.status.ok()) << out.status;
  EXPECT_GT(out.global_seq_first, 0u);
}

TEST_F(FencedSceneTest, RefusesEditsOnceTheLeaseIsLost) {
  fence_->Grant(1, Clock::now() + milliseconds(60000));
  ASSERT_TRUE(Press(1).status.ok());
  const uint64_t seq = scene_->global_seq();
  fence_->Revoke();
  const StrokeOutcome out = Press(2);
  EXPECT_EQ(out.status.code(), Status::Code::kUnavailable) << out.status;
  EXPECT_EQ(out.global_seq_first, 0u);
  EXPECT_EQ(scene_->global_seq(), seq) << "a fenced member sequenced an edit";
}

TEST_F(FencedSceneTest, RefusesEditsPastTheLeaseDeadline) {
  // The keep-alives stopped being answered: no revoke, the deadline just passes.
  fence_->Grant(1, Clock::now() + milliseconds(30));
  std::this_thread::sleep_for(milliseconds(40));
  const StrokeOutcome out = Press(1);
  EXPECT_EQ(out.status.code(), Status::Code::kUnavailable) << out.status;
  EXPECT_EQ(scene_->global_seq(), 0u);
}

TEST_F(FencedSceneTest, DoesNotAcknowledgeWhatItLoggedBeforeLosingTheLease) {
  fence_->Grant(1, Clock::now() + milliseconds(60000));
  // The lease goes between the append and the ack: the edit is in this member's log, but the
  // client must not hear an ack from a member that is no longer the owner.
  scene_->ObserveCommitsForTesting([this](const Scene::CommitEvent& e) {
    if (std::string(e.step) == "applied") fence_->Revoke();
  });
  const StrokeOutcome out = Press(1);
  EXPECT_EQ(out.status.code(), Status::Code::kUnavailable) << out.status;
  EXPECT_EQ(out.global_seq_first, 0u);
  EXPECT_FALSE(out.duplicate);
}

TEST_F(FencedSceneTest, AppliesNothingPastARefusedStrokeUntilItIsResent) {
  fence_->Grant(1, Clock::now() + milliseconds(60000));
  ASSERT_TRUE(Press(1).status.ok());
  // Stroke 2 meets a lapsed fence; the fence is back before stroke 3 (pipelined behind it).
  fence_->Revoke();
  EXPECT_EQ(Press(2).status.code(), Status::Code::kUnavailable);
  fence_->Grant(2, Clock::now() + milliseconds(60000));
  const uint64_t seq = scene_->global_seq();
  const StrokeOutcome third = Press(3);
  EXPECT_EQ(third.status.code(), Status::Code::kUnavailable) << third.status;
  EXPECT_NE(third.status.message().find("follows client_seq 2"), std::string::npos)
      << third.status;
  EXPECT_EQ(scene_->global_seq(), seq) << "a stroke past a refused one was applied";
  // The client resends in order: 2 is applied (not taken for a duplicate of 3), then 3.
  const StrokeOutcome two = Press(2);
  ASSERT_TRUE(two.status.ok()) << two.status;
  EXPECT_FALSE(two.duplicate);
  EXPECT_GT(two.global_seq_first, seq);
  const StrokeOutcome three = Press(3);
  ASSERT_TRUE(three.status.ok()) << three.status;
  EXPECT_FALSE(three.duplicate);
  EXPECT_GT(three.global_seq_first, two.global_seq_first);
}

}  // namespace
}  // namespace sculpt::server::cluster
