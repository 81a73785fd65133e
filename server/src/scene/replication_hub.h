/// @brief ReplicationHub: the scene's replicas (issue 4): subscriptions per session, the leaf
/// versions of every object, and what each replica is sent after an edit or when it (re)loads
/// its region.
#ifndef SCULPT_SERVER_SCENE_REPLICATION_HUB_H_
#define SCULPT_SERVER_SCENE_REPLICATION_HUB_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "scene/replica_sink.h"
#include "sculpt/codec/replica_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::server {

namespace cluster {
class OwnershipFence;
}  // namespace cluster

/// Replication counters since start.
struct ReplicationStats {
  std::atomic<uint64_t> broadcasts{0};   // EditBroadcast frames built
  std::atomic<uint64_t> leaf_deltas{0};  // LeafDelta frames built
  std::atomic<uint64_t> resyncs{0};      // subscribe / interest answers
  std::atomic<uint64_t> divergences{0};  // replicas' reports of a hash mismatch
  std::atomic<uint64_t> broadcast_bytes{0};
  std::atomic<uint64_t> leaf_delta_bytes{0};
};

/// Largest interest box edge accepted, in voxels; a replica wanting more subscribes to the
/// whole object.
inline constexpr int kMaxInterestVoxels = 1024;
/// A subscription holds its interest box dilated by this many voxels, so edits touching the box
/// usually fit (replayed) and the haptic look-ahead has material around the tool.
inline constexpr int kReplicaHaloVoxels = 16;

/// The form of an edit replay replicas can apply themselves (strokes): what an EditBroadcast
/// carries.
struct EditReplay {
  const std::string* source = nullptr;  // the client's serialized Stroke
  levelset::ReplayState before;
  levelset::EditFootprint footprint;
};

/// The replicas of a scene's objects. A subscription is one session's replica of one object,
/// kept current by EditBroadcasts it replays (replay mode, when the edit fits what it holds) or
/// by the changed leaves (leaf-delta mode, or an edit reaching beyond its region); it holds the
/// whole object or an interest box dilated by kReplicaHaloVoxels. Frames are built once per edit
/// and shared by every replica that gets the same bytes.
/// Thread safety: none of its own. The scene calls it on its compute thread only, between two
/// edits, as it did with these members inline; sinks are called there and must only post.
/// ReportDivergence and stats() (atomics, the log) may be called from any thread.
class ReplicationHub {
 public:
  /// Leaf versions are known only for edits after `seq` (the sequence recovery ended at): a
  /// replica holding an older state loads its region anew instead of the leaves since.
  void set_versions_floor(uint64_t seq) { versions_floor_ = seq; }
  /// The scene's resend table ((stream, client id) -> newest client_seq, read on the compute
  /// thread only): a region load to the scene's standby carries it, so a resend of an edit
  /// inside the load is recognised after a failover.
  using ResendEntries = std::map<std::pair<uint8_t, uint64_t>, uint64_t>;
  void set_resend_table(const ResendEntries* table) { resend_table_ = table; }
  /// Cluster mode: every frame sent carries this fence's epoch (EditBroadcast.epoch,
  /// LeafDelta.epoch), so a standby can refuse a stream of another epoch than etcd names. Null
  /// (a single process): epoch 0, absent from the bytes.
  void set_fence(const cluster::OwnershipFence* fence) { fence_ = fence; }
  /// Cluster mode: the scene's book files (skins and models with their undo histories) as of
  /// `seq`, (path relative to the data directory, bytes); a region load to the standby carries
  /// them (LeafDelta.book_files), so its copy starts from the owner's books. Compute thread.
  using BookFiles = std::function<std::vector<std::pair<std::string, std::string>>(uint64_t)>;
  void set_book_files(BookFiles files) { book_files_ = std::move(files); }
  /// The history file of an object's stroke undo history as of a sequence (history_file.h):
  /// sent with a region load to the scene's standby (LeafDelta.object_history), so its copy's
  /// snapshots carry the history the owner's would. Compute thread.
  using ObjectHistory = std::function<std::string(const std::string& object, uint64_t seq)>;
  void set_object_history(ObjectHistory history) { object_history_ = std::move(history); }

  /// Registers `sink`'s replica of `object` (`sculpture`, null when the scene has no such
  /// object) at the scene's sequence `seq`, replacing the session's earlier subscription, and
  /// sends it a LeafDelta of its region: the leaves written after request.have_seq, or the whole
  /// region (replace_region) when have_seq is 0 or older than the versions known. `answer` gets
  /// the outcome exactly once, before any frame: NotFound for an unknown object,
  /// InvalidArgument naming Subscribe.have_seq (above `seq`) or Subscribe.interest (an edge
  /// longer than kMaxInterestVoxels, or max below min).
  void Subscribe(ReplicaSink sink, const codec::ReplicaSubscription& request,
                 const levelset::Sculpture* sculpture, uint64_t seq,
                 const std::function<void(Status)>& answer);
  /// Moves the session's box (request.object's `sculpture`) and sends the new region whole
  /// (replace_region). `answer` as above, before any frame: FailedPrecondition when the session
  /// has no subscription to the object, InvalidArgument naming SetInterest.interest.
  void SetInterest(uint64_t session_id, const codec::InterestChange& request,
                   const levelset::Sculpture* sculpture, uint64_t seq,
                   const std::function<void(Status)>& answer);
  /// Forgets the session's subscription (none: nothing happens).
  void Unsubscribe(uint64_t session_id);

  /// Records that an edit ending at `seq` wrote `leaves` of `object` (every edit, subscribers or
  /// not, so a replica subscribing later catches up by version).
  void RecordVersions(const std::string& object, const std::vector<levelset::Int3>& leaves,
                      uint64_t seq);
  /// Sends an applied edit (sequences first_seq..last_seq, author client_id/client_seq, the
  /// leaves it changed) to the object's replicas: an EditBroadcast to replay replicas holding
  /// its footprint when it has a `replay` form, else the changed leaves inside each replica's
  /// region (a leaf-delta replica whose region the edit touched hears of it even when none of
  /// its leaves changed). Call after RecordVersions; nothing is built without subscribers.
  void Replicate(const std::string& object, const levelset::Sculpture& sculpture,
                 const std::vector<levelset::Int3>& dirty, uint64_t first_seq, uint64_t last_seq,
                 uint64_t client_id, uint64_t client_seq, const EditReplay* replay);

  /// Cluster mode: sends the scene's standby (a subscription whose sink is the standby's) the
  /// records logged at first_seq.. exactly as logged (LogRecords), for an edit no EditBroadcast
  /// carries to it; call before Replicate of the same edit, so the copy logs the record before
  /// it applies the leaves. True when a standby subscription got them (it reports them durable
  /// with ReplicaProgress).
  bool ShipRecords(uint64_t first_seq, const std::vector<std::string>& records);

  /// A replica's hash mismatch: logged with both hashes and counted. Any thread.
  void ReportDivergence(uint64_t session_id, const codec::Divergence& report);

  size_t subscriber_count() const { return subs_.size(); }
  ReplicationStats& stats() { return stats_; }

 private:
  struct Sub {
    ReplicaSink sink;
    std::string object;
    codec::ReplicaMode mode = codec::ReplicaMode::kReplay;
    bool whole = true;
    levelset::VoxelBox held;  // interest dilated by the halo (when !whole)
  };
  // The fence's epoch (0 without one).
  uint64_t epoch() const;
  void SendRegion(Sub& sub, const levelset::Sculpture& sculpture, uint64_t seq, uint64_t have_seq,
                  bool replace);

  std::map<uint64_t, Sub> subs_;  // by session
  std::map<std::string, levelset::LeafVersions> versions_;
  uint64_t versions_floor_ = 0;
  const ResendEntries* resend_table_ = nullptr;
  const cluster::OwnershipFence* fence_ = nullptr;
  BookFiles book_files_;
  ObjectHistory object_history_;
  ReplicationStats stats_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_REPLICATION_HUB_H_
