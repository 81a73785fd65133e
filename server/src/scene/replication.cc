/// @brief The scene's replication (issue 4): subscriptions, edit broadcasts for replay, leaf
/// deltas, region loads. Everything here runs on the compute thread, between two edits.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <future>

#include "scene/answer_once.h"
#include "scene/scene.h"
#include "sculpt/codec/frame.h"
#include "sculpt/core/check.h"

namespace sculpt::server {
namespace {

std::shared_ptr<const std::string> Frame(const v1::ServerMessage& m) {
  auto f = std::make_shared<std::string>();
  codec::AppendMessage(m, f.get());
  return f;
}

}  // namespace

StatusOr<levelset::VoxelBox> Scene::HeldBox(const levelset::Sculpture& s,
                                            const std::optional<codec::InterestBox>& interest,
                                            const char* field) const {
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

void Scene::SendRegion(Sub& sub, const levelset::Sculpture& sculpture, uint64_t have_seq,
                       bool replace) {
  levelset::VoxelBox box = sub.held;
  if (sub.whole) {
    const levelset::Aabb b = sculpture.WorldBounds();
    box = levelset::WorldToVoxelBox(sculpture, b.min, b.max).Dilated(kReplicaHaloVoxels);
  }
  const levelset::LeafVersions& versions = versions_[sub.object];
  std::vector<levelset::Int3> cells = replace ? levelset::OccupiedLeafCells(sculpture, box)
                                              : versions.NewerThan(have_seq, sub.whole ? levelset::VoxelBox{} : box);
  levelset::LeafRecordStats st;
  v1::ServerMessage m;
  v1::LeafDelta* d = m.mutable_leaf_delta();
  d->set_object(sub.object);
  d->set_global_seq(applied_seq_.load());
  d->set_records(levelset::EncodeLeafRecords(sculpture, cells, &versions, 3, &st));
  d->set_record_count(static_cast<uint32_t>(cells.size()));
  d->set_replace_region(replace);
  for (int v : {box.min.x, box.min.y, box.min.z}) d->add_region_min(v);
  for (int v : {box.max.x, box.max.y, box.max.z}) d->add_region_max(v);
  const levelset::ReplayState rs = levelset::CaptureReplayState(sculpture);
  d->set_volume(rs.volume);
  d->set_reference_volume(rs.reference_volume);
  d->set_edits_since_reinit(rs.edits_since_reinit);
  auto frame = Frame(m);
  repl_stats_.resyncs++;
  repl_stats_.leaf_delta_bytes += frame->size();
  spdlog::info("replica {}: region of {} leaf cells ({} leaves) to seq {}, {} bytes{}",
               sub.sink.session_id, cells.size(), st.leaves, applied_seq_.load(), frame->size(),
               replace ? " (replace)" : "");
  sub.sink.send(std::move(frame));
}

void Scene::Subscribe(ReplicaSink sink, codec::ReplicaSubscription req,
                      std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto cb = std::make_shared<std::function<void(Status)>>(once);
  auto fail = [once](const Status& st) { once(st); };
  const uint64_t who = CurrentRequester();
  Post(who, "subscribe", fail, [this, sink = std::move(sink), req = std::move(req), cb]() mutable {
    auto it = sculptures_.find(req.object);
    if (it == sculptures_.end()) {
      return (*cb)(
          Outside("Subscribe.object", req.object, "the scene's objects", Status::Code::kNotFound));
    }
    const uint64_t now = applied_seq_.load();
    if (req.have_seq > now) {
      return (*cb)(Outside("Subscribe.have_seq", std::to_string(req.have_seq),
                           std::string("[0, ") + std::to_string(now) +
                               "] (the server's sequence); subscribe with 0 to load anew"));
    }
    Sub sub;
    sub.sink = std::move(sink);
    sub.object = req.object;
    sub.mode = req.mode;
    sub.whole = !req.interest;
    auto held = HeldBox(it->second, req.interest, "Subscribe.interest");
    if (!held.ok()) return (*cb)(held.status());
    sub.held = *held;
    // A replica holding state from before this process started (or before the oldest version
    // kept) cannot be brought forward by leaf versions: it gets its region anew.
    const bool replace = req.have_seq == 0 || req.have_seq < versions_floor_;
    (*cb)(Status::Ok());
    SendRegion(sub, it->second, req.have_seq, replace);
    subs_[sub.sink.session_id] = std::move(sub);
  });
}

void Scene::SetInterest(uint64_t session_id, codec::InterestChange req,
                        std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto cb = std::make_shared<std::function<void(Status)>>(once);
  auto fail = [once](const Status& st) { once(st); };
  Post(CurrentRequester(), "set interest", fail, [this, session_id, req = std::move(req), cb] {
    auto s = subs_.find(session_id);
    if (s == subs_.end() || s->second.object != req.object) {
      return (*cb)(Outside("SetInterest.object", req.object, "this session's subscriptions",
                           Status::Code::kFailedPrecondition));
    }
    const levelset::Sculpture& sculpture = sculptures_.at(req.object);
    const bool whole = !req.interest;
    auto held = HeldBox(sculpture, req.interest, "SetInterest.interest");
    if (!held.ok()) return (*cb)(held.status());
    s->second.whole = whole;
    s->second.held = *held;
    (*cb)(Status::Ok());
    SendRegion(s->second, sculpture, 0, /*replace=*/true);
  });
}

void Scene::Unsubscribe(uint64_t session_id) {
  Post(CurrentRequester(), "unsubscribe", [this, session_id] { subs_.erase(session_id); });
}

void Scene::ReportDivergence(uint64_t session_id, const codec::Divergence& r) {
  repl_stats_.divergences++;
  spdlog::warn("replica {} diverged on {} at seq {}: server hash {:016x}, replica hash {:016x}",
               session_id, r.object, r.global_seq, r.expected_hash, r.actual_hash);
}

uint64_t Scene::RegionHash(const std::string& object, const levelset::VoxelBox& box) {
  std::promise<uint64_t> p;
  auto fail = [&p](const Status&) { p.set_value(0); };
  Post("region hash", fail, [&] {
    auto it = sculptures_.find(object);
    p.set_value(it == sculptures_.end() ? 0 : levelset::RegionHash(it->second, box));
  });
  return p.get_future().get();
}

}  // namespace sculpt::server
