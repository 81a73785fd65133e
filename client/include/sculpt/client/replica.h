/// @brief Replica: a client's copy of one object's narrow band (or a box of it), kept equal to
/// the server's by replaying the server's edits with the same kernel (issue 4), checked by leaf
/// hashes, with leaf records for loads, resyncs and interest moves.
#ifndef SCULPT_CLIENT_REPLICA_H_
#define SCULPT_CLIENT_REPLICA_H_

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "sculpt/client/client.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::client {

struct ReplicaOptions {
  std::string object = "clay";
  v1::ReplicaMode mode = v1::REPLICA_MODE_REPLAY;
  /// World box of interest; unset: the whole object.
  std::optional<levelset::Aabb> interest;
  /// Publish an immutable copy for readers (the haptic loop) at most this often; 0: never. An
  /// edit applied within the interval of the last copy is published once the interval ends.
  std::chrono::milliseconds snapshot_interval{0};
};

struct ReplicaStats {
  uint64_t broadcasts_applied = 0;
  uint64_t deltas_applied = 0;
  uint64_t region_loads = 0;
  uint64_t hash_mismatches = 0;
  uint64_t errors = 0;  // messages that failed to decode or apply
  uint64_t bytes = 0;       // per-edit payload bytes received (broadcasts, per-edit deltas)
  uint64_t load_bytes = 0;  // region loads (subscribe, resync, interest moves)
  uint64_t seq = 0;     // highest global sequence applied
  double apply_ms = 0;  // time spent applying
  uint64_t snapshots = 0;
};

/// What one applied message was, for latency accounting.
struct AppliedEdit {
  uint64_t client_id = 0;
  uint64_t client_seq = 0;
  uint64_t global_seq = 0;
  bool replayed = false;  // false: leaf delta
};

/// Attach to a Client created with ClientOptions::skip_state, after Join. Messages are applied on
/// the replica's own thread, never on the client's I/O thread. Thread safety: every method may be
/// called from any thread.
class Replica {
 public:
  using AppliedHandler = std::function<void(const AppliedEdit&)>;
  /// A published copy and the highest global sequence it holds.
  using SnapshotHandler =
      std::function<void(std::shared_ptr<const levelset::Sculpture> snapshot, uint64_t seq)>;
  Replica(Client& client, ReplicaOptions options);
  ~Replica();
  Replica(const Replica&) = delete;
  Replica& operator=(const Replica&) = delete;

  /// Reads the object's settings from the client's SceneInfo and subscribes (have_seq 0: the
  /// region is loaded anew). FailedPrecondition before Join, NotFound for an unknown object,
  /// InvalidArgument for settings the server sent that do not validate.
  Status Start();
  /// After Client::Reconnect: subscribes again with the sequence held, so the server sends only
  /// the leaves written since.
  Status Resubscribe();
  /// Moves the interest box (unset: whole object); the server answers with the new region.
  Status MoveInterest(std::optional<levelset::Aabb> interest);
  /// Waits until the replica has applied `seq` (or a later sequence) and its queue is empty.
  bool WaitForSeq(uint64_t seq, std::chrono::milliseconds timeout);
  /// Waits until at least `loads` region loads have been applied (Start: 1).
  bool WaitLoaded(uint64_t loads, std::chrono::milliseconds timeout);
  /// Waits until the queue is empty and nothing is being applied.
  bool WaitIdle(std::chrono::milliseconds timeout);

  uint64_t StateHash() const;
  uint64_t RegionHash(const levelset::VoxelBox& box) const;
  /// The region held, in index space (the interest dilated by the server's halo); empty before
  /// the first load.
  levelset::VoxelBox held() const;
  /// The latest published snapshot (null before the first, or with snapshots off).
  std::shared_ptr<const levelset::Sculpture> Snapshot() const;
  ReplicaStats stats() const;
  void SetAppliedHandler(AppliedHandler handler);
  /// Called on the replica's thread with each snapshot as it is published (the haptic loop's
  /// feed takes it from here instead of polling Snapshot()). It must not call back into the
  /// replica's blocking methods; it may keep the pointer. nullptr detaches it.
  void SetSnapshotHandler(SnapshotHandler handler);

 private:
  void Enqueue(v1::ServerMessage&& m);
  void Run();
  void Apply(v1::ServerMessage& m);
  void ApplyBroadcast(const v1::EditBroadcast& b);
  void ApplyDelta(const v1::LeafDelta& d);
  void Publish(bool force);
  void RequestResync();

  Client& client_;
  ReplicaOptions options_;
  levelset::ValidEditSettings settings_;  // the server's, validated by the settings codec
  double voxel_size_ = 1.0;
  mutable std::mutex mu_;  // guards sculpture_, held_, stats_, queue_, busy_
  std::condition_variable cv_;
  std::optional<levelset::Sculpture> sculpture_;
  levelset::VoxelBox held_;
  ReplicaStats stats_;
  std::deque<v1::ServerMessage> queue_;
  bool busy_ = false;
  bool stop_ = false;
  AppliedHandler on_applied_;
  SnapshotHandler on_snapshot_;
  bool publish_pending_ = false;  // an edit was applied since the last copy
  std::chrono::steady_clock::time_point last_publish_{};
  std::shared_ptr<const levelset::Sculpture> snapshot_;  // atomic_load / atomic_store
  std::thread thread_;
};

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_REPLICA_H_
