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
  bool warm = false;  // mesh every missing chunk into the cache, with or without viewers
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
  if (auto frame = FrameOf(req.object, *sculpture); !frame.ok()) return frame.status();
  Viewer v;
  v.sink = std::move(sink);
  v.object = req.object;
  v.period_s = 1.0 / rate;
  viewers_[v.sink.session_id] = std::move(v);
  double period = 10;
  for (const auto& [id, viewer] : viewers_) period = std::min(period, viewer.period_s);
  period_s_ = period;
  viewer_count_ = static_cast<int>(viewers_.size());
  {
    std::lock_guard<std::mutex> lock(mu_);
    woken_ = true;  // a new viewer is sent the cache at once, not a period later
  }
  cv_.notify_all();
  return Status::Ok();
}

StatusOr<mesh::QuantizationFrame> MeshFeed::FrameOf(const std::string& object,
                                                    const levelset::Sculpture& sculpture) {
  auto it = frames_.find(object);
  if (it != frames_.end()) return it->second;
  // One quantisation frame per object for as long as the server runs, wide enough for every
  // edit the bounds margin allows, so chunk seams quantise identically.
  auto frame = mesh::FrameAround(sculpture, options_.frame_pad_voxels);
  if (!frame.ok()) return frame.status();
  frames_[object] = *frame;
  return *frame;
}

void MeshFeed::RemoveViewer(uint64_t session_id) {
  viewers_.erase(session_id);
  viewer_count_ = static_cast<int>(viewers_.size());
  if (viewers_.empty()) {
    // No meshing while nobody watches; the dirty chunks of cached objects stay marked so the
    // cache is brought up to date for the next viewer.
    for (auto it = dirty_.begin(); it != dirty_.end();) {
      it = cached_objects_.count(it->first) ? std::next(it) : dirty_.erase(it);
    }
  }
}

void MeshFeed::MarkDirty(const std::string& object, const std::vector<levelset::Int3>& leaves) {
  if (viewers_.empty() && !cached_objects_.count(object)) return;
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
    if (source_.objects) cached_objects_.insert(name);  // the cache outlives its viewers
    out.push_back(std::move(w));
  }
  stats_.snapshot_us += static_cast<uint64_t>(Micros(Clock::now() - t0));
  return out;
}

std::vector<MeshFeed::Work> MeshFeed::TakeWarmWork() {
  const auto t0 = Clock::now();
  std::vector<Work> out;
  for (const std::string& name : source_.objects()) {
    const levelset::Sculpture* sculpture = source_.find(name);
    if (!sculpture) continue;
    auto frame = FrameOf(name, *sculpture);
    if (!frame.ok()) {
      spdlog::warn("mesher: {} not warmed: {}", name, frame.status().ToString());
      continue;
    }
    Work w;
    w.object = name;
    w.warm = true;
    w.copy = std::make_shared<const levelset::Sculpture>(sculpture->Clone());
    w.version = source_.seq();
    w.frame = *frame;
    // Edits from here on are marked dirty for the next viewer's first update.
    dirty_.erase(name);
    cached_objects_.insert(name);
    out.push_back(std::move(w));
  }
  stats_.snapshot_us += static_cast<uint64_t>(Micros(Clock::now() - t0));
  return out;
}

void MeshFeed::Warm() {
  const auto t0 = Clock::now();
  auto work = std::make_shared<std::promise<std::vector<Work>>>();
  auto fut = work->get_future();
  source_.post([this, work] { work->set_value(TakeWarmWork()); },
               [work](const Status& s) {
                 spdlog::warn("mesher: warm-up not taken: {}", s.ToString());
                 work->set_value({});
               });
  while (fut.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
    if (stopping()) return;
  }
  std::vector<Work> jobs = fut.get();
  const double wait_ms = Micros(Clock::now() - t0) / 1000;
  for (Work& w : jobs) {
    if (stopping() || viewer_count_.load() > 0) break;
    Mesh(w);
  }
  if (jobs.empty() || stopping()) return;
  spdlog::info("mesher: cache {}, {} chunks of {} object(s) in {:.0f} ms ({:.0f} ms to copy)",
               viewer_count_.load() > 0 ? "warm-up cut short by a viewer" : "warmed",
               stats_.warm_chunks.load(), jobs.size(), Micros(Clock::now() - t0) / 1000, wait_ms);
}

void MeshFeed::Loop() {
  RunInBackground(options_.nice);
  if (source_.objects) Warm();
  stats_.warmed = true;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      const auto period = std::chrono::duration<double>(period_s_.load());
      cv_.wait_for(lock, std::chrono::duration_cast<Clock::duration>(period),
                   [&] { return stop_ || woken_; });
      woken_ = false;
      if (stop_) return;
      if (viewer_count_.load() == 0) {
        // A cache that edits keep marked dirty stays; without a warm-up it is dropped.
        if (!source_.objects) cache_.clear();
        cv_.wait(lock, [&] { return stop_ || viewer_count_.load() > 0; });
        woken_ = false;
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
    if (w.warm) {
      stats_.warm_chunks++;
    } else {
      stats_.chunks_encoded++;
      stats_.chunk_bytes += f->size();
    }
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
  // New viewers get everything cached at once, before anything is meshed (after a warm-up that
  // is the whole object): a chunk edited since it was cached shows its older mesh until its new
  // one follows below with the other viewers', rather than a hole while the mesher, behind
  // sculptors' edits, gets to it.
  for (const ReplicaSink& s : w.full) {
    for (const auto& [key, f] : cache) s.send(f);
  }
  // Changed chunks go to every viewer; an emptied chunk is sent once (empty bytes) so
  // viewers drop it, then forgotten. With a new viewer, chunks it holds nothing of yet (the
  // surface edits moved into new chunks) come first: they are holes, the others show an older
  // mesh meanwhile.
  if (!w.full.empty()) {
    std::stable_partition(w.dirty.begin(), w.dirty.end(),
                          [&](const mesh::ChunkKey& key) { return !cache.count(key); });
  }
  for (const mesh::ChunkKey& key : w.dirty) {
    if (stopping()) return;
    auto f = encode(key);
    if (!f) continue;
    for (const ReplicaSink& s : w.all) s.send(f);
    cache[key] = f;
  }
  if (!w.full.empty() || w.warm) {
    // Every chunk not cached yet goes to the new viewers as soon as it is encoded (not after
    // the last one): the first pieces of a large object show while the rest is meshed. Missing
    // chunks are meshed on up to hardware_concurrency threads, each reading the same immutable
    // copy.
    std::vector<mesh::ChunkKey> missing;
    for (const mesh::ChunkKey& key : mesh::AllChunks(*w.copy, mo)) {
      if (!cache.count(key)) missing.push_back(key);
    }
    std::mutex cache_mu;
    std::atomic<size_t> next{0};
    auto worker = [&] {
      RunInBackground(w.warm ? options_.warm_nice : options_.nice);
      // A warm-up gives way to a viewer that subscribes meanwhile: its first update sends what
      // is cached and meshes the rest for it, chunk by chunk.
      auto cut = [&] { return stopping() || (w.warm && viewer_count_.load() > 0); };
      for (size_t i; !cut() && (i = next.fetch_add(1)) < missing.size();) {
        auto f = encode(missing[i]);
        if (!f) continue;
        for (const ReplicaSink& s : w.full) s.send(f);
        std::lock_guard<std::mutex> lock(cache_mu);
        cache[missing[i]] = f;
      }
    };
    const size_t threads = std::clamp<size_t>(std::thread::hardware_concurrency(), 1, 4);
    // The warm-up runs on helpers only: the mesher thread keeps its nice value for viewers.
    std::vector<std::thread> helpers;
    for (size_t t = w.warm ? 0 : 1; t < std::min(threads, missing.size()); ++t) {
      helpers.emplace_back(worker);
    }
    if (!w.warm) worker();
    for (std::thread& t : helpers) t.join();
  }
  if (!w.warm) stats_.updates++;
}

}  // namespace sculpt::server
