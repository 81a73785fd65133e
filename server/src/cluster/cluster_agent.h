/// @brief ClusterAgent: this member's presence in etcd (lease, membership record), the ownership
/// of its scene (acquired by txn with a new epoch, fenced locally), and the routing table
/// sessions read to redirect a JoinScene to a scene's owner.
#ifndef SCULPT_SERVER_CLUSTER_CLUSTER_AGENT_H_
#define SCULPT_SERVER_CLUSTER_CLUSTER_AGENT_H_

#include <atomic>
#include <chrono>
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

/// One sculptd's part in a cluster (docs/cluster.md). Every `lease_ttl_ms / 4` it: keeps its
/// lease alive (the fence's deadline follows each answered keep-alive), refreshes
/// `members/<name>` with its load, reads every member and scene key, and, if its scene has no
/// owner and this member may take it (a new scene placed here, least loaded, or a scene whose
/// last owner was this member), acquires `scenes/<scene>/owner` with epoch + 1 in one txn.
/// All etcd traffic runs on the EtcdClient's own thread; sessions only read the routing table
/// (RouteScene) and the commit pipeline only reads the fence.
/// Thread safety: Start and Stop from the owning thread; RouteScene, fence() and the accessors
/// from any thread.
/// Standby and failover (docs/cluster.md): the owner names a standby among the other live
/// members (`scenes/<scene>/standby`); that member follows the owner's edit stream into
/// `<data_dir>/standby/` (StandbyFollower); when the owner's key is gone it makes that copy its
/// data directory and restarts itself with the same command line, and the restarted process
/// takes the scene with the next epoch.
struct StandbyOptions {
  std::string data_dir;  // config.data_dir
  std::string token;     // a viewer token the owner accepts
  /// This process's command line, run again (execv of /proc/self/exe) after a promotion.
  std::vector<std::string> restart_argv;
  /// The copy's snapshot interval in logged records (config.snapshot_every_edits).
  uint64_t snapshot_every_edits = 5000;
  /// TLS to the owners it follows (ClusterConfig::peer_ca_file).
  PeerTlsOptions tls;
};

class ClusterAgent : public SceneRouter {
 public:
  /// `scene`: the scene this process serves (config.scene.name); `sessions`: its joined sessions
  /// now (called on the agent's thread).
  ClusterAgent(ClusterConfig config, std::string scene, std::function<uint32_t()> sessions);
  ~ClusterAgent() override;

  /// Connects to etcd, grants the lease and registers this member with its advertised
  /// addresses (HOST:PORT; http empty when the HTTP port is off), then runs the loop above in
  /// the background. Unavailable naming the endpoints when etcd does not answer; InvalidArgument
  /// for a malformed endpoint.
  Status Start(const std::string& tcp, const std::string& http);
  /// Before Start: this member may be a standby (cluster.standby) and take a scene over. Without
  /// it the member neither follows nor takes over a scene another member owned.
  void EnableStandby(StandbyOptions options);
  /// Before Start: the scene's last applied sequence (Scene::global_seq), which an owner asked to
  /// move its scene (`scenes/<scene>/move`) compares with its standby's copy. Without it no
  /// move request is carried out.
  void set_scene_seq(std::function<uint64_t()> scene_seq) {
    if (!started_) scene_seq_ = std::move(scene_seq);
  }
  /// Whether the scene's synchronous acks have fallen back to async (AckGate::fallen_back), for
  /// the member record; call before Start.
  void set_acks_async(std::function<bool()> acks_async) {
    if (!started_) acks_async_ = std::move(acks_async);
  }
  /// Revokes the lease (this member's keys and its scene's owner key go at once), stops the
  /// loop and fences the scene. Idempotent.
  void Stop();

  /// What the commit pipeline consults; valid from construction (not held until acquired).
  std::shared_ptr<const OwnershipFence> fence() const { return fence_; }
  Route RouteScene(const std::string& scene) const override;
  std::vector<MemberAddress> LiveMembers() const override;
  /// The epoch this member holds its scene at, 0 when it does not.
  uint64_t owned_epoch() const;
  /// The cluster's figures for /metrics (docs/cluster.md, "Metrics"): ownership, live members,
  /// the standby's progress and lag against `scene_seq` (the scene's global sequence here),
  /// etcd trouble. From any thread.
  void WriteMetrics(MetricsWriter& w, uint64_t scene_seq) const;

 private:
  asio::awaitable<void> Loop();
  asio::awaitable<void> Tick();
  asio::awaitable<Status> Register();
  asio::awaitable<void> KeepLeaseAlive();
  asio::awaitable<Status> Refresh();
  asio::awaitable<void> MaybeAcquire();
  // Owner: names a standby when there is none or it left. Standby: follows the owner, or takes
  // the scene over when the owner is gone.
  asio::awaitable<void> TendStandby();
  // Owner asked to move its scene (`scenes/<scene>/move`, docs/cluster.md "Moving a scene"):
  // names the target standby, fences once its copy has caught up, releases the owner key once
  // the copy holds the last sequence; the target's takeover (TendStandby, Promote) does the rest.
  // A request it cannot carry out is removed with the reason.
  asio::awaitable<void> TendMove();
  asio::awaitable<void> DropMove(int64_t mod_revision, std::string member, std::string why);
  // The move is off while fenced for it: acknowledge again.
  void ResumeAfterMove(const std::string& why);
  // The standby copy becomes the data directory and the process starts again (never returns
  // unless that fails).
  asio::awaitable<void> Promote(uint64_t dead_epoch);
  void RetireFollower();
  // Lost the scene (lease gone, owner key no longer ours): fence at once and say why.
  void LoseOwnership(const std::string& why);
  MemberRecord SelfRecord() const;

  const ClusterConfig config_;
  const std::string scene_;
  const Keys keys_;
  const std::function<uint32_t()> sessions_;
  const std::shared_ptr<OwnershipFence> fence_;
  const std::chrono::milliseconds tick_;
  std::unique_ptr<EtcdClient> etcd_;

  // The agent's thread only (the EtcdClient's io_context), after Start.
  std::string tcp_;
  std::string http_;
  int64_t lease_ = 0;
  OwnershipFence::Clock::time_point lease_valid_until_{};
  bool owned_ = false;
  std::unique_ptr<asio::steady_timer> timer_;
  std::atomic<bool> stopping_{false};
  bool started_ = false;  // the owning thread's
  std::optional<StandbyOptions> standby_;  // set before Start
  std::unique_ptr<StandbyFollower> follower_;  // the agent's thread
  OwnershipFence::Clock::time_point ended_at_{};  // when the current follower was seen ended
  struct Retired {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::mutex retired_mu_;
  std::vector<Retired> retired_;  // followers being stopped (a stop may wait on a connect)
  std::atomic<uint64_t> follow_seq_{0};
  std::function<uint64_t()> scene_seq_;  // set before Start
  std::function<bool()> acks_async_;
  // The move in progress (agent's thread): fenced for it since move_fenced_at_; the owner's
  // sequence when the target was first seen following (its copy must reach it before the fence).
  bool move_fenced_ = false;
  OwnershipFence::Clock::time_point move_fenced_at_{};
  std::string move_target_;
  std::optional<uint64_t> move_mark_;

  // What the last Refresh read; RouteScene's table.
  struct SceneState {
    std::optional<OwnerRecord> owner;
    std::optional<EpochRecord> epoch;
    int64_t epoch_mod_revision = 0;
    std::optional<StandbyRecord> standby;
    int64_t standby_mod_revision = 0;
    std::optional<MoveRecord> move;
    int64_t move_mod_revision = 0;
  };
  // This member's scene as the last Refresh read it, and the live members, copied under mu_.
  std::pair<SceneState, std::vector<MemberRecord>> ReadTable() const;
  mutable std::mutex mu_;
  std::map<std::string, SceneState> scenes_;  // guarded by mu_
  std::vector<MemberRecord> members_;         // guarded by mu_
  std::string waiting_reason_;  // guarded by mu_: why this member's scene has no owner
  std::string moving_to_;       // guarded by mu_: fenced for a move to this member
  std::atomic<uint64_t> owned_epoch_{0};
  std::atomic<uint64_t> etcd_failures_{0};     // keep-alives and refreshes etcd did not answer
  std::atomic<uint64_t> ownership_losses_{0};  // times this member stopped owning its scene
  // Frames its followers refused for their epoch (shared with each StandbyFollower).
  std::shared_ptr<std::atomic<uint64_t>> stale_epoch_refusals_ =
      std::make_shared<std::atomic<uint64_t>>(0);
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_CLUSTER_AGENT_H_
