/// @brief Unit tests for MeshFeed against a small sculpture and a stand-in compute thread (a
/// mutex the feed's tasks and the test's edits share): what a viewer is sent, when, and what is
/// meshed again.
#include "scene/mesh_feed.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "sculpt/codec/frame.h"
#include "sculpt/core/thread_priority.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {
namespace {

using Key = std::tuple<int, int, int>;

// A viewer session's end: the MeshChunk frames it was sent, parsed.
class FakeViewer {
 public:
  explicit FakeViewer(uint64_t session_id) : session_id_(session_id) {}
  ReplicaSink sink() {
    ReplicaSink s;
    s.session_id = session_id_;
    s.send = [this](std::shared_ptr<const std::string> f) {
      std::lock_guard<std::mutex> lock(mu_);
      frames_.push_back(std::move(f));
    };
    return s;
  }
  size_t size() {
    std::lock_guard<std::mutex> lock(mu_);
    return frames_.size();
  }
  std::vector<std::shared_ptr<const std::string>> frames() {
    std::lock_guard<std::mutex> lock(mu_);
    return frames_;
  }
  // The chunks of frames [from, end): key -> how many times, and every version seen.
  std::map<Key, int> Keys(size_t from, std::set<uint64_t>* versions = nullptr) {
    std::map<Key, int> keys;
    const auto all = frames();
    for (size_t i = from; i < all.size(); ++i) {
      codec::FrameReader reader;
      reader.Feed(all[i]->data(), all[i]->size());
      auto payload = reader.Next();
      EXPECT_TRUE(payload.ok() && *payload);
      v1::ServerMessage m;
      EXPECT_TRUE(m.ParseFromString(**payload));
      EXPECT_TRUE(m.has_mesh_chunk());
      const v1::MeshChunk& c = m.mesh_chunk();
      EXPECT_EQ(c.key_size(), 3);
      if (c.key_size() != 3) continue;
      ++keys[{c.key(0), c.key(1), c.key(2)}];
      if (versions) versions->insert(c.version());
    }
    return keys;
  }
  // Every chunk's versions in the order they were sent.
  std::map<Key, std::vector<uint64_t>> Versions() {
    std::map<Key, std::vector<uint64_t>> out;
    for (const auto& f : frames()) {
      codec::FrameReader reader;
      reader.Feed(f->data(), f->size());
      auto payload = reader.Next();
      v1::ServerMessage m;
      EXPECT_TRUE(payload.ok() && *payload && m.ParseFromString(**payload));
      const v1::MeshChunk& c = m.mesh_chunk();
      if (c.key_size() == 3) out[{c.key(0), c.key(1), c.key(2)}].push_back(c.version());
    }
    return out;
  }

 private:
  uint64_t session_id_;
  std::mutex mu_;
  std::vector<std::shared_ptr<const std::string>> frames_;
};

// Polls `done` for up to 20 s (the machine may be busy compiling).
template <typename Fn>
bool WaitFor(Fn done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

levelset::Sculpture Sphere() {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  o.name = "clay";
  return std::move(levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 12)).value();
}

class MeshFeedTest : public ::testing::Test {
 protected:
  MeshFeedTest() {
    options_.chunk.chunk_voxels = 16;
    options_.max_rate_hz = 20;
    options_.frame_pad_voxels = 8;
  }
  ~MeshFeedTest() override {
    if (feed_) feed_->Stop();
  }

  // The feed with the stand-in compute thread: tasks run at once on the mesher's thread,
  // under compute_mu_ (unless `hold_tasks_`, which drops them as a compute thread that never
  // gets to them would).
  void MakeFeed() { MakeFeedWithHook(nullptr); }
  // As MakeFeed, with `hook` injected before the feed starts.
  void MakeFeedWithHook(std::function<void(const std::string&)> hook) {
    MeshFeed::Source source;
    source.post = [this](std::function<void()> run, std::function<void(const Status&)>) {
      std::lock_guard<std::mutex> lock(compute_mu_);
      ++posted_;
      if (hold_tasks_) return held_.push_back(std::move(run));
      run();
    };
    source.find = [this](const std::string& object) -> const levelset::Sculpture* {
      return object == "clay" ? &sculpture_ : nullptr;
    };
    source.seq = [this] { return seq_; };
    source.on_failure = [this] { ++failures_; };
    if (warm_) source.objects = [] { return std::vector<std::string>{"clay"}; };
    feed_ = std::make_unique<MeshFeed>(options_, std::move(source));
    if (hook) feed_->InjectFaultForTesting(std::move(hook));
    feed_->Start();
  }
  Status AddViewer(FakeViewer& v, double rate_hz = 20) {
    codec::ViewerSubscription req;
    req.object = "clay";
    req.max_rate_hz = rate_hz;
    std::lock_guard<std::mutex> lock(compute_mu_);
    return feed_->AddViewer(v.sink(), req, &sculpture_);
  }
  // Presses, one edit each, in one turn of the compute thread (the mesher takes work before or
  // after all of them), as the scene applies them: each edit's leaves marked dirty. Returns
  // every leaf they changed.
  std::vector<levelset::Int3> Edits(const std::vector<Vec3>& at) {
    std::lock_guard<std::mutex> lock(compute_mu_);
    std::vector<levelset::Int3> all;
    for (const Vec3& c : at) {
      levelset::EditRequest r;
      r.kind = levelset::EditKind::kPress;
      r.tool.kind = levelset::ToolKind::kSphere;
      r.tool.size = {3, 3, 3};
      r.tool.center = c;
      r.speed = 30;
      r.dt = 1.0 / 120;
      auto out = levelset::ApplyEdits(sculpture_, {r}, levelset::EditSettings{});
      EXPECT_TRUE(out.ok()) << out.status().ToString();
      if (!out.ok()) continue;
      EXPECT_FALSE(out->dirty_leaves.empty());
      ++seq_;
      feed_->MarkDirty("clay", out->dirty_leaves);
      all.insert(all.end(), out->dirty_leaves.begin(), out->dirty_leaves.end());
    }
    return all;
  }
  // A viewer that outlives the feed's thread (the fixture stops it first).
  FakeViewer& NewViewer(uint64_t session_id) {
    viewers_.push_back(std::make_unique<FakeViewer>(session_id));
    return *viewers_.back();
  }
  size_t SurfaceChunks() {
    std::lock_guard<std::mutex> lock(compute_mu_);
    return mesh::AllChunks(sculpture_, options_.chunk).size();
  }

  levelset::Sculpture sculpture_ = Sphere();
  MeshFeed::Options options_;
  std::vector<std::unique_ptr<FakeViewer>> viewers_;
  std::unique_ptr<MeshFeed> feed_;
  std::mutex compute_mu_;
  uint64_t seq_ = 0;         // guarded by compute_mu_
  bool hold_tasks_ = false;  // guarded by compute_mu_
  std::vector<std::function<void()>> held_;
  int posted_ = 0;  // guarded by compute_mu_
  std::atomic<int> failures_{0};
  bool warm_ = false;  // the source lists its objects: the feed warms its cache at Start
};

TEST_F(MeshFeedTest, ViewerGetsTheChunksOfDirtyLeavesOncePerPeriod) {
  MakeFeed();
  FakeViewer& v = NewViewer(1);
  ASSERT_TRUE(AddViewer(v).ok());
  const size_t surface = SurfaceChunks();
  ASSERT_GT(surface, 1u);
  ASSERT_TRUE(WaitFor([&] { return feed_->stats().updates.load() >= 1 && v.size() >= surface; }));
  const size_t first = v.size();
  EXPECT_EQ(first, surface);
  EXPECT_EQ(feed_->stats().updates.load(), 1u);

  // Two edits between two takes: one update, each chunk they touched sent once, at the newer
  // sequence; then nothing more without another edit.
  std::set<Key> touched;
  for (const mesh::ChunkKey& k :
       mesh::ChunksTouchedBy(Edits({{12, 0, 0}, {8.5, 8.5, 0}}), options_.chunk)) {
    touched.insert({k.x, k.y, k.z});
  }
  ASSERT_GT(touched.size(), 1u);
  ASSERT_TRUE(WaitFor([&] { return v.size() >= first + touched.size(); }));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // four more periods
  std::set<uint64_t> versions;
  const std::map<Key, int> sent = v.Keys(first, &versions);
  std::set<Key> sent_keys;
  for (const auto& [key, count] : sent) {
    sent_keys.insert(key);
    EXPECT_EQ(count, 1) << "chunk sent " << count << " times";
  }
  EXPECT_EQ(sent_keys, touched);
  EXPECT_EQ(versions, std::set<uint64_t>{2u});
  EXPECT_EQ(feed_->stats().updates.load(), 2u);
}

TEST_F(MeshFeedTest, CachedChunksAreSentToANewViewerWithoutMeshingAgain) {
  MakeFeed();
  FakeViewer& a = NewViewer(1);
  ASSERT_TRUE(AddViewer(a).ok());
  const size_t surface = SurfaceChunks();
  ASSERT_TRUE(WaitFor([&] { return a.size() >= surface; }));
  const uint64_t encoded = feed_->stats().chunks_encoded.load();
  EXPECT_EQ(encoded, surface);
  FakeViewer& b = NewViewer(2);
  ASSERT_TRUE(AddViewer(b).ok());
  ASSERT_TRUE(WaitFor([&] { return b.size() >= surface; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(b.size(), surface);
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), encoded);
  // The same bytes, not a copy.
  std::set<const std::string*> of_a;
  for (const auto& f : a.frames()) of_a.insert(f.get());
  for (const auto& f : b.frames()) EXPECT_TRUE(of_a.count(f.get()));
  EXPECT_EQ(a.size(), surface);  // the old viewer got nothing again
}

TEST_F(MeshFeedTest, ChunkThatThrowsIsSkippedCountedAndTheRestSent) {
  MakeFeed();
  // The hook owns its count: mesher threads may call it until teardown, after this body.
  auto throws = std::make_shared<std::atomic<int>>(1);
  feed_->InjectFaultForTesting([throws](const std::string& op) {
    if (op == "mesh chunk" && throws->fetch_sub(1) > 0) throw std::runtime_error("injected");
  });
  FakeViewer& v = NewViewer(1);
  ASSERT_TRUE(AddViewer(v).ok());
  const size_t surface = SurfaceChunks();
  ASSERT_TRUE(WaitFor([&] { return feed_->stats().updates.load() >= 1; }));
  EXPECT_EQ(v.size(), surface - 1);
  EXPECT_EQ(failures_.load(), 1);
}

TEST_F(MeshFeedTest, MesherThreadsYieldTheCoreToTheComputeThread) {
  // Every chunk is encoded, and sent, on a thread at the configured nice value (or further back
  // when the whole test runs under `nice`), while the test's own thread keeps its priority.
  const int process_nice = ThreadNice();
  options_.nice = 10;
  options_.chunk.chunk_voxels = 8;  // many chunks: a new viewer's are meshed by helper threads
  MakeFeed();
  std::mutex mu;
  std::set<int> seen;
  std::atomic<size_t> sent{0};
  ReplicaSink sink;
  sink.session_id = 1;
  sink.send = [&](std::shared_ptr<const std::string>) {
    std::lock_guard<std::mutex> lock(mu);
    seen.insert(ThreadNice());
    ++sent;
  };
  codec::ViewerSubscription req;
  req.object = "clay";
  {
    std::lock_guard<std::mutex> lock(compute_mu_);
    ASSERT_TRUE(feed_->AddViewer(sink, req, &sculpture_).ok());
  }
  const size_t surface = SurfaceChunks();
  ASSERT_GT(surface, 8u);
  ASSERT_TRUE(WaitFor([&] { return sent.load() >= surface; }));
  feed_->Stop();
  std::lock_guard<std::mutex> lock(mu);
  EXPECT_EQ(seen, std::set<int>{std::max(process_nice, 10)});
  EXPECT_EQ(ThreadNice(), process_nice);
}

TEST_F(MeshFeedTest, SleepsWithoutViewersAndRefusesUnknownObjects) {
  MakeFeed();
  Edits({{12, 0, 0}});
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), 0u);
  {
    std::lock_guard<std::mutex> lock(compute_mu_);
    EXPECT_EQ(posted_, 0);  // the mesher sleeps while nobody watches
  }
  FakeViewer& v = NewViewer(1);
  codec::ViewerSubscription req;
  req.object = "nope";
  const Status st = feed_->AddViewer(v.sink(), req, nullptr);
  EXPECT_EQ(st.code(), Status::Code::kNotFound);
  EXPECT_NE(st.message().find("ViewerSubscribe.object=nope"), std::string::npos);
}

TEST_F(MeshFeedTest, StopJoinsTheMesherEvenWhileItWaitsForTheComputeThread) {
  MakeFeed();
  {
    std::lock_guard<std::mutex> lock(compute_mu_);
    hold_tasks_ = true;  // the mesher's take never runs
  }
  FakeViewer& v = NewViewer(1);
  ASSERT_TRUE(AddViewer(v).ok());
  ASSERT_TRUE(WaitFor([&] {
    std::lock_guard<std::mutex> lock(compute_mu_);
    return !held_.empty();
  }));
  std::promise<void> stopped;
  std::thread stopper([&] {
    feed_->Stop();
    stopped.set_value();
  });
  if (stopped.get_future().wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
    ADD_FAILURE() << "Stop did not join the mesher";
    std::abort();  // a hung stop: fail loudly instead of blocking the suite
  }
  stopper.join();
  // Stopped: a take that runs now sends nothing, and nothing more is posted.
  int posted = 0;
  {
    std::lock_guard<std::mutex> lock(compute_mu_);
    for (auto& run : held_) run();
    held_.clear();
    posted = posted_;
  }
  Edits({{12, 0, 0}});
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_EQ(v.size(), 0u);
  std::lock_guard<std::mutex> lock(compute_mu_);
  EXPECT_EQ(posted_, posted);
  feed_->Stop();  // idempotent
}

TEST_F(MeshFeedTest, WarmUpCachesEveryChunkSoTheFirstViewerNeedsNoMeshing) {
  // As after a restart: the feed meshes the object before anyone watches; the first viewer is
  // sent the cached chunks and nothing is meshed for it.
  warm_ = true;
  const int process_nice = ThreadNice();
  options_.warm_nice = 19;
  // Created before Start, so the warm-up cannot outrun it; records each encoding thread's nice.
  auto nices = std::make_shared<std::pair<std::mutex, std::set<int>>>();
  MakeFeedWithHook([nices](const std::string& op) {
    if (op != "mesh chunk") return;
    std::lock_guard<std::mutex> lock(nices->first);
    nices->second.insert(ThreadNice());
  });
  const size_t surface = SurfaceChunks();
  ASSERT_GT(surface, 1u);
  ASSERT_TRUE(WaitFor([&] { return feed_->stats().warmed.load(); }));
  {
    // The warm-up yields to everything else: its threads run at warm_nice.
    std::lock_guard<std::mutex> lock(nices->first);
    EXPECT_EQ(nices->second, std::set<int>{std::max(process_nice, 19)});
  }
  EXPECT_EQ(ThreadNice(), process_nice);
  EXPECT_EQ(feed_->stats().warm_chunks.load(), surface);
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), 0u);
  EXPECT_EQ(feed_->stats().updates.load(), 0u);
  FakeViewer& v = NewViewer(1);
  ASSERT_TRUE(AddViewer(v).ok());
  ASSERT_TRUE(WaitFor([&] { return v.size() >= surface; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(150));  // three more periods
  EXPECT_EQ(v.size(), surface);
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), 0u);  // nothing meshed for the viewer
  std::set<Key> expected;
  {
    std::lock_guard<std::mutex> lock(compute_mu_);
    for (const mesh::ChunkKey& k : mesh::AllChunks(sculpture_, options_.chunk)) {
      expected.insert({k.x, k.y, k.z});
    }
  }
  std::set<Key> got;
  for (const auto& [key, count] : v.Keys(0)) {
    got.insert(key);
    EXPECT_EQ(count, 1);
  }
  EXPECT_EQ(got, expected);
}

TEST_F(MeshFeedTest, EditsWhileNobodyWatchesAreMeshedForTheNextViewerOnly) {
  // Edits after the warm-up leave their chunks dirty. The next viewer is sent the whole cache at
  // once (an edited chunk's older mesh included), then only the touched chunks meshed again, at
  // the edit's sequence.
  warm_ = true;
  {
    // A larger sphere: one press touches a few of its chunks.
    levelset::SculptureOptions o;
    o.voxel_size = 1.0;
    o.half_width = 4;
    o.name = "clay";
    sculpture_ = std::move(levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 40)).value();
  }
  MakeFeed();
  std::set<Key> cached;
  {
    std::lock_guard<std::mutex> lock(compute_mu_);
    for (const mesh::ChunkKey& k : mesh::AllChunks(sculpture_, options_.chunk)) {
      cached.insert({k.x, k.y, k.z});
    }
  }
  ASSERT_TRUE(WaitFor([&] { return feed_->stats().warmed.load(); }));
  ASSERT_EQ(feed_->stats().warm_chunks.load(), cached.size());
  std::set<Key> touched;
  for (const mesh::ChunkKey& k : mesh::ChunksTouchedBy(Edits({{40, 0, 0}}), options_.chunk)) {
    touched.insert({k.x, k.y, k.z});
  }
  ASSERT_FALSE(touched.empty());
  ASSERT_LT(touched.size(), cached.size());
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  // Nothing meshed while unwatched.
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), 0u);
  FakeViewer& v = NewViewer(1);
  ASSERT_TRUE(AddViewer(v).ok());
  ASSERT_TRUE(WaitFor([&] { return feed_->stats().updates.load() >= 1; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_EQ(feed_->stats().updates.load(), 1u);
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), touched.size());
  std::set<Key> expected = cached;
  expected.insert(touched.begin(), touched.end());
  std::set<Key> got;
  for (const auto& [key, versions] : v.Versions()) {
    got.insert(key);
    std::vector<uint64_t> want;
    if (cached.count(key)) want.push_back(0);  // the warm-up's, at once
    if (touched.count(key)) want.push_back(1);  // the edit's, meshed for this viewer
    EXPECT_EQ(versions, want);
  }
  EXPECT_EQ(got, expected);
  // The whole cache came first: what follows it is the touched chunks, meshed anew.
  std::set<uint64_t> late_versions;
  std::set<Key> late;
  for (const auto& [key, count] : v.Keys(cached.size(), &late_versions)) late.insert(key);
  EXPECT_EQ(late, touched);
  EXPECT_EQ(late_versions, std::set<uint64_t>{1u});
}

TEST_F(MeshFeedTest, WithoutObjectListNothingIsWarmed) {
  MakeFeed();
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_TRUE(feed_->stats().warmed.load());
  EXPECT_EQ(feed_->stats().warm_chunks.load(), 0u);
  EXPECT_EQ(feed_->stats().chunks_encoded.load(), 0u);
}

}  // namespace
}  // namespace sculpt::server
