/// @brief Replica: edit replay, leaf records, hash checks, snapshots (issue 4).
#include "sculpt/client/replica.h"

#include <spdlog/spdlog.h>

#include <atomic>

#include "sculpt/codec/replica_sculpture.h"
#include "sculpt/codec/settings.h"
#include "sculpt/codec/stroke.h"

namespace sculpt::client {
namespace {

v1::Box3 ToBox(const levelset::Aabb& b) {
  v1::Box3 out;
  *out.mutable_min() = codec::ToProto(b.min);
  *out.mutable_max() = codec::ToProto(b.max);
  return out;
}

using Clock = std::chrono::steady_clock;

}  // namespace

Replica::Replica(Client& client, ReplicaOptions options)
    : client_(client), options_(std::move(options)) {
  thread_ = std::thread([this] { Run(); });
  client_.SetReplicationHandler([this](v1::ServerMessage&& m) { Enqueue(std::move(m)); });
}

Replica::~Replica() {
  client_.SetReplicationHandler(nullptr);
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

Status Replica::Start() {
  const v1::SceneInfo info = client_.scene_info();
  const v1::ObjectInfo* obj = nullptr;
  for (const v1::ObjectInfo& o : info.objects()) {
    if (o.name() == options_.object) obj = &o;
  }
  if (!client_.joined()) return FailedPrecondition("Replica::Start needs a joined client");
  if (!obj) return NotFound("replica object=" + options_.object + " outside the scene's objects");
  auto settings = codec::SettingsFromProto(info.edit_settings());
  if (!settings.ok()) return settings.status();
  auto empty = codec::EmptyReplicaSculpture(info, *obj);
  if (!empty.ok()) return empty.status();
  {
    std::lock_guard<std::mutex> lock(mu_);
    settings_ = *settings;
    voxel_size_ = obj->voxel_size();
    sculpture_.emplace(std::move(empty).value());
    stats_.seq = 0;
  }
  v1::ClientMessage m;
  v1::Subscribe* s = m.mutable_subscribe();
  s->set_object(options_.object);
  s->set_mode(options_.mode);
  if (options_.interest) *s->mutable_interest() = ToBox(*options_.interest);
  s->set_have_seq(0);
  return client_.SendMessage(m);
}

Status Replica::Resubscribe() {
  v1::ClientMessage m;
  v1::Subscribe* s = m.mutable_subscribe();
  s->set_object(options_.object);
  s->set_mode(options_.mode);
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!sculpture_) return FailedPrecondition("Replica::Resubscribe before Start");
    if (options_.interest) *s->mutable_interest() = ToBox(*options_.interest);
    s->set_have_seq(stats_.seq);
  }
  return client_.SendMessage(m);
}

Status Replica::MoveInterest(std::optional<levelset::Aabb> interest) {
  v1::ClientMessage m;
  v1::SetInterest* s = m.mutable_set_interest();
  s->set_object(options_.object);
  {
    std::lock_guard<std::mutex> lock(mu_);
    options_.interest = interest;
    if (interest) *s->mutable_interest() = ToBox(*interest);
  }
  return client_.SendMessage(m);
}

void Replica::RequestResync() {
  // The server answers SetInterest with the region anew (replace), on the same connection.
  v1::ClientMessage m;
  v1::SetInterest* s = m.mutable_set_interest();
  s->set_object(options_.object);
  if (options_.interest) *s->mutable_interest() = ToBox(*options_.interest);
  (void)client_.SendMessage(m);
}

void Replica::Enqueue(v1::ServerMessage&& m) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back(std::move(m));
  }
  cv_.notify_all();
}

void Replica::Run() {
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    const auto ready = [&] { return stop_ || !queue_.empty(); };
    if (publish_pending_) {
      // An edit is waiting to be published: without this the last edit of a burst would stay
      // unseen by the haptic loop until some later message arrived.
      if (!cv_.wait_until(lock, last_publish_ + options_.snapshot_interval, ready)) {
        busy_ = true;
        lock.unlock();
        Publish(true);
        lock.lock();
        busy_ = false;
        cv_.notify_all();
        continue;
      }
    } else {
      cv_.wait(lock, ready);
    }
    if (stop_) return;
    v1::ServerMessage m = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    Apply(m);
    lock.lock();
    busy_ = false;
    cv_.notify_all();
  }
}

void Replica::Apply(v1::ServerMessage& m) {
  const auto t0 = Clock::now();
  if (m.has_edit()) {
    if (m.edit().object() == options_.object) ApplyBroadcast(m.edit());
  } else if (m.has_leaf_delta()) {
    if (m.leaf_delta().object() == options_.object) ApplyDelta(m.leaf_delta());
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    stats_.apply_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  }
  Publish(false);
}

void Replica::ApplyBroadcast(const v1::EditBroadcast& b) {
  std::vector<levelset::EditRequest> reqs;
  uint64_t author = b.client_id(), author_seq = b.stroke().client_seq();
  if (b.records_size() > 0) {
    for (const v1::EditRecord& r : b.records()) reqs.push_back(codec::EditFromRecord(r));
    author = b.records(0).client_id();
    author_seq = b.records(0).client_seq();
  } else {
    // The compact form: decode the author's stroke as the server did, then round each edit
    // through its record exactly as the server's log and apply do.
    v1::Stroke stroke = b.stroke();
    stroke.set_object(b.object());  // the broadcast names the object once
    auto decoded = codec::DecodeStroke(stroke, codec::ReplicaLimits(voxel_size_));
    if (!decoded.ok()) {
      spdlog::warn("replica: broadcast stroke does not decode: {}", decoded.status().ToString());
    } else {
      for (const levelset::EditRequest& e : decoded->edits) {
        reqs.push_back(codec::EditFromRecord(codec::RecordFromEdit(e)));
      }
    }
  }
  uint64_t mismatch_seq = 0;
  uint64_t actual = 0;
  bool undecodable = false;
  AppliedEdit applied;
  {
    std::lock_guard<std::mutex> lock(mu_);
    stats_.bytes += static_cast<uint64_t>(b.ByteSizeLong());
    if (!sculpture_) {
      ++stats_.errors;
      return;
    }
    undecodable = reqs.empty();
  }
  if (undecodable) {
    // Cannot replay what does not decode: take the region anew instead.
    std::lock_guard<std::mutex> lock(mu_);
    ++stats_.errors;
  }
  if (undecodable) return RequestResync();
  {
    std::lock_guard<std::mutex> lock(mu_);
    const levelset::ReplayState state{b.volume(), b.reference_volume(), b.edits_since_reinit()};
    auto res = levelset::ReplayEdits(*sculpture_, reqs, settings_, state);
    const uint64_t last = b.global_seq_first() + static_cast<uint64_t>(reqs.size()) - 1;
    if (!res.ok()) {
      ++stats_.errors;
      spdlog::warn("replica: replay of seq {} failed: {}", last, res.status().ToString());
      mismatch_seq = last;
    } else {
      actual = levelset::LeavesHash(*sculpture_, res->dirty_leaves);
      if (actual != b.leaves_hash()) {
        ++stats_.hash_mismatches;
        mismatch_seq = last;
        spdlog::warn("replica: seq {} leaves hash {:016x}, server {:016x}", last, actual,
                     b.leaves_hash());
      }
    }
    ++stats_.broadcasts_applied;
    stats_.seq = std::max(stats_.seq, last);
    applied = {author, author_seq, last, true};
  }
  if (mismatch_seq) {
    v1::ClientMessage m;
    v1::DivergenceReport* d = m.mutable_divergence();
    d->set_object(options_.object);
    d->set_global_seq(mismatch_seq);
    d->set_expected_hash(b.leaves_hash());
    d->set_actual_hash(actual);
    (void)client_.SendMessage(m);
    RequestResync();
  }
  AppliedHandler h;
  {
    std::lock_guard<std::mutex> lock(mu_);
    h = on_applied_;
  }
  if (h) h(applied);
}

void Replica::ApplyDelta(const v1::LeafDelta& d) {
  AppliedEdit applied;
  bool resync = false;
  levelset::VoxelBox region;
  {
    std::lock_guard<std::mutex> lock(mu_);
    (d.replace_region() ? stats_.load_bytes : stats_.bytes) += d.records().size();
    if (!sculpture_) {
      ++stats_.errors;
      return;
    }
    if (d.region_min_size() == 3 && d.region_max_size() == 3) {
      region.min = {d.region_min(0), d.region_min(1), d.region_min(2)};
      region.max = {d.region_max(0), d.region_max(1), d.region_max(2)};
    }
    // A region load replaces what the replica held there (stale leaves included).
    if (d.replace_region()) levelset::ClearRegion(*sculpture_, region);
    auto r = levelset::ApplyLeafRecords(*sculpture_, d.records());
    if (!r.ok()) {
      // Records are validated whole before any is written; the replica asks for its region
      // anew rather than run on with a hole.
      ++stats_.errors;
      spdlog::warn("replica: leaf records at seq {} refused: {}", d.global_seq(),
                   r.status().ToString());
      resync = true;
    }
  }
  if (resync) return RequestResync();
  {
    std::lock_guard<std::mutex> lock(mu_);
    levelset::RestoreReplayState(*sculpture_,
                                 {d.volume(), d.reference_volume(), d.edits_since_reinit()});
    if (d.replace_region()) {
      held_ = region;
      ++stats_.region_loads;
    } else {
      ++stats_.deltas_applied;
    }
    stats_.seq = std::max(stats_.seq, d.global_seq());
    applied = {d.client_id(), d.client_seq(), d.global_seq(), false};
  }
  AppliedHandler h;
  {
    std::lock_guard<std::mutex> lock(mu_);
    h = on_applied_;
  }
  if (h && applied.client_id) h(applied);
}

void Replica::Publish(bool force) {
  if (options_.snapshot_interval.count() <= 0) return;
  const auto now = Clock::now();
  std::shared_ptr<const levelset::Sculpture> snap;
  SnapshotHandler handler;
  uint64_t seq = 0;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!sculpture_) return;
    if (!force && now - last_publish_ < options_.snapshot_interval) {
      publish_pending_ = true;
      return;
    }
    publish_pending_ = false;
    last_publish_ = now;
    snap = std::make_shared<const levelset::Sculpture>(sculpture_->Clone());
    ++stats_.snapshots;
    seq = stats_.seq;
    handler = on_snapshot_;
  }
  std::atomic_store(&snapshot_, snap);
  if (handler) handler(std::move(snap), seq);
}

bool Replica::WaitForSeq(uint64_t seq, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout,
                      [&] { return stats_.seq >= seq && queue_.empty() && !busy_; });
}

bool Replica::WaitLoaded(uint64_t loads, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout, [&] { return stats_.region_loads >= loads; });
}

bool Replica::WaitIdle(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout, [&] { return queue_.empty() && !busy_; });
}

uint64_t Replica::StateHash() const {
  std::lock_guard<std::mutex> lock(mu_);
  return sculpture_ ? sculpture_->StateHash() : 0;
}

uint64_t Replica::RegionHash(const levelset::VoxelBox& box) const {
  std::lock_guard<std::mutex> lock(mu_);
  return sculpture_ ? levelset::RegionHash(*sculpture_, box) : 0;
}

levelset::VoxelBox Replica::held() const {
  std::lock_guard<std::mutex> lock(mu_);
  return held_;
}

std::shared_ptr<const levelset::Sculpture> Replica::Snapshot() const {
  return std::atomic_load(&snapshot_);
}

ReplicaStats Replica::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

void Replica::SetAppliedHandler(AppliedHandler handler) {
  std::lock_guard<std::mutex> lock(mu_);
  on_applied_ = std::move(handler);
}

void Replica::SetSnapshotHandler(SnapshotHandler handler) {
  std::lock_guard<std::mutex> lock(mu_);
  on_snapshot_ = std::move(handler);
}

}  // namespace sculpt::client
