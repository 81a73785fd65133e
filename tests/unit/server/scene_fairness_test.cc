// The scene's compute thread shares itself between client sessions (Scene::RequesterScope,
// FairQueue): a session's backlog delays another session's edit by at most the one job of it in
// service; each session's edits keep their order; the scene's own work (hashes, Inspect,
// Flush) sees every job posted before it. Orders are asserted through global sequences.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "integration/raw_client.h"
#include "scene/scene.h"
#include "sculpt/core/thread_priority.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

class SceneFairnessTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_fair_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    ServerConfig c;
    c.fsync = "group";
    c.group_commit_ms = 2;
    c.scene.objects.front().radius = 12;
    c.data_dir = dir_.string();
    auto s = Scene::Open(c);
    ASSERT_TRUE(s.ok()) << s.status();
    scene_ = std::move(s).value();
    // The viewers' mesh cache is warmed at open by one job on the compute thread: let it pass,
    // so the queues below hold the test's jobs only.
    for (int i = 0; i < 2000 && !scene_->mesh_stats().warmed.load(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_TRUE(scene_->mesh_stats().warmed.load()) << "the mesh cache's warm-up did not end";
    // The first stroke holds the compute thread until released, so the queue behind it is
    // built deterministically.
    scene_->InjectTaskFaultForTesting([this](const std::string& op) {
      if (op != "stroke" || held_) return;
      held_ = true;
      entered_.set_value();
      release_.get_future().wait();
    });
  }
  void TearDown() override {
    scene_.reset();
    fs::remove_all(dir_);
  }

  // A 3-pose press from `client` (as session `session`), its outcome kept by client and seq.
  void Press(uint64_t session, uint64_t client, uint64_t seq) {
    const Scene::RequesterScope requester(session);
    const v1::ClientMessage m =
        testing::RawClient::PressStroke(seq, {0.2 * static_cast<double>(seq % 7), 0, 11.2}, 3,
                                        2.0);
    auto limits = scene_->LimitsFor("clay");
    ASSERT_TRUE(limits.ok());
    auto stroke = codec::DecodeStroke(m.stroke(), *limits);
    ASSERT_TRUE(stroke.ok()) << stroke.status();
    scene_->Submit(client, std::move(stroke).value(), [this, client](const StrokeOutcome& o) {
      std::lock_guard<std::mutex> lock(mu_);
      outcomes_[client].push_back(o);
    });
  }

  std::vector<StrokeOutcome> Outcomes(uint64_t client) {
    std::lock_guard<std::mutex> lock(mu_);
    return outcomes_[client];
  }

  fs::path dir_;
  std::unique_ptr<Scene> scene_;
  bool held_ = false;  // compute thread only
  std::promise<void> entered_;
  std::promise<void> release_;
  std::mutex mu_;
  std::map<uint64_t, std::vector<StrokeOutcome>> outcomes_;
};

TEST_F(SceneFairnessTest, ABacklogOfFiftyDelaysAnotherSessionsStrokeByAtMostTheOneInService) {
  constexpr uint64_t kA = 11, kB = 22;
  Press(/*session=*/1, kA, 1);
  entered_.get_future().wait();  // A's first stroke is in service
  for (uint64_t seq = 2; seq <= 50; ++seq) Press(1, kA, seq);
  Press(/*session=*/2, kB, 1);
  EXPECT_EQ(scene_->compute_queue_depth(), 50u);
  release_.set_value();
  scene_->Flush();

  const std::vector<StrokeOutcome> a = Outcomes(kA);
  const std::vector<StrokeOutcome> b = Outcomes(kB);
  ASSERT_EQ(a.size(), 50u);
  ASSERT_EQ(b.size(), 1u);
  ASSERT_TRUE(b[0].status.ok()) << b[0].status;
  // A's stroke in service holds seqs 1-3: B's comes right after it, not after A's other 49.
  EXPECT_EQ(b[0].global_seq_first, 4u) << "B's stroke waited for more than A's stroke in service";
  EXPECT_GE(scene_->task_stats().passed_over.load(), 1u);
}

TEST_F(SceneFairnessTest, EachSessionsStrokesKeepTheirOrderBesideOthers) {
  Press(1, 11, 1);
  entered_.get_future().wait();
  // Three sessions interleaved, each with its own client id.
  for (uint64_t seq = 2; seq <= 12; ++seq) {
    Press(1, 11, seq);
    Press(2, 22, seq);
    Press(3, 33, seq);
  }
  release_.set_value();
  scene_->Flush();
  for (uint64_t client : {11u, 22u, 33u}) {
    std::vector<StrokeOutcome> out = Outcomes(client);
    ASSERT_EQ(out.size(), client == 11 ? 12u : 11u);
    // Answered in the order applied; the client sequences must be in posting order too.
    std::sort(out.begin(), out.end(), [](const StrokeOutcome& x, const StrokeOutcome& y) {
      return x.global_seq_first < y.global_seq_first;
    });
    for (size_t i = 1; i < out.size(); ++i) {
      EXPECT_EQ(out[i].client_seq, out[i - 1].client_seq + 1)
          << "client " << client << "'s strokes were reordered";
      EXPECT_FALSE(out[i].duplicate);
    }
  }
}

TEST_F(SceneFairnessTest, TheScenesOwnWorkSeesEveryJobPostedBeforeItAndNoneAfter) {
  Press(1, 11, 1);
  entered_.get_future().wait();
  for (uint64_t seq = 2; seq <= 5; ++seq) Press(1, 11, seq);
  // Inspect is the scene's own work, posted after A's five strokes and before B's.
  std::promise<uint64_t> seen;
  std::thread inspector([&] {
    EXPECT_TRUE(scene_->Inspect("clay", [&](const levelset::Sculpture&) {
      seen.set_value(scene_->global_seq());
    }));
  });
  while (scene_->compute_queue_depth() < 5) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  Press(2, 22, 1);
  release_.set_value();
  EXPECT_EQ(seen.get_future().get(), 15u) << "Inspect ran before A's strokes or after B's";
  inspector.join();
  scene_->Flush();
  ASSERT_EQ(Outcomes(22).size(), 1u);
  EXPECT_EQ(Outcomes(22)[0].global_seq_first, 16u);
}

TEST_F(SceneFairnessTest, WorkOutsideASessionIsTheScenesOwn) {
  EXPECT_EQ(Scene::CurrentRequester(), 0u);
  {
    const Scene::RequesterScope outer(7);
    EXPECT_EQ(Scene::CurrentRequester(), 7u);
    {
      const Scene::RequesterScope inner(9);
      EXPECT_EQ(Scene::CurrentRequester(), 9u);
    }
    EXPECT_EQ(Scene::CurrentRequester(), 7u);
  }
  EXPECT_EQ(Scene::CurrentRequester(), 0u);
}

// A late join's serialisation shares the core with the edits at a lower priority (nice 10, or
// further back when the whole test runs under `nice`), so a flood of joins slows the joins.
TEST_F(SceneFairnessTest, LateJoinsAreSerialisedOnAThreadThatYieldsTheCoreToEdits) {
  const int process_nice = ThreadNice();
  std::promise<int> worker_nice;
  scene_->RequestJoinState([&worker_nice](StatusOr<JoinState> js) {
    EXPECT_TRUE(js.ok()) << js.status();
    worker_nice.set_value(ThreadNice());
  });
  auto answered = worker_nice.get_future();
  ASSERT_EQ(answered.wait_for(std::chrono::seconds(30)), std::future_status::ready);
  EXPECT_EQ(answered.get(), std::max(process_nice, 10));
  EXPECT_EQ(ThreadNice(), process_nice);
}

}  // namespace
}  // namespace sculpt::server
