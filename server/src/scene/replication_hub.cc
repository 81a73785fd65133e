/// @brief ReplicationHub: subscriptions, edit broadcasts for replay, leaf deltas, region loads.
/// Everything here runs on the scene's compute thread, between two edits.
#include "scene/replication_hub.h"

#include <spdlog/spdlog.h>

#include <optional>
#include <utility>

#include "cluster/ownership_fence.h"
#include "sculpt/codec/replica_frames.h"
#include "sculpt/core/check.h"

namespace sculpt::server {
namespace {

// The index box an interest box selects (dilated by the halo); InvalidArgument naming `field`.
StatusOr<levelset::VoxelBox> HeldBox(const levelset::Sculpture& s,
                                     const std::optional<codec::InterestBox>& interest,
                                     const char* field) {
  if (!interest) {
    const levelset::Aabb b = s.WorldBounds();
    return levelset::WorldToVoxelBox(s, b.min, b.max).Dilated(kReplicaHaloVoxels);
  }
  // Finite corners are the decoder's check; the extent in voxels needs the object.
  const std::string f(field);
  const Vec3 lo = interest->min;
  const Vec3 hi = interest->max;
  const double dx = s.voxel_size();
  const double limit = kMaxInterestVoxels * dx;
  const char* axis[3] = {"x", "y", "z"};
  const double l[3] = {lo.x, lo.y, lo.z};
  const double h[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; ++a) {
    if (!(h[a] >= l[a]) || h[a] - l[a] > limit) {
      return Outside(f + ".max." + axis[a], FormatNumber(h[a]),
                     std::string("[") + FormatNumber(l[a]) + ", " + FormatNumber(l[a] + limit) +
                         std::string("] (min to min + ") + std::to_string(kMaxInterestVoxels) +
                         " voxels; leave interest unset for the whole object)");
    }
  }
  return levelset::WorldToVoxelBox(s, lo, hi).Dilated(kReplicaHaloVoxels);
}

}  // namespace

uint64_t ReplicationHub::epoch() const { return fence_ ? fence_->epoch() : 0; }

void ReplicationHub::SendRegion(Sub& sub, const levelset::Sculpture& sculpture, uint64_t seq,
                                uint64_t have_seq, bool replace) {
  levelset::VoxelBox box = sub.held;
  if (sub.whole) {
    const levelset::Aabb b = sculpture.WorldBounds();
    box = levelset::WorldToVoxelBox(sculpture, b.min, b.max).Dilated(kReplicaHaloVoxels);
  }
  const levelset::LeafVersions& versions = versions_[sub.object];
  std::vector<levelset::Int3> cells =
      replace ? levelset::OccupiedLeafCells(sculpture, box)
              : versions.NewerThan(have_seq, sub.whole ? levelset::VoxelBox{} : box);
  levelset::LeafRecordStats st;
  codec::LeafDeltaFrame d;
  d.object = sub.object;
  d.global_seq = seq;
  d.records = levelset::EncodeLeafRecords(sculpture, cells, &versions, 3, &st);
  d.record_count = static_cast<uint32_t>(cells.size());
  d.replace_region = replace;
  d.region = box;
  d.state = levelset::CaptureReplayState(sculpture);
  if (replace && sub.sink.standby && resend_table_) d.resend_table = *resend_table_;
  if (replace && sub.sink.standby && book_files_) d.book_files = book_files_(seq);
  if (replace && sub.sink.standby && object_history_) {
    d.object_history = object_history_(sub.object, seq);
  }
  const size_t book_files = d.book_files.size();
  d.epoch = epoch();
  codec::SharedFrame frame = codec::EncodeLeafDelta(std::move(d));
  stats_.resyncs++;
  stats_.leaf_delta_bytes += frame->size();
  spdlog::info(
      "replica {}: region of {} leaf cells ({} leaves) to seq {}, {} bytes{}{}",
      sub.sink.session_id, cells.size(), st.leaves, seq, frame->size(), replace ? " (replace)" : "",
      replace && sub.sink.standby ? " with the resend table and " + std::to_string(book_files) +
                                        " book file(s) and the undo history, to the standby"
                                  : std::string());
  sub.sink.send(std::move(frame));
}

void ReplicationHub::Subscribe(ReplicaSink sink, const codec::ReplicaSubscription& req,
                               const levelset::Sculpture* sculpture, uint64_t seq,
                               const std::function<void(Status)>& answer) {
  if (!sculpture) {
    return answer(
        Outside("Subscribe.object", req.object, "the scene's objects", Status::Code::kNotFound));
  }
  if (req.have_seq > seq) {
    return answer(Outside("Subscribe.have_seq", std::to_string(req.have_seq),
                          std::string("[0, ") + std::to_string(seq) +
                              "] (the server's sequence); subscribe with 0 to load anew"));
  }
  Sub sub;
  sub.sink = std::move(sink);
  sub.object = req.object;
  sub.mode = req.mode;
  sub.whole = !req.interest;
  auto held = HeldBox(*sculpture, req.interest, "Subscribe.interest");
  if (!held.ok()) return answer(held.status());
  sub.held = *held;
  // A replica holding state from before this process started (or before the oldest version
  // kept) cannot be brought forward by leaf versions: it gets its region anew.
  const bool replace = req.have_seq == 0 || req.have_seq < versions_floor_;
  answer(Status::Ok());
  SendRegion(sub, *sculpture, seq, req.have_seq, replace);
  subs_[sub.sink.session_id] = std::move(sub);
}

void ReplicationHub::SetInterest(uint64_t session_id, const codec::InterestChange& req,
                                 const levelset::Sculpture* sculpture, uint64_t seq,
                                 const std::function<void(Status)>& answer) {
  auto s = subs_.find(session_id);
  if (s == subs_.end() || s->second.object != req.object || !sculpture) {
    return answer(Outside("SetInterest.object", req.object, "this session's subscriptions",
                          Status::Code::kFailedPrecondition));
  }
  auto held = HeldBox(*sculpture, req.interest, "SetInterest.interest");
  if (!held.ok()) return answer(held.status());
  s->second.whole = !req.interest;
  s->second.held = *held;
  answer(Status::Ok());
  SendRegion(s->second, *sculpture, seq, 0, /*replace=*/true);
}

void ReplicationHub::Unsubscribe(uint64_t session_id) { subs_.erase(session_id); }

void ReplicationHub::ReportDivergence(uint64_t session_id, const codec::Divergence& r) {
  stats_.divergences++;
  spdlog::warn("replica {} diverged on {} at seq {}: server hash {:016x}, replica hash {:016x}",
               session_id, r.object, r.global_seq, r.expected_hash, r.actual_hash);
}

void ReplicationHub::RecordVersions(const std::string& object,
                                    const std::vector<levelset::Int3>& leaves, uint64_t seq) {
  versions_[object].Record(leaves, seq);
}

// An EditBroadcast to replay replicas that hold the edit's footprint, the changed leaves (inside
// what each holds) to every other replica of the object.
bool ReplicationHub::ShipRecords(uint64_t first_seq, const std::vector<std::string>& records) {
  codec::SharedFrame frame;
  bool shipped = false;
  for (auto& [session, sub] : subs_) {
    if (!sub.sink.standby) continue;
    if (!frame) frame = codec::EncodeLogRecords({first_seq, &records, epoch()});
    sub.sink.send(frame);
    shipped = true;
  }
  return shipped;
}

void ReplicationHub::Replicate(const std::string& object, const levelset::Sculpture& sculpture,
                               const std::vector<levelset::Int3>& dirty, uint64_t first_seq,
                               uint64_t last_seq, uint64_t client_id, uint64_t client_seq,
                               const EditReplay* replay) {
  if (subs_.empty()) return;
  const levelset::LeafVersions& versions = versions_[object];
  codec::SharedFrame broadcast;    // built once, shared by replay replicas
  codec::SharedFrame whole_delta;  // built once, shared by whole-object replicas
  const levelset::ReplayState after = levelset::CaptureReplayState(sculpture);
  auto delta_frame = [&](const std::vector<levelset::Int3>& cells) {
    codec::LeafDeltaFrame d;
    d.object = object;
    d.global_seq = last_seq;
    d.records = levelset::EncodeLeafRecords(sculpture, cells, &versions);
    d.record_count = static_cast<uint32_t>(cells.size());
    d.state = after;
    d.client_id = client_id;
    d.client_seq = client_seq;
    d.epoch = epoch();
    codec::SharedFrame f = codec::EncodeLeafDelta(std::move(d));
    stats_.leaf_deltas++;
    stats_.leaf_delta_bytes += f->size();
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
        codec::EditBroadcastFrame b;
        b.object = object;
        b.global_seq_first = first_seq;
        b.stroke = *replay->source;
        b.client_id = client_id;
        b.before = replay->before;
        b.leaves_hash = levelset::LeavesHash(sculpture, dirty);
        b.dirty_leaves = static_cast<uint32_t>(dirty.size());
        b.epoch = epoch();
        broadcast = codec::EncodeEditBroadcast(b);
        stats_.broadcasts++;
        stats_.broadcast_bytes += broadcast->size();
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
