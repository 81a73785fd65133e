/// @brief The one commit pipeline (Scene::Commit), the log-record decoder and the one way the
/// changed leaves of an edit reach replicas.
#include "scene/commit.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "scene/scene.h"
#include "sculpt/codec/frame.h"
#include "store/edit_log.h"

namespace sculpt::server {
namespace {

double NowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::shared_ptr<const std::string> Frame(const v1::ServerMessage& m) {
  auto f = std::make_shared<std::string>();
  codec::AppendMessage(m, f.get());
  return f;
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
    // Changes the model, not the voxels (Scene::OpenModels): no object.
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
    e.object = u->object;
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

void Scene::AnswerWhenDurable(uint64_t seq, std::function<void()> answer) {
  {
    std::lock_guard<std::mutex> lock(pending_mu_);
    pending_.push_back({seq, std::move(answer)});
  }
  ReleaseDurable(log_->durable_seq());
}

void Scene::RunCommit(const std::shared_ptr<EditOp>& op) {
  CommitOutcome out;
  out.client_seq = op->client_seq();
  if (resend_.IsResend(op->stream(), op->client_id(), op->client_seq())) {
    // Already applied: acknowledged once everything logged so far is durable, never re-applied.
    out.duplicate = true;
    op->Duplicate(*this);
    return AnswerWhenDurable(next_seq_ - 1, [this, op, out] {
      Observe("answered", op->operation(), out.global_seq_last);
      op->Answer(out);
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
  if (applied.status.ok() && sculpture) {
    // Leaf versions always (cheap), so a replica subscribing later resyncs by version.
    versions_[applied.object].Record(applied.dirty_leaves, last);
    if (!viewers_.empty()) MarkDirtyChunks(applied.object, applied.dirty_leaves);
    if (!subs_.empty()) {
      Replicate(applied.object, *sculpture, applied.dirty_leaves, first, last, op->client_id(),
                op->client_seq(), applied.replay ? &*applied.replay : nullptr);
    }
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
  AnswerWhenDurable(last, [this, op, out] {
    Observe("answered", op->operation(), out.global_seq_last);
    op->Answer(out);
  });
  MaybeSnapshot();
  if (applied.status.ok() && sculpture) SendSlices(applied.object, applied.dirty_leaves);
}

// ---------------------------------------------------------------------------------------------
// Replication: an EditBroadcast to replay replicas that hold the edit's footprint, the changed
// leaves (inside what each holds) to every other replica of the object.

void Scene::Replicate(const std::string& object, const levelset::Sculpture& sculpture,
                      const std::vector<levelset::Int3>& dirty, uint64_t first_seq,
                      uint64_t last_seq, uint64_t client_id, uint64_t client_seq,
                      const Applied::Replay* replay) {
  const levelset::LeafVersions& versions = versions_[object];
  std::shared_ptr<const std::string> broadcast;    // built once, shared by replay replicas
  std::shared_ptr<const std::string> whole_delta;  // built once, shared by whole-object replicas
  const levelset::ReplayState after = levelset::CaptureReplayState(sculpture);
  auto delta_frame = [&](const std::vector<levelset::Int3>& cells) {
    v1::ServerMessage m;
    v1::LeafDelta* d = m.mutable_leaf_delta();
    d->set_object(object);
    d->set_global_seq(last_seq);
    d->set_records(levelset::EncodeLeafRecords(sculpture, cells, &versions));
    d->set_record_count(static_cast<uint32_t>(cells.size()));
    d->set_volume(after.volume);
    d->set_reference_volume(after.reference_volume);
    d->set_edits_since_reinit(after.edits_since_reinit);
    d->set_client_id(client_id);
    d->set_client_seq(client_seq);
    auto f = Frame(m);
    repl_stats_.leaf_deltas++;
    repl_stats_.leaf_delta_bytes += f->size();
    return f;
  };
  const levelset::VoxelBox fb =
      replay ? levelset::VoxelBox{replay->footprint.min, replay->footprint.max}
             : levelset::VoxelBox{};
  for (auto& [id, sub] : subs_) {
    if (sub.object != object) continue;
    bool fits = false;
    bool touches = false;
    if (replay) {
      fits = sub.whole || (!replay->footprint.whole_object && sub.held.Contains(fb));
      touches = sub.whole || replay->footprint.whole_object || sub.held.Intersects(fb);
      if (!touches) continue;
    }
    if (fits && sub.mode == codec::ReplicaMode::kReplay) {
      if (!broadcast) {
        v1::ServerMessage m;
        v1::EditBroadcast* b = m.mutable_edit();
        b->set_object(object);
        b->set_global_seq_first(first_seq);
        b->mutable_stroke()->ParseFromString(*replay->source);
        b->mutable_stroke()->clear_object();  // the broadcast names it once
        b->set_client_id(client_id);
        b->set_volume(replay->before.volume);
        b->set_reference_volume(replay->before.reference_volume);
        b->set_edits_since_reinit(replay->before.edits_since_reinit);
        b->set_leaves_hash(levelset::LeavesHash(sculpture, dirty));
        b->set_dirty_leaves(static_cast<uint32_t>(dirty.size()));
        broadcast = Frame(m);
        repl_stats_.broadcasts++;
        repl_stats_.broadcast_bytes += broadcast->size();
      }
      sub.sink.send(broadcast);
    } else if (sub.whole) {
      if (!whole_delta) whole_delta = delta_frame(dirty);
      sub.sink.send(whole_delta);
    } else {
      // The edit reaches beyond what this replica holds (or has no replay form): its changed
      // leaves inside the region.
      std::vector<levelset::Int3> cells;
      for (const levelset::Int3& c : dirty) {
        const levelset::VoxelBox cb{c,
                                    {c.x + levelset::kLeafDim - 1, c.y + levelset::kLeafDim - 1,
                                     c.z + levelset::kLeafDim - 1}};
        if (sub.held.Intersects(cb)) cells.push_back(c);
      }
      // A leaf-delta replica whose region the edit touched hears of the sequence even when no
      // leaf it holds changed.
      if (!cells.empty() || (touches && sub.mode == codec::ReplicaMode::kLeafDelta)) {
        sub.sink.send(delta_frame(cells));
      }
    }
  }
}

}  // namespace sculpt::server
