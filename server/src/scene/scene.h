/// @brief Scene: the actor that owns a scene's sculptures, orders edits by a global sequence,
/// logs them durably, applies them on its compute thread and acknowledges them once durable.
#ifndef SCULPT_SERVER_SCENE_SCENE_H_
#define SCULPT_SERVER_SCENE_SCENE_H_

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "config/server_config.h"
#include "scene/ack_gate.h"
#include "scene/commit.h"
#include "scene/scene_summary.h"
#include "scene/fair_queue.h"
#include "scene/mesh_feed.h"
#include "scene/models.h"
#include "scene/outcomes.h"
#include "scene/replica_sink.h"
#include "scene/replication_hub.h"
#include "scene/skins.h"
#include "sculpt/codec/history.h"
#include "sculpt/codec/model_messages.h"
#include "sculpt/codec/paint_messages.h"
#include "sculpt/codec/replica_messages.h"
#include "sculpt/codec/skin_messages.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/codec/undo.h"
#include "sculpt/core/latency_histogram.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/skin/skin.h"

namespace sculpt::server::cluster {
class OwnershipFence;
}  // namespace sculpt::server::cluster

namespace sculpt::server {

class EditHistory;

namespace store {
class EditLog;
class SnapshotStore;
}  // namespace store

/// What became of one stroke.
struct StrokeOutcome {
  Status status;  // not ok: the stroke was refused before anything was logged
  uint64_t client_seq = 0;
  uint64_t global_seq_first = 0;
  uint32_t edits = 0;
  bool duplicate = false;
  levelset::EditResult last;  // result of the stroke's last pose
};

/// The current state for a late joiner.
struct JoinState {
  SceneSummary info;  // each object's state_hash set
  std::vector<std::pair<std::string, std::string>> objects;  // name, .vdb bytes
  /// The joining client's newest committed client_seq per ResendStream (indexed by its value)
  /// when the copy was taken: its requests up to there are resends the scene answers as
  /// duplicates without applying them again.
  std::array<uint64_t, kResendStreams> committed_up_to{};
};

/// The scene actor. Edits are applied in global-sequence order on one compute thread (one
/// writer per object); readers get copies. Thread safety: every public method may be called
/// from any thread; callbacks run on the compute thread or the edit log's sync thread and must
/// only post work elsewhere.
class Scene {
 public:
  using StrokeDone = std::function<void(const StrokeOutcome&)>;

  /// Recovers the scene from config.data_dir (newest snapshots plus the log tail), or builds it
  /// from the configured primitives. DataLoss for a corrupt log, with the reason.
  static StatusOr<std::unique_ptr<Scene>> Open(const ServerConfig& config);
  ~Scene();

  /// Queues a validated stroke. The edits are logged, applied, and `done` is called once they
  /// are durable (per the fsync policy). A resend of an already applied (client_id, client_seq)
  /// is not applied again: `done` gets duplicate = true.
  void Submit(uint64_t client_id, codec::DecodedStroke stroke, StrokeDone done);

  /// Scene info and each object's .vdb bytes for a late joiner: the objects are copied between
  /// two edits on the compute thread and serialised on the one join worker, so a joiner never
  /// stalls the others' edits. At most limits.max_pending_joins joins are in progress at once;
  /// past it `done` gets ResourceExhausted naming that limit at once (nothing is copied).
  /// Unavailable when the scene is shutting down; Internal naming the step when one threw.
  /// `client_id` names the joiner whose resend position goes into JoinState::committed_up_to.
  void RequestJoinState(std::function<void(StatusOr<JoinState>)> done, uint64_t client_id = 0);
  /// Late joins admitted and not yet answered (waiting for a copy, for the worker, or being
  /// serialised).
  size_t pending_joins() const;

  /// Limits a stroke on `object` is decoded against; NotFound for an unknown object.
  StatusOr<codec::StrokeLimits> LimitsFor(const std::string& object) const;
  /// The scene as of the last applied edit (net/wire_info.h puts it on the wire).
  SceneSummary Info() const;
  const std::string& name() const { return config_.scene.name; }
  uint64_t global_seq() const { return applied_seq_.load(); }
  /// Cluster mode (issue 17): edits are sequenced and acknowledged only while `fence` holds; an
  /// edit it refuses is answered with its Unavailable error, never acknowledged. Null (the
  /// default, a single process): always. Set before the scene serves anyone.
  void set_ownership_fence(std::shared_ptr<const cluster::OwnershipFence> fence) {
    fence_ = std::move(fence);
    replication_.set_fence(fence_.get());  // frames to replicas carry its epoch
  }

  /// Cluster mode, `replication = "sync"` (docs/cluster.md): the scene's standby says its copy
  /// is durable up to `seq` (a validated ReplicaProgress from the named standby's session).
  /// Acknowledgements wait for it; ignored under async and none.
  void StandbyDurable(uint64_t seq) { acks_->StandbyDurable(seq); }
  /// The acknowledgements' gate: its mode and state for /metrics and tests.
  const AckGate& acks() const { return *acks_; }

  /// Waits until every queued stroke is applied and durable (tests, shutdown).
  void Flush();
  /// Flush, then a snapshot of every object if anything changed since the last one, written
  /// before returning: a graceful restart then replays nothing.
  void FlushAndSnapshot();
  /// State hash of one object, taken on the compute thread (0 for an unknown object).
  uint64_t StateHash(const std::string& object);
  /// Registers a replica of one object (decoded by codec::DecodeSubscribe; checked here: the
  /// object, the interest box's extent, have_seq) and sends it, through `sink`, the leaf records
  /// that bring its region to the current sequence, then every later edit touching the region.
  /// Runs on the compute thread, between two edits; `done` gets the refusal
  /// (InvalidArgument/NotFound naming the field).
  void Subscribe(ReplicaSink sink, codec::ReplicaSubscription request,
                 std::function<void(Status)> done);
  /// Moves a subscription's box (decoded by codec::DecodeSetInterest): sends the leaves of the
  /// new region. FailedPrecondition when the session has no subscription to the object.
  void SetInterest(uint64_t session_id, codec::InterestChange request,
                   std::function<void(Status)> done);
  void Unsubscribe(uint64_t session_id);
  /// A replica's hash mismatch: logged with both hashes and counted.
  void ReportDivergence(uint64_t session_id, const codec::Divergence& report);
  /// Hash of every voxel of an index box of one object, on the compute thread (tests); 0 for an
  /// unknown object.
  uint64_t RegionHash(const std::string& object, const levelset::VoxelBox& box);
  ReplicationStats& replication_stats() { return replication_.stats(); }

  /// Registers a viewer of one object's Draco mesh chunks (codec::DecodeViewerSubscribe): it gets every
  /// chunk holding surface, then the chunks edits change, re-meshed on the mesher thread at most
  /// max_rate_hz times a second (capped by scene.mesh_max_rate_hz), several edits coalesced.
  /// Nothing is meshed while no viewer is subscribed.
  void SubscribeViewer(ReplicaSink sink, codec::ViewerSubscription request,
                       std::function<void(Status)> done);
  void UnsubscribeViewer(uint64_t session_id);
  /// Runs `fn` on the object between two edits (tests, tools); false for an unknown object.
  bool Inspect(const std::string& object, const std::function<void(const levelset::Sculpture&)>& fn);
  using MeshStats = MeshFeed::Stats;
  MeshStats& mesh_stats() { return mesh_feed_.stats(); }

  /// Ball skins (issue 6, skins.cc). A ball edit (decoded by codec::DecodeSkinBallEdit; its
  /// index is checked against the skin here) rebuilds at most two sections and sends contour
  /// subscribers of the skin an update with only those; logged (a SkinEditRecord after 0x03,
  /// replayed by recovery); `done` gets the outcome once durable (a refusal, naming the field,
  /// at once). A resend (client_seq not above the client's last ball edit) is acknowledged as a
  /// duplicate and not applied again.
  void EditSkin(uint64_t client_id, codec::BallEdit edit, std::function<void(SkinOutcome)> done);
  /// Sweeps a skin's outline into an object (decoded by codec::DecodeSkinSweep): logged (a
  /// SkinSweepRecord, replayed by recovery), applied, replicated as leaf deltas; `done` once
  /// durable. A resend (client_seq not above the client's last sweep) is acknowledged as a
  /// duplicate and not applied again.
  void SweepSkin(uint64_t client_id, codec::SkinSweepRequest sweep,
                 std::function<void(SkinOutcome)> done);
  /// A skin's contours (a snapshot now, then updates) or an object's slice (now and after each
  /// edit of the object) to `sink` (decoded by codec::DecodeContourSubscribe). NotFound naming
  /// the skin or object; FailedPrecondition when the scene computes no contours.
  void SubscribeContours(ReplicaSink sink, codec::ContourRequest request,
                         std::function<void(Status)> done);
  void UnsubscribeContours(uint64_t session_id);
  /// A copy of a skin as the server holds it (tests, tools). NotFound for an unknown skin.
  StatusOr<skin::Skin> SkinCopy(const std::string& name);

  /// Paints or fills material fractions (issue 7, paint.cc; decoded by codec::DecodePaintEdit):
  /// logged (a PaintRecord, replayed by recovery), applied, replicated as leaf deltas, marked for
  /// viewers; `done` gets the outcome once durable (a refusal, naming the field, at once). A
  /// resend (client_seq not above the client's last paint) is acknowledged as a duplicate and
  /// not applied again.
  void Paint(uint64_t client_id, codec::Paint paint, std::function<void(PaintOutcome)> done);

  /// Edits an object's hyperpatch model (issue 7, models.cc; decoded by
  /// codec::DecodeModelIntent): corner and cell checked against the model, the intent
  /// expanded by the library and validity checked after ordering. Refused (reason code, cell,
  /// direction, span) → `done` at once, nothing logged or changed; accepted → logged (a
  /// ModelRecord after 0x02, replayed by recovery), applied, `done` once durable. The voxelised
  /// sculpture is not re-voxelised. A resend is acknowledged as a duplicate.
  void EditModel(uint64_t client_id, codec::ModelEdit edit,
                 std::function<void(ModelOutcome)> done);
  /// The model of a `model` object (tests, tools). NotFound for an object without one.
  StatusOr<ModelSummary> ModelInfo(const std::string& object);

  /// Per-author undo and redo (issue 15, undo.cc): takes back the client's own most recent
  /// edit as if it had never been made (later edits by anyone replayed without it), or puts back
  /// the one it undid most recently. command.object names an object (its strokes and paints,
  /// EditHistory, and for a `model` object its intents, ModelBook: the newest of them) or a skin
  /// (its ball edits, SkinBook). Logged (an UndoRecord after 0x04 naming the history and the
  /// edit chosen, replayed by recovery), replicated as changed leaves (a skin's contour
  /// subscribers get the whole skin), `done` once durable. Refused by name: nothing to undo or
  /// redo (FailedPrecondition), beyond the history (OutOfRange), an unknown object or skin
  /// (NotFound). The stroke history reaches back to the object's last snapshot (the history file
  /// kept with it), the ball-edit and intent histories to the last snapshot round; at most
  /// limits.undo_depth edits per author. A resend is acknowledged as a duplicate.
  /// The command was decoded by codec::DecodeUndo (its object name's length checked).
  void Undo(uint64_t client_id, codec::UndoCommand command,
            std::function<void(UndoCommandOutcome)> done);
  /// Edits `client_id` can undo / redo on `object` (or skin) now (tests, tools); 0 for an unknown
  /// name.
  std::pair<size_t, size_t> UndoDepth(const std::string& object, uint64_t client_id);
  /// The history view (issue 15, undo.cc; the query already checked by DecodeHistoryRequest):
  /// the object's edits as its undo history holds them, newest first, at most query.limit, only
  /// query.author's when set; read on the compute thread between two edits, changing nothing.
  /// `done` gets the answer there (it must only post); its error is NotFound for an unknown
  /// object.
  void History(codec::HistoryQuery query, std::function<void(HistoryOutcome)> done);

  /// Names the authenticated user behind `client_id` (named users; a session calls it once
  /// authenticated): every log record of that client's edits carries the name from then on
  /// (codec::AppendRecordUser), and the history view shows it and filters by it. Recovery
  /// learns the names from the records it replays. The most recent kMaxNamedAuthors are kept.
  /// Thread safety: any thread.
  void NameAuthor(uint64_t client_id, std::string user);
  /// The user named for `client_id`, empty if none.
  std::string AuthorUser(uint64_t client_id) const;
  static constexpr size_t kMaxNamedAuthors = 16384;

  /// Whose share of the compute thread the calling thread's requests take (set by a session
  /// around each request it handles: its named user's, else its source address's key, never 0).
  /// The compute work of requests made while it is alive (edits, subscriptions, interest moves,
  /// late-join copies, unsubscriptions) is that requester's: each requester gets a fair share
  /// of the compute thread by measured cost and its own work keeps its order, so one client's
  /// heavy or many requests delay another's by at most the one job of it in service. Without
  /// one (tests, tools, the scene itself), work is the scene's own, served after everything
  /// posted before it.
  class RequesterScope {
   public:
    explicit RequesterScope(uint64_t requester);
    ~RequesterScope();
    RequesterScope(const RequesterScope&) = delete;
    RequesterScope& operator=(const RequesterScope&) = delete;

   private:
    uint64_t previous_;
  };
  /// The calling thread's RequesterScope key, 0 for none.
  static uint64_t CurrentRequester();

  /// Tasks queued for the compute thread and not yet started (edits, joins, subscriptions).
  size_t compute_queue_depth() const { return queue_depth_.load(std::memory_order_relaxed); }
  /// Edits applied and waiting for the edit log to become durable before they are acknowledged.
  size_t acks_awaiting_durability() const;
  /// Durations of the edit log's fdatasync calls since start.
  LatencyHistogram::Snapshot log_sync_seconds() const;

  /// Failures of the compute thread, join worker and mesher, and late-join refusals, since start.
  struct TaskStats {
    std::atomic<uint64_t> failures{0};       // tasks (or mesh chunks) that threw
    std::atomic<uint64_t> joins_refused{0};  // late joins over limits.max_pending_joins
    // Compute-thread jobs chosen while an older job of another requester waited (fair sharing
    // at work), and requesters (RequesterScope) with a job waiting now.
    std::atomic<uint64_t> passed_over{0};
    std::atomic<size_t> waiting_sessions{0};
  };
  TaskStats& task_stats() { return task_stats_; }

  /// Tests only: `hook(operation)` runs before each compute-thread task, each join
  /// serialisation and each mesh chunk encode ("mesh chunk"), inside the exception boundary, so
  /// a hook that throws fails that task as an exception from OpenVDB would. Null removes it.
  void InjectTaskFaultForTesting(std::function<void(const std::string& operation)> hook);

  /// Tests only: `observer` hears each step of the commit pipeline for every edit, with the edit
  /// log's last appended and durable sequences at that moment: "appended" (its records are in
  /// the log), "applied" (the scene changed) and "answered" (the requester is told). Called on
  /// the compute thread or the log's durability thread; null removes it.
  struct CommitEvent {
    std::string step;
    const char* operation = "";
    uint64_t seq = 0;  // the edit's last record
    uint64_t log_last_seq = 0;
    uint64_t log_durable_seq = 0;
  };
  void ObserveCommitsForTesting(std::function<void(const CommitEvent&)> observer);

  /// What recovery found at start-up.
  const std::string& recovery_summary() const { return recovery_summary_; }

 private:
  explicit Scene(const ServerConfig& config);
  void Run();
  // Queues `run` for the compute thread; `operation` names it in logs and errors. If `run`
  // throws, the exception is logged and `fail` gets Internal naming the operation; the thread
  // then serves the next task. A task that answers a requester does so through an AnswerOnce
  // wrapper that `fail` shares, or as its last step (so `fail` runs only when it did not).
  void Post(const char* operation, std::function<void(const Status&)> fail,
            std::function<void()> run);
  // A task without a requester to answer: an exception is logged and counted.
  void Post(const char* operation, std::function<void()> run) {
    Post(operation, nullptr, std::move(run));
  }
  // The same for work a client asked for (`requester`: CurrentRequester(), 0 for the scene's
  // own): in order with the requester's other work, shared fairly with others' (FairQueue).
  void Post(uint64_t requester, const char* operation, std::function<void(const Status&)> fail,
            std::function<void()> run);
  void Post(uint64_t requester, const char* operation, std::function<void()> run) {
    Post(requester, operation, nullptr, std::move(run));
  }
  // The scene's background work that needs no earlier job done first: ahead of everything.
  void PostFirst(const char* operation, std::function<void(const Status&)> fail,
                 std::function<void()> run);
  void JoinLoop();
  // The commit pipeline (commit.h, commit.cc): every edit kind is an EditOp, nested here so
  // that it reaches the parts of the scene it edits.
  struct StrokeOp;    // scene.cc
  struct PaintOp;     // paint.cc
  struct SweepOp;     // skins.cc
  struct BallEditOp;  // skins.cc
  struct ModelOp;     // models.cc
  struct UndoOp;      // undo.cc
  // Per object, every stroke since its last snapshot with what undo needs (compute thread).
  std::map<std::string, std::unique_ptr<EditHistory>> histories_;
  EditHistory& HistoryOf(const std::string& object);
  // Forgets every object's history.
  void ClearHistories(const std::string& why);
  // An object's history is kept beside its snapshot of round `seq` (history_file.h): serialised
  // on the compute thread, written by the snapshot writer after that snapshot, so a restart from
  // any kept snapshot undoes what was undoable before it, and the compute thread never waits
  // for the disk.
  // Recovery: the history kept with the snapshot the object was loaded from (an older or
  // missing one: an empty history, and a warning).
  void LoadHistory(const std::string& object, uint64_t snapshot_seq);
  void Commit(std::shared_ptr<EditOp> op);
  void RunCommit(const std::shared_ptr<EditOp>& op);
  // `out`, or, when the ownership fence no longer holds, a refusal carrying its error.
  CommitOutcome Fenced(const CommitOutcome& out) const;
  std::shared_ptr<const cluster::OwnershipFence> fence_;  // set before serving; null: always owner
  // Queues `answer` until the log (and under sync the standby's copy) is durable up to `seq`
  // (in sequence order with every other).
  void AnswerWhenDurable(uint64_t seq, std::function<void()> answer);
  void MaybeSnapshot(bool force = false);
  void ReleaseDurable(uint64_t durable_seq);
  void RefreshInfoLocked();
  // Ball skins and contour subscriptions (skins.h), compute thread only; saved under
  // data_dir/skins at each snapshot, the logged ball edits replayed past them at start.
  SkinBook skins_;
  // Hyperpatch models of `model` objects (models.h), compute thread only; saved under
  // data_dir/models at each snapshot, the log replayed past them at start.
  ModelBook models_;
  // Replicas (replication_hub.h) and viewers' mesh chunks (mesh_feed.h): driven from the
  // compute thread; the feed meshes on its own thread, stopped first at shutdown.
  ReplicationHub replication_;
  MeshFeed mesh_feed_;

  ServerConfig config_;
  levelset::ValidEditSettings settings_;  // from config_.scene, validated once by Open
  std::map<std::string, levelset::Sculpture> sculptures_;  // compute thread only
  std::unique_ptr<store::EditLog> log_;
  std::unique_ptr<store::SnapshotStore> snapshots_;
  // The newest client_seq of every (edit kind, client): resends are acknowledged, not applied.
  ResendFilter resend_;  // compute thread only
  // Cluster fencing: per (edit kind, client), the lowest client_seq refused while this member
  // did not hold its scene. Later requests of that client are refused too until it resends that
  // one, so no request is applied past a refused one and a resend is never taken for a
  // duplicate of a later request (compute thread only; one entry per client so refused).
  std::map<std::pair<ResendStream, uint64_t>, uint64_t> fenced_from_;
  mutable std::mutex authors_mu_;
  std::map<uint64_t, std::string> author_users_;  // NameAuthor, at most kMaxNamedAuthors
  std::deque<uint64_t> author_order_;             // oldest naming first
  uint64_t next_seq_ = 1;                          // compute thread only
  // Where each run of one ownership epoch begins in the log, first seq -> epoch (from recovery,
  // then extended by the commit pipeline): the epoch the history view shows for an edit.
  // Compute thread only.
  std::map<uint64_t, uint64_t> epoch_runs_;
  // The highest epoch in the log (compute thread only): nothing is logged under a lower one.
  uint64_t highest_epoch_ = 0;
  uint64_t EpochAt(uint64_t seq) const;
  uint64_t edits_since_snapshot_ = 0;
  double tail_apply_s_ = 0;  // stroke apply time since the last snapshot (compute thread)
  double last_snapshot_time_ = 0;
  // Bounded log: once every object's snapshot of a round is durable (with the resend table,
  // skins and models saved at its seq), the log is dropped up to the previous complete round,
  // so a damaged newest snapshot can still fall back to the previous one plus the longer tail.
  bool SaveResendTable(uint64_t seq);
  void OnSnapshotRoundDurable(uint64_t seq);
  std::mutex trim_mu_;
  uint64_t last_round_seq_ = 0;  // guarded by trim_mu_
  std::atomic<uint64_t> applied_seq_{0};
  std::string recovery_summary_;

  mutable std::mutex info_mu_;
  SceneSummary info_;
  std::map<std::string, levelset::Aabb> bounds_;

  // Answers waiting for durability (the local log's, and the standby's under sync), answered in
  // sequence order. Made in Open, before the log reports durability to it.
  std::unique_ptr<AckGate> acks_;

  // Late joins (RequestJoinState): admitted up to limits.max_pending_joins, serialised in order
  // on one worker joined at shutdown. A queued join runs with `cancelled` = true when the scene
  // stops before it was served.
  mutable std::mutex join_mu_;
  std::condition_variable join_cv_;
  struct JoinWork {
    std::function<void(bool cancelled)> run;
    std::function<void(const Status&)> fail;  // when `run` throws
  };
  std::deque<JoinWork> join_queue_;
  size_t joins_pending_ = 0;
  bool join_stop_ = false;
  std::thread join_worker_;

  TaskStats task_stats_;
  struct Job {
    const char* operation = "";
    std::function<void()> run;
    std::function<void(const Status&)> fail;
  };
  std::function<void(const std::string&)> fault_hook_;  // guarded by jobs_mu_
  std::mutex observer_mu_;
  std::function<void(const CommitEvent&)> commit_observer_;  // guarded by observer_mu_
  void Observe(const char* step, const char* operation, uint64_t seq);
  std::mutex jobs_mu_;
  std::condition_variable jobs_cv_;
  FairQueue<Job> jobs_;                 // guarded by jobs_mu_
  std::atomic<size_t> queue_depth_{0};  // jobs_.size(), read without jobs_mu_
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_SCENE_H_
