/// @brief MeshFeed: dirty chunks tracked on the compute thread while a viewer is subscribed,
/// re-meshed and Draco-encoded on the mesher thread from a copy of the object, at most at the
/// viewers' rate, several edits coalesced into one update.
#include "scene/mesh_feed.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <future>
#include <utility>

#include "sculpt/codec/replica_frames.h"
#include "sculpt/core/thread_priority.h"
#include "sculpt/mesh/vertex_colours.h"

namespace sculpt::server {
namespace {

using Clock = std::chrono::steady_clock;

double Micros(Clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

// Meshing for viewers is background work: where it competes with the compute thread for a
// core, the kernel's scheduler gives the edits the larger share.
void RunInBackground(int nice) {
  const Status s = LowerThreadPriority(nice);
  if (!s.ok()) spdlog::warn("mesher: nice {} not applied: {}", nice, s.message());
}

}  // namespace

// One update's work for one object, taken on the compute thread.
struct MeshFeed::Work {
  std::string object;
  std::shared_ptr<const levelset::Sculpture> copy;
  uint64_t version = 0;
  std::vector<mesh::ChunkKey> dirty;
  std::vector<ReplicaSink> all;   // every viewer of the object
  std::vector<ReplicaSink> full;  // viewers that need every chunk (new ones)
  mesh::QuantizationFrame frame;
};

MeshFeed::MeshFeed(Options options, Source source)
    : options_(std::move(options)), source_(std::move(source)) {}

MeshFeed::~MeshFeed() { Stop(); }

void MeshFeed::Start() {
  std::lock_guard<std::mutex> lock(mu_);
  if (thread_.joinable() || stop_) return;
  thread_ = std::thread([this] { Loop(); });
}

void MeshFeed::Stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void MeshFeed::InjectFaultForTesting(std::function<void(const std::string&)> hook) {
  std::lock_guard<std::mutex> lock(mu_);
  fault_ = std::move(hook);
}

Status MeshFeed::AddViewer(ReplicaSink sink, const codec::ViewerSubscription& req,
                           const levelset::Sculpture* sculpture) {
  if (!sculpture) {
    return Outside("ViewerSubscribe.object", req.object, "the scene's objects",
                   Status::Code::kNotFound);
  }
  // The decoder checked a requested rate; the default and the cap are the scene's.
  const double max_rate = options_.max_rate_hz;
  double rate = req.max_rate_hz;
  if (rate == 0) rate = std::min(10.0, max_rate);
  rate = std::min(rate, max_rate);
  if (!frames_.count(req.object)) {
    // One quantisation frame per object for as long as the server runs, wide enough for
    // every edit the bounds margin allows, so chunk seams quantise identically.
    auto frame = mesh::FrameAround(*sculpture, options_.frame_pad_voxels);
    if (!frame.ok()) return frame.status();
    frames_[req.object] = *frame;
  }
  Viewer v;
  v.sink = std::move(sink);
  v.object = req.object;
  v.period_s = 1.0 / rate;
  viewers_[v.sink.session_id] = std::move(v);
  double period = 10;
  for (const auto& [id, viewer] : viewers_) period = std::min(period, viewer.period_s);
  period_s_ = period;
  viewer_count_ = static_cast<int>(viewers_.size());
  cv_.notify_all();
  return Status::Ok();
}

void MeshFeed::RemoveViewer(uint64_t session_id) {
  viewers_.erase(session_id);
  viewer_count_ = static_cast<int>(viewers_.size());
  if (viewers_.empty()) dirty_.clear();  // no meshing while nobody watches
}

void MeshFeed::MarkDirty(const std::string& object, const std::vector<levelset::Int3>& leaves) {
  if (viewers_.empty()) return;
  std::set<mesh::ChunkKey>& d = dirty_[object];
  for (const mesh::ChunkKey& k : mesh::ChunksTouchedBy(leaves, options_.chunk)) d.insert(k);
}

std::vector<MeshFeed::Work> MeshFeed::TakeWork() {
  const auto t0 = Clock::now();
  std::map<std::string, Work> by_object;
  for (auto& [id, v] : viewers_) {
    Work& w = by_object[v.object];
    w.object = v.object;
    w.all.push_back(v.sink);
    if (v.needs_full) {
      w.full.push_back(v.sink);
      v.needs_full = false;
    }
  }
  std::vector<Work> out;
  for (auto& [name, w] : by_object) {
    auto d = dirty_.find(name);
    if (d != dirty_.end()) {
      w.dirty.assign(d->second.begin(), d->second.end());
      dirty_.erase(d);
    }
    if (w.dirty.empty() && w.full.empty()) continue;
    const levelset::Sculpture* sculpture = source_.find(name);
    if (!sculpture) continue;
    w.copy = std::make_shared<const levelset::Sculpture>(sculpture->Clone());
    w.version = source_.seq();
    w.frame = frames_.at(name);
    out.push_back(std::move(w));
  }
  stats_.snapshot_us += static_cast<uint64_t>(Micros(Clock::now() - t0));
  return out;
}

void MeshFeed::Loop() {
  RunInBackground(options_.nice);
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      const auto period = std::chrono::duration<double>(period_s_.load());
      cv_.wait_for(lock, std::chrono::duration_cast<Clock::duration>(period),
                   [&] { return stop_; });
      if (stop_) return;
      if (viewer_count_.load() == 0) {
        cache_.clear();
        cv_.wait(lock, [&] { return stop_ || viewer_count_.load() > 0; });
        if (stop_) return;
      }
    }
    // Take the work between two edits: the dirty sets and a copy of each watched object.
    auto work = std::make_shared<std::promise<std::vector<Work>>>();
    auto fut = work->get_future();
    source_.post([this, work] { work->set_value(TakeWork()); },
                 [work](const Status&) { work->set_value({}); });
    // Wait for the compute thread, but leave at once on shutdown.
    while (fut.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
      std::lock_guard<std::mutex> lock(mu_);
      if (stop_) return;
    }
    std::vector<Work> jobs = fut.get();
    for (Work& w : jobs) Mesh(w);
  }
}

void MeshFeed::Mesh(Work& w) {
  std::function<void(const std::string&)> hook;  // tests only
  {
    std::lock_guard<std::mutex> lock(mu_);
    hook = fault_;
  }
  const mesh::ChunkMeshOptions& mo = options_.chunk;
  mesh::DracoChunkOptions dopt;
  dopt.position_bits = options_.position_bits;
  dopt.speed = options_.speed;
  dopt.frame = w.frame;
  auto& cache = cache_[w.object];
  auto encode_chunk = [&](const mesh::ChunkKey& key) -> std::shared_ptr<const std::string> {
    const auto t0 = Clock::now();
    auto m = mesh::MeshChunk(*w.copy, key, mo);
    if (!m.ok()) {
      spdlog::warn("mesh chunk ({},{},{}): {}", key.x, key.y, key.z, m.status().ToString());
      return nullptr;
    }
    codec::MeshChunkFrame c;
    c.object = w.object;
    c.key[0] = key.x;
    c.key[1] = key.y;
    c.key[2] = key.z;
    c.version = w.version;
    c.chunk_voxels = static_cast<uint32_t>(mo.chunk_voxels);
    if (!m->mesh.empty()) {
      // A scene with materials: each vertex's colour mixed from the fractions there.
      if (const Status cs = mesh::ColourVertices(*w.copy, &m->mesh); !cs.ok()) {
        spdlog::warn("chunk colours ({},{},{}): {}", key.x, key.y, key.z, cs.ToString());
      }
      auto e = mesh::EncodeChunk(m->mesh, dopt);
      if (!e.ok()) {
        spdlog::warn("draco chunk ({},{},{}): {}", key.x, key.y, key.z, e.status().ToString());
        return nullptr;
      }
      c.draco = std::move(e->bytes);
      c.vertices = e->vertices;
      c.faces = e->faces;
    }
    c.encode_ms =
        static_cast<float>(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    codec::SharedFrame f = codec::EncodeMeshChunk(std::move(c));
    stats_.chunks_encoded++;
    stats_.chunk_bytes += f->size();
    return f;
  };
  // The mesher's exception boundary (OpenVDB and Draco may throw): a chunk that throws is
  // skipped like one that fails to mesh, and the thread keeps meshing.
  auto encode = [&](const mesh::ChunkKey& key) -> std::shared_ptr<const std::string> {
    std::string what;
    try {
      if (hook) hook("mesh chunk");
      return encode_chunk(key);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
      what = "an exception of unknown type";
    }
    if (source_.on_failure) source_.on_failure();
    spdlog::error("mesher: chunk ({},{},{}) of {} threw: {}; skipped", key.x, key.y, key.z,
                  w.object, what);
    return nullptr;
  };
  // Changed chunks go to every viewer; an emptied chunk is sent once (empty bytes) so
  // viewers drop it, then forgotten.
  for (const mesh::ChunkKey& key : w.dirty) {
    auto f = encode(key);
    if (!f) continue;
    for (const ReplicaSink& s : w.all) s.send(f);
    cache[key] = f;
  }
  if (!w.full.empty()) {
    // New viewers get what is cached at once, then every missing chunk as soon as it is
    // encoded (not after the last one): the first pieces of a large object show while the
    // rest is meshed. Missing chunks are meshed on up to hardware_concurrency threads, each
    // reading the same immutable copy.
    const bool dirty_sent_to_new = !w.dirty.empty();
    for (const ReplicaSink& s : w.full) {
      for (const auto& [key, f] : cache) {
        // New viewers already got this update's dirty chunks above.
        if (dirty_sent_to_new && std::binary_search(w.dirty.begin(), w.dirty.end(), key)) {
          continue;
        }
        s.send(f);
      }
    }
    std::vector<mesh::ChunkKey> missing;
    for (const mesh::ChunkKey& key : mesh::AllChunks(*w.copy, mo)) {
      if (!cache.count(key)) missing.push_back(key);
    }
    std::mutex cache_mu;
    std::atomic<size_t> next{0};
    auto worker = [&] {
      RunInBackground(options_.nice);
      for (size_t i; (i = next.fetch_add(1)) < missing.size();) {
        auto f = encode(missing[i]);
        if (!f) continue;
        for (const ReplicaSink& s : w.full) s.send(f);
        std::lock_guard<std::mutex> lock(cache_mu);
        cache[missing[i]] = f;
      }
    };
    const size_t threads = std::clamp<size_t>(std::thread::hardware_concurrency(), 1, 4);
    std::vector<std::thread> helpers;
    for (size_t t = 1; t < std::min(threads, missing.size()); ++t) helpers.emplace_back(worker);
    worker();
    for (std::thread& t : helpers) t.join();
  }
  stats_.updates++;
}

}  // namespace sculpt::server
