/// @brief ClusterAgent: this member's presence in etcd (lease, membership record), the ownership
/// of the scenes it hosts (each acquired by txn with a new epoch, fenced locally), and the
/// routing table sessions read to redirect a JoinScene to a scene's owner.
#ifndef SCULPT_SERVER_CLUSTER_CLUSTER_AGENT_H_
#define SCULPT_SERVER_CLUSTER_CLUSTER_AGENT_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cluster/etcd_client.h"
#include "cluster/ownership_fence.h"
#include "cluster/records.h"
#include "cluster/scene_router.h"
#include "cluster/standby_follower.h"
#include "config/server_config.h"

namespace sculpt::server {
class MetricsWriter;
}  // namespace sculpt::server

namespace sculpt::server::cluster {

/// One scene this member hosts: its name, the data directory it lives in (config.data_dir for
/// the configured scene; a standby copy of it is promoted into this directory), and two hooks the
/// agent calls on its own thread: the scene's last applied sequence (Scene::global_seq: the
/// standbys' lag, and what a move compares the target's copy with; empty: no move is carried
/// out) and whether its synchronous acks have fallen back to async (AckGate::fallen_back).
struct HostedScene {
  std::string name;
  std::string data_dir;
  std::function<uint64_t()> seq;
  std::function<bool()> acks_async;
  /// The scene's skins and model objects as this member hosts it: a standby copy keeps them.
  BookConfig books;
};

/// What a member needs to follow other owners' scenes and to take one over.
struct StandbyOptions {
  /// The member's data directory (config.data_dir): its standby copies live in
  /// `<data_dir>/standby/<scene>/`, whichever hosted scene they copy.
  std::string data_dir;
  std::string token;  // a viewer token the owner accepts
  /// This process's command line, run again (execv of /proc/self/exe) after a promotion.
  std::vector<std::string> restart_argv;
  /// The copy's snapshot interval in logged records (config.snapshot_every_edits).
  uint64_t snapshot_every_edits = 5000;
  /// TLS to the owners it follows (ClusterConfig::peer_ca_file).
  PeerTlsOptions tls;
};

/// The environment variable a promotion sets before execv ("<lease id>:<pid>"): the restarted
/// process resumes that lease, and the scenes it owned under it, when the lease still lives.
inline constexpr char kResumeLeaseEnv[] = "SCULPT_CLUSTER_RESUME_LEASE";

/// The lease named by kResumeLeaseEnv when this very process set it (same PID: the image before
/// an execv), else 0. Leaves the variable in place (ClusterAgent::Start reads and removes it).
int64_t ResumableLease();

/// Keeps a promotion's lease alive while the restarted process opens its scenes, before its
/// ClusterAgent starts (docs/cluster.md, "Lease resume"): opening and recovering every hosted
/// scene can take longer than the lease TTL (several scenes, long logs, a slow machine), and the
/// lease lost then takes the owner keys of the member's other scenes with it. Nothing is
/// acknowledged under the lease meanwhile (no fence is granted before Start). Keeps it alive
/// every `lease_ttl_ms / 4` for at most `limit`, then lets it run out (a recovery that long
/// should not hold the member's scenes from their standbys). Stopped by its destructor, which
/// main runs just before ClusterAgent::Start.
class ResumedLeaseKeeper {
 public:
  /// Null when there is no lease of this process to resume (a plain start), or when the etcd
  /// client cannot be made (Start then says why).
  static std::unique_ptr<ResumedLeaseKeeper> StartIfResuming(
      const ClusterConfig& config, std::chrono::milliseconds limit = std::chrono::seconds(60));
  ~ResumedLeaseKeeper();
  ResumedLeaseKeeper(const ResumedLeaseKeeper&) = delete;
  ResumedLeaseKeeper& operator=(const ResumedLeaseKeeper&) = delete;
  /// Keep-alives etcd answered so far (tests).
  uint64_t kept() const { return kept_.load(); }

 private:
  ResumedLeaseKeeper(std::unique_ptr<EtcdClient> etcd, int64_t lease,
                     std::chrono::milliseconds every, std::chrono::milliseconds limit);
  void Run(std::chrono::milliseconds every, std::chrono::milliseconds limit);

  std::unique_ptr<EtcdClient> etcd_;
  const int64_t lease_;
  std::atomic<uint64_t> kept_{0};
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;  // guarded by mu_
  std::thread thread_;
};

/// One sculptd's part in a cluster (docs/cluster.md), for every scene it hosts, under one member
/// lease. Every `lease_ttl_ms / 4` it keeps its lease alive, on its own schedule so that no other
/// etcd call delays it (the fences' deadline follows each answered keep-alive); and every
/// `lease_ttl_ms / 4` after its last pass it: refreshes `members/<name>` with its load (`offers`
/// every hosted scene, `owns` those it owns), reads every member and scene key, and acquires each hosted scene that
/// has no owner and that this member may take (a never-owned scene placed here by PlaceScenes,
/// or a scene whose last owner was this member) with `scenes/<scene>/owner` at epoch + 1 in one
/// txn. All etcd traffic runs on the EtcdClient's own thread; sessions only read the routing
/// table (RouteScene) and each scene's commit pipeline only reads its fence.
/// Standby and failover: each owner names a standby per scene among the other live members
/// (`scenes/<scene>/standby`); the named member follows the owner's edit stream into
/// `<data_dir>/standby/<scene>/` (one StandbyFollower per followed scene); when the owner's key
/// is gone it makes that copy the scene's data directory (HostedScene::data_dir) and restarts
/// itself with the same command line, keeping its lease for the scenes it owns (Start resumes
/// it), and the restarted process takes the scene with the next epoch.
/// Thread safety: constructor, Start, Stop, Abandon and EnableStandby from the owning thread;
/// RouteScene, fence(), the accessors and WriteMetrics from any thread.
class ClusterAgent : public SceneRouter {
 public:
  /// `scenes`: the scenes this process serves (at least one; the first is the one a JoinScene
  /// naming no scene gets); `sessions`: its joined sessions now (called on the agent's thread).
  ClusterAgent(ClusterConfig config, std::vector<HostedScene> scenes,
               std::function<uint32_t()> sessions);
  ~ClusterAgent() override;

  /// Connects to etcd and registers this member with its advertised addresses (HOST:PORT; http
  /// empty when the HTTP port is off), then runs the loop above in the background. The lease is
  /// the one named by kResumeLeaseEnv when that was set by this very process image's
  /// predecessor (same PID: execv) and etcd still keeps it alive; the scenes whose owner keys
  /// name this member under it are then owned again at their epochs (docs/cluster.md, "Lease
  /// resume"). Otherwise a new lease is granted. Unavailable naming the endpoints when etcd does
  /// not answer; InvalidArgument for a malformed endpoint.
  Status Start(const std::string& tcp, const std::string& http);
  /// Before Start: this member may be a standby (cluster.standby) and take a scene over. Without
  /// it the member neither follows nor takes over a scene another member owned.
  void EnableStandby(StandbyOptions options);
  /// Revokes the lease (this member's keys and its scenes' owner keys go at once), stops the
  /// loop and fences every scene. Idempotent.
  void Stop();
  /// Ends the agent as execv ends a process image: every fence revoked and the loop stopped, the
  /// lease neither revoked nor kept alive any more (it lives out its TTL). What a promotion does
  /// before the restart; tests use it to stand for one. Stop afterwards does nothing more.
  void Abandon();
  /// The value a promotion puts in kResumeLeaseEnv ("<lease id>:<pid>"); empty before Start.
  std::string ResumeToken() const;

  /// What `scene`'s commit pipeline consults; valid from construction (not held until
  /// acquired). A scene this member does not host gets a fence that is never held.
  std::shared_ptr<const OwnershipFence> fence(const std::string& scene) const;
  /// kLocal for a hosted scene this member owns, kRedirect to the owner of another, kUnavailable
  /// with the reason, kUnknown for a scene the cluster does not know; "" is the first hosted
  /// scene.
  Route RouteScene(const std::string& scene) const override;
  std::vector<MemberAddress> LiveMembers() const override;
  /// The epoch this member holds `scene` at, 0 when it does not (or does not host it).
  uint64_t owned_epoch(const std::string& scene) const;
  /// The cluster's figures for /metrics (docs/cluster.md, "Metrics"), per hosted scene (label
  /// `scene`): ownership, the standby's progress and lag (from the scene's `seq` hook), this
  /// member's copies as a standby; and the live members and etcd trouble. From any thread.
  void WriteMetrics(MetricsWriter& w) const;

 private:
  using Clock = OwnershipFence::Clock;

  // What the last Refresh read of one scene; RouteScene's table.
  struct SceneState {
    std::optional<OwnerRecord> owner;
    int64_t owner_lease = 0;  // the lease the owner key is held under
    std::optional<EpochRecord> epoch;
    int64_t epoch_mod_revision = 0;
    std::optional<StandbyRecord> standby;
    int64_t standby_mod_revision = 0;
    std::optional<MoveRecord> move;
    int64_t move_mod_revision = 0;
  };

  // One hosted scene: what the agent does for it, as owner or as standby.
  struct Slot {
    explicit Slot(HostedScene h);
    const HostedScene hosted;
    const std::shared_ptr<OwnershipFence> fence;
    // The agent's thread.
    bool owned = false;
    std::unique_ptr<StandbyFollower> follower;
    Clock::time_point ended_at{};  // when the current follower was seen ended
    // The move in progress: fenced for it since move_fenced_at; the owner's sequence when the
    // target was first seen following (its copy must reach it before the fence).
    bool move_fenced = false;
    Clock::time_point move_fenced_at{};
    std::string move_target;
    std::optional<uint64_t> move_mark;
    // Any thread.
    std::atomic<uint64_t> owned_epoch{0};
    std::atomic<uint64_t> follow_seq{0};
    // Guarded by the agent's mu_.
    std::string waiting_reason;  // why the scene has no owner
    std::string moving_to;       // fenced for a move to this member
  };

  asio::awaitable<void> Loop();
  // The lease's keep-alive every tick, on its own: never behind the loop's other etcd calls.
  asio::awaitable<void> KeepAliveLoop();
  asio::awaitable<void> Tick();
  // Grants a lease (or resumes `resume`, the lease of the image before a promotion's execv, if
  // etcd still keeps it alive) and writes this member's record under it.
  asio::awaitable<Status> Register(int64_t resume);
  asio::awaitable<void> KeepLeaseAlive();
  asio::awaitable<Status> Refresh();
  // Acquires `slot`'s scene when it has no owner and this member may take it; `picks` is the
  // placement of every never-owned scene this tick (PlaceScenes over the live members).
  asio::awaitable<void> MaybeAcquire(Slot& slot, const std::map<std::string, std::string>& picks,
                                     bool may_place);
  // Owner: names a standby when there is none or it left. Standby: follows the owner, or, when
  // the owner is gone, returns the dead owner's epoch: the scene is to be promoted.
  asio::awaitable<std::optional<uint64_t>> TendStandby(Slot& slot);
  // Owner asked to move its scene (`scenes/<scene>/move`, docs/cluster.md "Moving a scene"):
  // names the target standby, fences once its copy has caught up, releases the owner key once
  // the copy holds the last sequence; the target's takeover (TendStandby, Promote) does the rest.
  // A request it cannot carry out is removed with the reason.
  asio::awaitable<void> TendMove(Slot& slot);
  asio::awaitable<void> DropMove(Slot& slot, int64_t mod_revision, std::string member,
                                 std::string why);
  // The move is off while fenced for it: acknowledge again.
  void ResumeAfterMove(Slot& slot, const std::string& why);
  // Each standby copy of `promote` (slot, dead owner's epoch) becomes its scene's data
  // directory and the process starts again, keeping its lease (never returns unless that
  // fails).
  asio::awaitable<void> Promote(std::vector<std::pair<Slot*, uint64_t>> promote);
  // Stop (revoke_lease) and Abandon: fences revoked, the loop and its thread stopped, followers
  // retired; idempotent.
  void Shutdown(bool revoke_lease);
  void RetireFollower(Slot& slot);
  // Lost the scene (lease gone, owner key no longer ours): fence at once and say why.
  void LoseOwnership(Slot& slot, const std::string& why);
  MemberRecord SelfRecord() const;
  Slot* FindSlot(const std::string& scene) const;
  bool AnyFollowing() const;
  // The scene as the last Refresh read it, and the live members, copied under mu_.
  std::pair<SceneState, std::vector<MemberRecord>> ReadTable(const std::string& scene) const;

  const ClusterConfig config_;
  const Keys keys_;
  const std::function<uint32_t()> sessions_;
  const std::chrono::milliseconds tick_;
  std::vector<std::unique_ptr<Slot>> slots_;  // fixed at construction
  std::unique_ptr<EtcdClient> etcd_;

  // The agent's thread only (the EtcdClient's io_context), after Start.
  std::string tcp_;
  std::string http_;
  std::atomic<int64_t> lease_{0};
  bool resumed_ = false;  // the first Register kept the lease of the image before the execv
  OwnershipFence::Clock::time_point lease_valid_until_{};
  // Never-owned scenes are placed only from here on (one tick after the first registration), so
  // members started together see each other's records before they place new scenes.
  OwnershipFence::Clock::time_point place_from_{};
  std::unique_ptr<asio::steady_timer> timer_;
  std::unique_ptr<asio::steady_timer> keep_alive_timer_;
  std::atomic<bool> stopping_{false};
  bool started_ = false;  // the owning thread's
  std::optional<StandbyOptions> standby_;  // set before Start
  struct Retired {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::mutex retired_mu_;
  // Threads stopping followers (a stop may wait on a connect) or moving a promoted copy's files;
  // joined when done by RetireFollower, and all of them by Shutdown.
  std::vector<Retired> retired_;

  mutable std::mutex mu_;
  std::map<std::string, SceneState> scenes_;  // guarded by mu_
  std::vector<MemberRecord> members_;         // guarded by mu_
  std::atomic<uint64_t> etcd_failures_{0};     // keep-alives and refreshes etcd did not answer
  std::atomic<uint64_t> ownership_losses_{0};  // times this member stopped owning a scene
  // Frames its followers refused for their epoch (shared with each StandbyFollower).
  std::shared_ptr<std::atomic<uint64_t>> stale_epoch_refusals_ =
      std::make_shared<std::atomic<uint64_t>>(0);
  // Times its followers' copies diverged and were loaded anew (shared with each StandbyFollower).
  std::shared_ptr<std::atomic<uint64_t>> standby_divergences_ =
      std::make_shared<std::atomic<uint64_t>>(0);
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_CLUSTER_AGENT_H_
