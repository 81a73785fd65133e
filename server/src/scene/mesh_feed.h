/// @brief MeshFeed: the viewers' Draco mesh chunks (issue 4): viewers and dirty chunks on the
/// scene's compute thread, re-meshed and encoded on the feed's own mesher thread.
#ifndef SCULPT_SERVER_SCENE_MESH_FEED_H_
#define SCULPT_SERVER_SCENE_MESH_FEED_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "scene/replica_sink.h"
#include "sculpt/codec/replica_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/draco_chunk_codec.h"

namespace sculpt::server {

/// The mesh chunks of a scene's objects for viewers. A viewer of an object gets every chunk
/// holding surface (what is cached at once, the rest as it is encoded), then the chunks edits
/// change, at most once per period (the shortest any viewer asked for), several edits coalesced
/// into one update. When the source lists its objects, Start first meshes each object's surface
/// chunks once into the cache (the warm-up), so the first viewer after a restart is sent cached
/// chunks instead of waiting for a full mesh on a core sculptors' edits hold; from then on the
/// chunks edits change are tracked even while nobody watches and re-meshed when a viewer next
/// subscribes. Otherwise nothing is meshed while no viewer is subscribed. A chunk that fails or
/// throws is skipped (counted) and the thread meshes on.
/// Thread safety: AddViewer, RemoveViewer and MarkDirty run on the scene's compute thread (as
/// the tasks `Source::post` runs do); the cache of encoded chunks belongs to the mesher thread;
/// Start, Stop, stats() and InjectFaultForTesting may be called from any thread. Sinks are
/// called on the mesher thread (and helpers it starts for a new viewer) and must only post.
class MeshFeed {
 public:
  struct Options {
    mesh::ChunkMeshOptions chunk;
    /// Cap on a viewer's rate (scene.mesh_max_rate_hz); a viewer asking for none gets
    /// min(10, cap).
    double max_rate_hz = 30;
    /// An object's quantisation frame reaches this many voxels beyond its bounds, so every
    /// edit the bounds margin allows quantises identically across chunk seams.
    double frame_pad_voxels = 0;
    int position_bits = 14;
    int speed = 5;
    /// The mesher threads' nice value, at least (a process already further back stays so):
    /// viewers' meshes yield the core to sculptors' edits where both compete for it.
    int nice = 10;
    /// The warm-up threads' nice value, at least: the warm-up only prefetches, so it takes what
    /// sculptors' edits, joins and viewers' meshes leave of a contended core.
    int warm_nice = 19;
  };
  /// What the feed needs of its scene.
  struct Source {
    /// Runs `run` on the compute thread between two edits, ahead of queued edits; `fail` gets
    /// the error if `run` threw.
    std::function<void(std::function<void()> run, std::function<void(const Status&)> fail)> post;
    /// The object named, or null; called only inside tasks `post` runs.
    std::function<const levelset::Sculpture*(const std::string&)> find;
    /// The global sequence the objects hold; called only inside tasks `post` runs.
    std::function<uint64_t()> seq;
    /// Called on the mesher thread when encoding a chunk threw (may be null).
    std::function<void()> on_failure;
    /// The names of the objects whose chunks Start warms; called only inside tasks `post` runs.
    /// Null: no warm-up, nothing meshed before the first viewer.
    std::function<std::vector<std::string>()> objects;
  };
  struct Stats {
    std::atomic<uint64_t> chunks_encoded{0};  // for viewers' updates (the warm-up's apart)
    std::atomic<uint64_t> chunk_bytes{0};
    std::atomic<uint64_t> updates{0};
    std::atomic<uint64_t> snapshot_us{0};  // compute-thread time spent copying for the mesher
    std::atomic<uint64_t> warm_chunks{0};  // chunks the warm-up encoded
    std::atomic<bool> warmed{false};       // the warm-up has ended (done, failed or stopped)
  };

  MeshFeed(Options options, Source source);
  /// Stops the mesher thread (Stop).
  ~MeshFeed();
  MeshFeed(const MeshFeed&) = delete;
  MeshFeed& operator=(const MeshFeed&) = delete;

  /// Starts the mesher thread (once); it warms the cache first when the source lists objects.
  void Start();
  /// Stops and joins the mesher thread; an update in progress ends after its current chunk
  /// batch, a copy not yet taken is abandoned. Idempotent. Call before the compute thread
  /// stops: the mesher waits on tasks it posted there.
  void Stop();

  /// Registers `sink` as a viewer of request.object (`sculpture`, null when the scene has no
  /// such object), replacing the session's earlier viewer. NotFound naming
  /// ViewerSubscribe.object; the quantisation frame's error when the object is too large to
  /// quantise. Compute thread.
  Status AddViewer(ReplicaSink sink, const codec::ViewerSubscription& request,
                   const levelset::Sculpture* sculpture);
  /// Forgets the session's viewer (none: nothing happens). Compute thread.
  void RemoveViewer(uint64_t session_id);
  /// Marks the chunks holding `leaves` of `object` for the next update; nothing while no viewer
  /// is subscribed and the cache holds nothing of `object`. Compute thread.
  void MarkDirty(const std::string& object, const std::vector<levelset::Int3>& leaves);

  Stats& stats() { return stats_; }
  /// Tests only: `hook("mesh chunk")` runs before each chunk encode; a throw fails that chunk as
  /// an exception from OpenVDB or Draco would. Null removes it.
  void InjectFaultForTesting(std::function<void(const std::string&)> hook);

 private:
  struct Viewer {
    ReplicaSink sink;
    std::string object;
    double period_s = 0.1;
    bool needs_full = true;
  };
  struct Work;
  void Loop();
  // Meshes every surface chunk of the source's objects into the cache (mesher thread).
  void Warm();
  // The dirty sets and a copy of each watched object (compute thread).
  std::vector<Work> TakeWork();
  // A copy of every object for the warm-up, their dirty sets cleared (compute thread).
  std::vector<Work> TakeWarmWork();
  // The object's frame, made on first use (compute thread).
  StatusOr<mesh::QuantizationFrame> FrameOf(const std::string& object,
                                            const levelset::Sculpture& sculpture);
  void Mesh(Work& w);
  bool stopping() const { return stop_.load(std::memory_order_relaxed); }

  const Options options_;
  const Source source_;
  Stats stats_;
  // Compute thread only.
  std::map<uint64_t, Viewer> viewers_;
  std::map<std::string, std::set<mesh::ChunkKey>> dirty_;
  std::map<std::string, mesh::QuantizationFrame> frames_;
  // Objects the mesher's cache holds chunks of: their edits are tracked with no viewer.
  std::set<std::string> cached_objects_;
  // Mesher thread only.
  std::map<std::string, std::map<mesh::ChunkKey, std::shared_ptr<const std::string>>> cache_;
  // Read by the mesher between updates, written on the compute thread.
  std::atomic<int> viewer_count_{0};
  std::atomic<double> period_s_{0.1};
  std::mutex mu_;
  std::condition_variable cv_;
  // Set under mu_ (the waits below test it); read without the lock between chunks.
  std::atomic<bool> stop_{false};
  bool woken_ = false;  // guarded by mu_: a new viewer, take work without waiting a period
  std::function<void(const std::string&)> fault_;  // guarded by mu_
  std::thread thread_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_MESH_FEED_H_
