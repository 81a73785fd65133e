/// @brief StandbyFollower: a standby member's copy of another member's scene, kept by following
/// the owner's edit stream as a replay replica (issue 4's Subscribe) and logging what it applies
/// into a data directory of its own, so that the copy can be opened as the scene on failover.
#ifndef SCULPT_SERVER_CLUSTER_STANDBY_FOLLOWER_H_
#define SCULPT_SERVER_CLUSTER_STANDBY_FOLLOWER_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "config/server_config.h"
#include "sculpt/core/status.h"

namespace sculpt::v1 {
class ServerMessage;
}  // namespace sculpt::v1

namespace sculpt::server::cluster {

/// Where a member keeps its standby copies: `<data_dir>/standby/<scene>/`, holding generations
/// `gen-<n>/` (each a data directory: `snapshots/`, `log/`) and `CURRENT`, the name of the newest
/// generation that is complete (its region loaded and snapshotted, its log started after it).
/// A new connection to the owner starts a new generation; CURRENT moves to it only once it is
/// complete, so a connection lost at the owner's death never costs the copy already held.
std::string StandbyDir(const std::string& data_dir, const std::string& scene);
/// The complete generation's directory, or nullopt when there is none; `epoch` (may be null)
/// gets the owner's epoch it was following.
std::optional<std::string> CurrentStandbyCopy(const std::string& data_dir,
                                              const std::string& scene, uint64_t* epoch = nullptr);

/// Failover: makes the standby copy of `scene` (in `StandbyDir(data_dir, scene)`, `data_dir`
/// being the member's data directory) the scene's data directory `scene_dir` (data_dir itself
/// for the member's configured scene, `<data_dir>/scenes/<scene>` for another hosted one).
/// Everything else in `scene_dir` (the scene this process opened at start, other side files) is
/// moved, never deleted, into `<scene_dir>/superseded/<epoch>-<ms>/`, except `standby/` (the
/// member's copies), `scenes/` (its other hosted scenes) and `superseded/`; the copy's files take
/// its place; `<scene_dir>/cluster-promoted` records that the directory is the standby copy of
/// `scene` as owned at `dead_epoch`, so the restarted process may take the scene with epoch + 1.
/// FailedPrecondition without a complete copy; Internal for a file-system error (the directory is
/// then left as the error says).
Status PromoteStandbyCopy(const std::string& data_dir, const std::string& scene,
                          const std::string& scene_dir, uint64_t dead_epoch);
/// The epoch PromoteStandbyCopy wrote into `scene_dir` for `scene`, nullopt when none.
std::optional<uint64_t> PromotedFromEpoch(const std::string& scene_dir, const std::string& scene);
/// Forgets the promotion marker of `scene_dir` (once the scene is acquired).
void ClearPromotedMarker(const std::string& scene_dir);

/// TLS to the owner: a cluster whose members' TCP ports speak TLS (cluster.peer_ca_file,
/// docs/cluster.md "TLS between members").
struct PeerTlsOptions {
  bool enabled = false;
  std::string ca_file;    // PEM CAs the owner's certificate must chain to; empty: system store
  std::string cert_file;  // this member's certificate and key, for owners that require one
  std::string key_file;
};

/// What a copy needs of the scene's own configuration to keep its books (skins and models,
/// with their undo histories) as the owner keeps them: the scene as this member hosts it.
struct BookConfig {
  std::vector<SkinConfig> skins;
  std::vector<ObjectConfig> objects;  // the `model` objects have books
  uint32_t undo_depth = 64;           // limits.undo_depth
};

/// True for the paths a region load's book files may name (LeafDelta.book_files): skins/<name>.pb,
/// skins/<name>.history, models/<name>.json or models/<name>.history, the name of letters, digits,
/// '.', '_' and '-', not starting with '.', the file name at most 200 characters. Anything else
/// (another directory, "..", a slash in the name) is refused before a byte is written.
bool IsBookFilePath(const std::string& path);

struct FollowerOptions {
  std::string data_dir;
  std::string scene;
  std::string member;  // this member's name (the session name the owner logs)
  std::string token;   // cluster.peer_token, or (none configured) a viewer token the owner accepts
  std::string owner_tcp;  // HOST:PORT; over TLS the certificate must name HOST
  PeerTlsOptions tls;
  /// The ownership epoch of the owner etcd names (scenes/<scene>/owner): every EditBroadcast and
  /// LeafDelta must carry it, else it is refused (fencing, docs/cluster.md).
  uint64_t owner_epoch = 0;
  /// Counts the frames refused for another epoch (the member's
  /// sculpt_cluster_stale_epoch_refusals_total); may be null.
  std::shared_ptr<std::atomic<uint64_t>> stale_epoch_refusals;
  /// Counts the copy's divergences (a replayed edit whose leaves hash differed from the owner's:
  /// reported to the owner and the object loaded anew; the member's
  /// sculpt_cluster_standby_divergences_total); may be null.
  std::shared_ptr<std::atomic<uint64_t>> divergences;
  /// The copy snapshots its object after this many logged records and drops the log before the
  /// previous snapshot (as the owner does with snapshot_every_edits), so a failover replays a
  /// bounded tail; 0: only at region loads.
  uint64_t snapshot_every_records = 5000;
  /// The scene's skins and model objects (unset: the copy keeps no books, and a failover starts
  /// them from what the owner's region load sent).
  BookConfig books;
};

/// One follow of one owner: connects as a viewer, joins the scene without its state, subscribes
/// to the whole of its object in replay mode, and then, on its own thread, for each message:
/// an EditBroadcast is logged (the stroke's pose records, as the owner logged them, in one group)
/// and replayed with the kernel, its leaves hash checked (a mismatch is reported to the owner
/// and the object loaded anew); LogRecords (every other edit: paint, sweep, undo, ball edit,
/// model intent) are logged as the owner logged them and replayed into the copy's books (skins
/// and models, which the region load's book files started); a region load or a leaf delta is
/// applied and the object (and the books) snapshotted at its sequence. Every stroke, paint,
/// sweep and object undo is recorded in the object's stroke undo history as the owner records
/// it (started from the owner's, LeafDelta.object_history), which each snapshot keeps beside it.
/// So the copy's log holds every record of the owner's since the copy's oldest snapshot, and a
/// promoted copy recovers objects, skins, models and all their undo histories as the owner's
/// own directory would.
/// The follow ends when the connection does; the copy stays for promotion.
/// Fencing: a broadcast or delta whose epoch is not the expected one (options().owner_epoch, or
/// the one Supersede gave) is neither applied nor logged: it is counted, logged with both
/// epochs, and the follow ends (the connection dropped), so the member reads the owner from
/// etcd again before it follows anew. The copy logs each stroke record with the broadcast's
/// epoch.
/// Limits: a scene of one object (several objects would need one connection each and a merge by
/// sequence); the owner's authenticated user names and resend table are not carried (see
/// docs/cluster.md). Thread safety: every method from any thread.
class StandbyFollower {
 public:
  explicit StandbyFollower(FollowerOptions options);
  /// Stops following and waits for the thread; the copy's log is made durable first.
  ~StandbyFollower();
  StandbyFollower(const StandbyFollower&) = delete;
  StandbyFollower& operator=(const StandbyFollower&) = delete;

  const FollowerOptions& options() const { return options_; }
  /// The connection ended or never started (the copy, if any, stays).
  bool finished() const { return finished_.load(); }
  /// Why the follow ended (empty while it runs).
  std::string failure() const;
  /// This follow's generation is complete and current.
  bool ready() const { return ready_.load(); }
  /// The last sequence the copy holds durably (0 before ready).
  uint64_t durable_seq() const;
  /// etcd names `epoch` for the scene's owner now, not the epoch this follow began with: from
  /// now on nothing of another epoch is taken, and the follow ends once the frames already
  /// received are refused (a new owner is followed by a new StandbyFollower).
  void Supersede(uint64_t epoch);
  /// The epoch frames must carry to be taken.
  uint64_t expected_epoch() const { return expected_epoch_.load(); }
  /// Frames this follow refused for their epoch.
  uint64_t stale_epoch_refusals() const { return refusals_.load(); }
  /// Times this follow's copy diverged from the owner and was loaded anew.
  uint64_t divergences() const { return divergences_.load(); }

 private:
  struct Impl;
  void Run();

  const FollowerOptions options_;
  std::shared_ptr<Impl> impl_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<bool> ready_{false};
  std::atomic<uint64_t> expected_epoch_{0};
  std::atomic<bool> superseded_{false};
  std::atomic<uint64_t> refusals_{0};
  std::atomic<uint64_t> divergences_{0};
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::unique_ptr<v1::ServerMessage>> queue_;  // guarded by mu_
  std::string failure_;                                    // guarded by mu_
  std::thread thread_;
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_STANDBY_FOLLOWER_H_
