/// @brief The one commit pipeline (Scene::Commit) and the log-record decoder; the pipeline hands
/// each edit's changed leaves to the replication hub and the mesh feed.
#include "scene/commit.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <iterator>

#include "cluster/ownership_fence.h"
#include "scene/scene.h"
#include "store/edit_log.h"

namespace sculpt::server {
namespace {

double NowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

StatusOr<LoggedEdit> DecodeLogRecord(uint64_t seq, const std::string& payload) {
  SCULPT_ASSIGN_OR_RETURN(codec::EditLogRecord record, codec::DecodeLogRecord(seq, payload));
  LoggedEdit e;
  if (const auto* r = std::get_if<codec::StrokePoseRecord>(&record)) {
    e.stream = ResendStream::kStrokes;
    e.client_id = r->client_id;
    e.client_seq = r->client_seq;
    e.object = r->object;
    // Logs written before strokes were grouped may end in part of one.
    e.completes = r->completes();
  } else if (const auto* p = std::get_if<codec::PaintRecord>(&record)) {
    e.stream = ResendStream::kPaints;
    e.client_id = p->client_id;
    e.client_seq = p->paint.client_seq;
    e.object = p->paint.object;
  } else if (const auto* w = std::get_if<codec::SweepRecord>(&record)) {
    e.stream = ResendStream::kSweeps;
    e.client_id = w->client_id;
    e.client_seq = w->client_seq;
    e.object = w->object;
  } else if (const auto* m = std::get_if<codec::ModelRecord>(&record)) {
    // Changes the model, not the voxels (ModelBook): no object.
    e.stream = ResendStream::kModels;
    e.client_id = m->client_id;
    e.client_seq = m->edit.client_seq;
  } else if (const auto* b = std::get_if<codec::BallEditRecord>(&record)) {
    e.stream = ResendStream::kBallEdits;
    e.client_id = b->client_id;
    e.client_seq = b->edit.client_seq;
  } else if (const auto* u = std::get_if<codec::UndoRecord>(&record)) {
    e.stream = ResendStream::kUndos;
    e.client_id = u->client_id;
    e.client_seq = u->client_seq;
    // An undo of a skin's ball edit names the skin, not an object (no sculpture changes).
    if (u->target_book != codec::kUndoSkinBook) e.object = u->object;
  }
  e.record = std::move(record);
  return e;
}

// ---------------------------------------------------------------------------------------------
// The pipeline

void Scene::Commit(std::shared_ptr<EditOp> op) {
  const char* operation = op->operation();
  auto fail = [op](const Status& st) {
    CommitOutcome out;
    out.status = st;
    out.client_seq = op->client_seq();
    op->Answer(out);
  };
  Post(CurrentRequester(), operation, fail, [this, op] { RunCommit(op); });
}

void Scene::ObserveCommitsForTesting(std::function<void(const CommitEvent&)> observer) {
  std::lock_guard<std::mutex> lock(observer_mu_);
  commit_observer_ = std::move(observer);
}

void Scene::Observe(const char* step, const char* operation, uint64_t seq) {
  std::function<void(const CommitEvent&)> observer;
  {
    std::lock_guard<std::mutex> lock(observer_mu_);
    observer = commit_observer_;
  }
  if (!observer) return;
  CommitEvent e;
  e.step = step;
  e.operation = operation;
  e.seq = seq;
  e.log_last_seq = log_->last_seq();
  e.log_durable_seq = log_->durable_seq();
  observer(e);
}

uint64_t Scene::EpochAt(uint64_t seq) const {
  auto it = epoch_runs_.upper_bound(seq);
  return it == epoch_runs_.begin() ? 0 : std::prev(it)->second;
}

void Scene::AnswerWhenDurable(uint64_t seq, std::function<void()> answer) {
  acks_->Hold(seq, std::move(answer));
  ReleaseDurable(log_->durable_seq());
}

CommitOutcome Scene::Fenced(const CommitOutcome& out) const {
  if (!fence_) return out;
  Status held = fence_->Check();
  if (held.ok()) return out;
  // Not an ack: no sequence, no records, so the requester hears a refusal it may resend.
  CommitOutcome refused;
  refused.status = std::move(held);
  refused.client_seq = out.client_seq;
  return refused;
}

void Scene::RunCommit(const std::shared_ptr<EditOp>& op) {
  CommitOutcome out;
  out.client_seq = op->client_seq();
  // Cluster fencing: a member that is not the scene's owner now sequences nothing, and (below)
  // acknowledges nothing, also what it logged while it still was.
  if (fence_) {
    const std::pair<ResendStream, uint64_t> key{op->stream(), op->client_id()};
    if (Status held = fence_->Check(); !held.ok()) {
      fenced_from_.try_emplace(key, op->client_seq());
      out.status = std::move(held);
      return op->Answer(out);
    }
    if (auto it = fenced_from_.find(key); it != fenced_from_.end()) {
      if (op->client_seq() > it->second) {
        out.status = Status(Status::Code::kUnavailable,
                            std::string(op->operation()) + " client_seq " +
                                std::to_string(op->client_seq()) + " follows client_seq " +
                                std::to_string(it->second) +
                                ", which was refused while this member did not hold the scene: "
                                "reconnect and resend from " +
                                std::to_string(it->second));
        return op->Answer(out);
      }
      if (op->client_seq() == it->second) fenced_from_.erase(it);  // resent: in order again
    }
  }
  if (resend_.IsResend(op->stream(), op->client_id(), op->client_seq())) {
    // Already applied: acknowledged once everything logged so far is durable, never re-applied.
    out.duplicate = true;
    op->Duplicate(*this);
    return AnswerWhenDurable(next_seq_ - 1, [this, op, out] {
      Observe("answered", op->operation(), out.global_seq_last);
      op->Answer(Fenced(out));
    });
  }
  const uint64_t first = next_seq_;
  std::vector<std::string> records;
  if (Status s = op->Prepare(*this, first, &records); !s.ok()) {
    out.status = std::move(s);
    return op->Answer(out);
  }
  if (records.empty()) {
    out.status = Internal(std::string(op->operation()) + " prepared no log record");
    return op->Answer(out);
  }
  // The log names who made each edit (named users).
  if (const std::string user = AuthorUser(op->client_id()); !user.empty()) {
    for (std::string& r : records) codec::AppendRecordUser(&r, user);
  }
  // Cluster mode: the epoch under which this member sequenced the edit (the fence held just
  // above), so every record of every kind says which ownership wrote it, and recovery can
  // refuse a log whose epochs go backwards. None on a single process (the bytes stay as they
  // were).
  const uint64_t epoch = fence_ ? fence_->epoch() : 0;
  // A log's epochs never go backwards (recovery refuses such a log): a member holding an older
  // epoch than one already logged here is a stale owner, whatever its fence says, and logs
  // nothing. The agent never grants one; this keeps a bug there from making the data directory
  // unable to start. Epoch 0 (a single process) is never refused, as in recovery.
  if (epoch != 0 && epoch < highest_epoch_) {
    spdlog::error("refusing {} client_seq {}: this member holds epoch {} but the log already "
                  "holds epoch {}",
                  op->operation(), op->client_seq(), epoch, highest_epoch_);
    out.status = Status(Status::Code::kUnavailable,
                        std::string(op->operation()) + " refused: this member holds the scene at "
                        "epoch " + std::to_string(epoch) + ", lower than epoch " +
                        std::to_string(highest_epoch_) +
                        " already in its log (a stale owner); reconnect through another member");
    return op->Answer(out);
  }
  for (std::string& r : records) codec::AppendRecordEpoch(&r, epoch);
  // One group: recovery sees the whole edit or none of it, so a crash between two of a stroke's
  // poses cannot leave part of it applied and its resend refused.
  const Status a = records.size() == 1 ? log_->Append(first, records.front())
                                       : log_->AppendGroup(first, records);
  if (!a.ok()) {
    spdlog::critical("edit log append failed at seq {}: {}", first, a.ToString());
    out.status = a;
    return op->Answer(out);
  }
  const uint64_t last = first + records.size() - 1;
  next_seq_ = last + 1;
  if (epoch_runs_.empty() ? epoch != 0 : epoch != epoch_runs_.rbegin()->second) {
    epoch_runs_.emplace(first, epoch);
  }
  highest_epoch_ = std::max(highest_epoch_, epoch);
  resend_.Record(op->stream(), op->client_id(), op->client_seq());
  Observe("appended", op->operation(), last);

  const double t0 = NowSeconds();
  Applied applied = op->Apply(*this);
  tail_apply_s_ += NowSeconds() - t0;
  applied_seq_ = last;
  edits_since_snapshot_ += records.size();
  Observe("applied", op->operation(), last);

  levelset::Sculpture* sculpture = nullptr;
  if (!applied.object.empty()) {
    auto it = sculptures_.find(applied.object);
    if (it != sculptures_.end()) sculpture = &it->second;
  }
  // Cluster mode: the records of an edit no EditBroadcast carries (every kind but an applied
  // stroke) go to the standby as logged, before the leaves of the same edit, so its copy logs
  // everything this log holds and recovery from it rebuilds skins, models and histories.
  const bool broadcast = applied.status.ok() && sculpture && applied.replay;
  const bool shipped = !broadcast && replication_.ShipRecords(first, records);
  if (applied.status.ok() && sculpture) {
    // Leaf versions always (cheap), so a replica subscribing later resyncs by version.
    replication_.RecordVersions(applied.object, applied.dirty_leaves, last);
    mesh_feed_.MarkDirty(applied.object, applied.dirty_leaves);
    replication_.Replicate(applied.object, *sculpture, applied.dirty_leaves, first, last,
                           op->client_id(), op->client_seq(),
                           applied.replay ? &*applied.replay : nullptr);
  }
  {
    std::lock_guard<std::mutex> lock(info_mu_);
    if (sculpture && applied.bounds_may_change) bounds_[applied.object] = sculpture->WorldBounds();
    RefreshInfoLocked();
  }
  out.status = applied.status;
  out.global_seq_first = first;
  out.global_seq_last = last;
  out.records = static_cast<uint32_t>(records.size());
  // Replicate or ShipRecords sends a whole-object standby every edit; without a standby
  // subscribed nothing reaches a copy, so under sync the answer must not wait for one.
  if (!(applied.status.ok() && sculpture) && !shipped) acks_->Skip(first, last);
  AnswerWhenDurable(last, [this, op, out] {
    Observe("answered", op->operation(), out.global_seq_last);
    op->Answer(Fenced(out));
  });
  MaybeSnapshot();
  if (applied.status.ok() && sculpture) {
    skins_.SendSlices(applied.object, *sculpture, applied.dirty_leaves, applied_seq_.load());
  }
}

}  // namespace sculpt::server
