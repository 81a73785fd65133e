// Per-author undo and redo through the scene's commit pipeline (issue 15): logged, acknowledged
// once durable, de-duplicated, recovered after a restart, and equal to a scene that never had
// the undone stroke.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <future>
#include <string>

#include "integration/raw_client.h"
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
    std::promise<v1::UndoAck> p;
    scene.Undo(client, r, [&p](v1::UndoAck a) { p.set_value(std::move(a)); });
    return p.get_future().get();
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

}  // namespace
}  // namespace sculpt::server
