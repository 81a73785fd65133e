// A real Scene with replication = "sync" (issue 17), without etcd: a stroke's acknowledgement
// waits for the standby's word (Scene::StandbyDurable), and falls back to async after
// cluster.sync_fallback_ms when the word does not come.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>

#include "cluster/processes.h"
#include "integration/raw_client.h"
#include "scene/scene.h"
#include "sculpt/codec/skin_messages.h"

namespace sculpt::server {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

class SyncSceneTest : public ::testing::Test {
 protected:
  void Open(int fallback_ms) {
    config_.data_dir = (dir_.path() / "data").string();
    config_.group_commit_ms = 2;
    // Cluster settings only: no agent runs here, so the scene is never fenced.
    config_.cluster.etcd = {"http://127.0.0.1:9"};
    config_.cluster.member = "a";
    config_.cluster.replication = "sync";
    config_.cluster.sync_fallback_ms = fallback_ms;
    auto s = Scene::Open(config_);
    ASSERT_TRUE(s.ok()) << s.status();
    scene_ = std::move(s).value();
  }
  void TearDown() override { scene_.reset(); }

  std::future<StrokeOutcome> Press(uint64_t client_seq) {
    v1::ClientMessage m =
        sculpt::testing::RawClient::PressStroke(client_seq, {0, 0, 22.5 + client_seq * 0.1}, 3);
    auto limits = scene_->LimitsFor("clay");
    EXPECT_TRUE(limits.ok());
    auto stroke = codec::DecodeStroke(m.stroke(), *limits);
    EXPECT_TRUE(stroke.ok()) << stroke.status();
    auto p = std::make_shared<std::promise<StrokeOutcome>>();
    scene_->Submit(7, std::move(stroke).value(), [p](const StrokeOutcome& o) { p->set_value(o); });
    return p->get_future();
  }

  sculpt::testing::TempDir dir_{"sculpt-sync-scene"};
  ServerConfig config_;
  std::unique_ptr<Scene> scene_;
};

TEST_F(SyncSceneTest, AckWaitsForTheStandbyAndComesInOrder) {
  Open(/*fallback_ms=*/0);  // never fall back: only the standby's word releases the acks
  ASSERT_TRUE(scene_->acks().sync());
  std::atomic<int> applied{0};
  scene_->ObserveCommitsForTesting([&](const Scene::CommitEvent& e) {
    if (std::string(e.step) == "applied") ++applied;
  });
  std::future<StrokeOutcome> first = Press(1);
  std::future<StrokeOutcome> second = Press(2);
  // Both applied and locally durable (group commit every 2 ms), yet not acknowledged.
  // (Each stroke is logged as one record per pose: the two take 2 * poses sequences.)
  ASSERT_TRUE(sculpt::testing::WaitFor([&] { return applied.load() == 2; }, milliseconds(5000)));
  scene_->ObserveCommitsForTesting(nullptr);
  const uint64_t per_stroke = scene_->global_seq() / 2;
  EXPECT_EQ(first.wait_for(milliseconds(300)), std::future_status::timeout)
      << "acknowledged before the standby had it";
  EXPECT_EQ(scene_->acks_awaiting_durability(), 2u);
  // The standby holds the first stroke's poses: only the first is answered.
  scene_->StandbyDurable(per_stroke);
  ASSERT_EQ(first.wait_for(milliseconds(5000)), std::future_status::ready);
  const StrokeOutcome a = first.get();
  EXPECT_TRUE(a.status.ok()) << a.status;
  EXPECT_EQ(a.global_seq_first, 1u);
  EXPECT_EQ(second.wait_for(milliseconds(200)), std::future_status::timeout);
  scene_->StandbyDurable(scene_->global_seq());
  ASSERT_EQ(second.wait_for(milliseconds(5000)), std::future_status::ready);
  EXPECT_EQ(second.get().global_seq_first, per_stroke + 1);
  EXPECT_FALSE(scene_->acks().fallen_back());
}

TEST_F(SyncSceneTest, FallsBackToAsyncWhenNoStandbyConfirms) {
  Open(/*fallback_ms=*/250);
  const auto t0 = Clock::now();
  std::future<StrokeOutcome> f = Press(1);
  ASSERT_EQ(f.wait_for(milliseconds(10000)), std::future_status::ready);
  const auto waited = Clock::now() - t0;
  EXPECT_TRUE(f.get().status.ok());
  EXPECT_GE(waited, milliseconds(250)) << "acknowledged before sync_fallback_ms";
  EXPECT_TRUE(scene_->acks().fallen_back());
  EXPECT_EQ(scene_->acks().fallbacks(), 1u);
  // Fallen back: the next stroke is acknowledged without waiting for anyone.
  const auto t1 = Clock::now();
  std::future<StrokeOutcome> g = Press(2);
  ASSERT_EQ(g.wait_for(milliseconds(10000)), std::future_status::ready);
  EXPECT_LT(Clock::now() - t1, milliseconds(200));
  // The standby catches up with everything held at the fall-back: synchronous again.
  scene_->StandbyDurable(scene_->global_seq());
  EXPECT_FALSE(scene_->acks().fallen_back());
  const uint64_t before = scene_->global_seq();
  std::future<StrokeOutcome> h = Press(3);
  EXPECT_EQ(h.wait_for(milliseconds(150)), std::future_status::timeout)
      << "acknowledged without the standby after it caught up";
  ASSERT_TRUE(
      sculpt::testing::WaitFor([&] { return scene_->global_seq() > before; }, milliseconds(5000)));
  scene_->StandbyDurable(scene_->global_seq());
  ASSERT_EQ(h.wait_for(milliseconds(5000)), std::future_status::ready);
  EXPECT_EQ(scene_->acks().fallbacks(), 1u);
}

// A ball edit changes no object, so it never reaches the standby's copy: once the standby holds
// everything before it, its answer goes (it used to wait for the next stroke, or the fall-back,
// which then switched the scene to async).
TEST_F(SyncSceneTest, AnEditTheStandbyNeverGetsWaitsOnlyForWhatCameBefore) {
  SkinConfig skin;
  skin.name = "outline";
  skin.origin = {0, 0, 0};
  skin.chord_tolerance = 0.05;
  skin.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
  config_.scene.skins = {skin};
  Open(/*fallback_ms=*/0);  // never fall back
  std::future<StrokeOutcome> stroke = Press(1);
  ASSERT_TRUE(sculpt::testing::WaitFor([&] { return scene_->global_seq() > 0; }, milliseconds(5000)));
  const uint64_t stroke_last = scene_->global_seq();
  v1::SkinBallEdit e;
  e.set_client_seq(1);
  e.set_skin("outline");
  e.set_op(v1::SKIN_BALL_OP_MOVE);
  e.set_index(2);
  e.mutable_ball()->set_x(0.5);
  e.mutable_ball()->set_r(3);
  auto edit = codec::DecodeSkinBallEdit(e);
  ASSERT_TRUE(edit.ok()) << edit.status();
  auto p = std::make_shared<std::promise<SkinOutcome>>();
  std::future<SkinOutcome> ball = p->get_future();
  scene_->EditSkin(7, std::move(edit).value(), [p](const SkinOutcome& k) { p->set_value(k); });
  EXPECT_EQ(ball.wait_for(milliseconds(300)), std::future_status::timeout)
      << "answered before the standby held the stroke before it";
  scene_->StandbyDurable(stroke_last);
  ASSERT_EQ(stroke.wait_for(milliseconds(5000)), std::future_status::ready);
  ASSERT_EQ(ball.wait_for(milliseconds(5000)), std::future_status::ready)
      << "the ball edit waits for a standby that never gets it";
  EXPECT_TRUE(ball.get().status.ok());
  EXPECT_GT(scene_->global_seq(), stroke_last);
  EXPECT_FALSE(scene_->acks().fallen_back());
}

TEST_F(SyncSceneTest, AsyncIsTheDefault) {
  ServerConfig c;
  EXPECT_EQ(c.cluster.replication, "async");
  config_.data_dir = (dir_.path() / "data").string();
  auto s = Scene::Open(config_);
  ASSERT_TRUE(s.ok()) << s.status();
  scene_ = std::move(s).value();
  EXPECT_FALSE(scene_->acks().sync());
  std::future<StrokeOutcome> f = Press(1);
  ASSERT_EQ(f.wait_for(milliseconds(5000)), std::future_status::ready);
  EXPECT_TRUE(f.get().status.ok());
}

}  // namespace
}  // namespace sculpt::server
