/// @brief Viewers' mesh chunks (issue 4): dirty chunks tracked on the compute thread while a
/// viewer is subscribed, re-meshed and Draco-encoded on the mesher thread from a copy of the
/// object, at most at the viewers' rate, several edits coalesced into one update.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <exception>
#include <future>

#include "scene/answer_once.h"
#include "scene/scene.h"
#include "sculpt/codec/frame.h"
#include "sculpt/core/check.h"
#include "sculpt/mesh/vertex_colours.h"

namespace sculpt::server {
namespace {

using Clock = std::chrono::steady_clock;

double Micros(Clock::duration d) {
  return std::chrono::duration<double, std::micro>(d).count();
}

}  // namespace

// One update's work for one object, taken on the compute thread.
struct Scene::MeshWork {
  std::string object;
  std::shared_ptr<const levelset::Sculpture> copy;
  uint64_t version = 0;
  std::vector<mesh::ChunkKey> dirty;
  std::vector<ReplicaSink> all;   // every viewer of the object
  std::vector<ReplicaSink> full;  // viewers that need every chunk (new ones)
  mesh::QuantizationFrame frame;
};

void Scene::SubscribeViewer(ReplicaSink sink, codec::ViewerSubscription req,
                            std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto cb = std::make_shared<std::function<void(Status)>>(once);
  auto fail = [once](const Status& st) { once(st); };
  const uint64_t who = CurrentRequester();
  Post(who, "viewer", fail, [this, sink = std::move(sink), req = std::move(req), cb]() mutable {
    auto it = sculptures_.find(req.object);
    if (it == sculptures_.end()) {
      return (*cb)(Outside("ViewerSubscribe.object", req.object, "the scene's objects",
                           Status::Code::kNotFound));
    }
    // The decoder checked a requested rate; the default and the cap are the scene's.
    const double max_rate = config_.scene.mesh_max_rate_hz;
    double rate = req.max_rate_hz;
    if (rate == 0) rate = std::min(10.0, max_rate);
    rate = std::min(rate, max_rate);
    if (!mesh_frames_.count(req.object)) {
      // One quantisation frame per object for as long as the server runs, wide enough for
      // every edit the bounds margin allows, so chunk seams quantise identically.
      const double dx = config_.scene.voxel_size;
      const double pad =
          (config_.scene.bounds_margin + 2 * config_.scene.max_tool_size) / dx + 2 * config_.scene.half_width;
      auto frame = mesh::FrameAround(it->second, pad);
      if (!frame.ok()) return (*cb)(frame.status());
      mesh_frames_[req.object] = *frame;
    }
    Viewer v;
    v.sink = std::move(sink);
    v.object = req.object;
    v.period_s = 1.0 / rate;
    (*cb)(Status::Ok());
    viewers_[v.sink.session_id] = std::move(v);
    double period = 10;
    for (const auto& [id, viewer] : viewers_) period = std::min(period, viewer.period_s);
    mesh_period_s_ = period;
    viewer_count_ = static_cast<int>(viewers_.size());
    mesher_cv_.notify_all();
  });
}

void Scene::UnsubscribeViewer(uint64_t session_id) {
  Post(CurrentRequester(), "viewer unsubscribe", [this, session_id] {
    viewers_.erase(session_id);
    viewer_count_ = static_cast<int>(viewers_.size());
    if (viewers_.empty()) dirty_chunks_.clear();  // no meshing while nobody watches
  });
}

bool Scene::Inspect(const std::string& object,
                    const std::function<void(const levelset::Sculpture&)>& fn) {
  std::promise<bool> p;
  auto fail = [&p](const Status&) { p.set_value(false); };
  Post("inspect", fail, [&] {
    auto it = sculptures_.find(object);
    if (it != sculptures_.end()) fn(it->second);
    p.set_value(it != sculptures_.end());
  });
  return p.get_future().get();
}

void Scene::MarkDirtyChunks(const std::string& object, const std::vector<levelset::Int3>& leaves) {
  mesh::ChunkMeshOptions o;
  o.chunk_voxels = config_.scene.mesh_chunk_voxels;
  std::set<mesh::ChunkKey>& d = dirty_chunks_[object];
  for (const mesh::ChunkKey& k : mesh::ChunksTouchedBy(leaves, o)) d.insert(k);
}

void Scene::MesherLoop() {
  mesh::ChunkMeshOptions mo;
  mo.chunk_voxels = config_.scene.mesh_chunk_voxels;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mesher_mu_);
      const auto period = std::chrono::duration<double>(mesh_period_s_.load());
      mesher_cv_.wait_for(lock, std::chrono::duration_cast<Clock::duration>(period), [&] {
        return mesher_stop_;
      });
      if (mesher_stop_) return;
      if (viewer_count_.load() == 0) {
        mesh_cache_.clear();
        mesher_cv_.wait(lock, [&] { return mesher_stop_ || viewer_count_.load() > 0; });
        if (mesher_stop_) return;
      }
    }
    // Take the work between two edits: the dirty sets and a copy of each watched object.
    auto work = std::make_shared<std::promise<std::vector<MeshWork>>>();
    auto fut = work->get_future();
    auto fail = [work](const Status&) { work->set_value({}); };
    PostFirst("mesh snapshot", fail, [this, work] {
      const auto t0 = Clock::now();
      std::map<std::string, MeshWork> by_object;
      for (auto& [id, v] : viewers_) {
        MeshWork& w = by_object[v.object];
        w.object = v.object;
        w.all.push_back(v.sink);
        if (v.needs_full) {
          w.full.push_back(v.sink);
          v.needs_full = false;
        }
      }
      std::vector<MeshWork> out;
      for (auto& [name, w] : by_object) {
        auto d = dirty_chunks_.find(name);
        if (d != dirty_chunks_.end()) {
          w.dirty.assign(d->second.begin(), d->second.end());
          dirty_chunks_.erase(d);
        }
        if (w.dirty.empty() && w.full.empty()) continue;
        w.copy = std::make_shared<const levelset::Sculpture>(sculptures_.at(name).Clone());
        w.version = applied_seq_.load();
        w.frame = mesh_frames_.at(name);
        out.push_back(std::move(w));
      }
      mesh_stats_.snapshot_us += static_cast<uint64_t>(Micros(Clock::now() - t0));
      work->set_value(std::move(out));
    });
    std::vector<MeshWork> jobs;
    {
      // Wait for the compute thread, but leave at once on shutdown.
      while (fut.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
        std::lock_guard<std::mutex> lock(mesher_mu_);
        if (mesher_stop_) return;
      }
      jobs = fut.get();
    }
    std::function<void(const std::string&)> hook;  // tests only
    {
      std::lock_guard<std::mutex> lock(jobs_mu_);
      if (fault_hook_) hook = fault_hook_;
    }
    mesh::DracoChunkOptions dopt;
    dopt.position_bits = config_.scene.mesh_position_bits;
    dopt.speed = config_.scene.mesh_speed;
    for (MeshWork& w : jobs) {
      dopt.frame = w.frame;
      auto& cache = mesh_cache_[w.object];
      auto encode_chunk = [&](const mesh::ChunkKey& key) -> std::shared_ptr<const std::string> {
        const auto t0 = Clock::now();
        auto m = mesh::MeshChunk(*w.copy, key, mo);
        if (!m.ok()) {
          spdlog::warn("mesh chunk ({},{},{}): {}", key.x, key.y, key.z, m.status().ToString());
          return nullptr;
        }
        v1::ServerMessage msg;
        v1::MeshChunk* c = msg.mutable_mesh_chunk();
        c->set_object(w.object);
        c->add_key(key.x);
        c->add_key(key.y);
        c->add_key(key.z);
        c->set_version(w.version);
        c->set_chunk_voxels(static_cast<uint32_t>(mo.chunk_voxels));
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
          c->set_draco(std::move(e->bytes));
          c->set_vertices(e->vertices);
          c->set_faces(e->faces);
        }
        c->set_encode_ms(static_cast<float>(
            std::chrono::duration<double, std::milli>(Clock::now() - t0).count()));
        auto f = std::make_shared<std::string>();
        codec::AppendMessage(msg, f.get());
        mesh_stats_.chunks_encoded++;
        mesh_stats_.chunk_bytes += f->size();
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
        task_stats_.failures++;
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
            if (dirty_sent_to_new &&
                std::binary_search(w.dirty.begin(), w.dirty.end(), key)) {
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
      mesh_stats_.updates++;
    }
  }
}

}  // namespace sculpt::server
