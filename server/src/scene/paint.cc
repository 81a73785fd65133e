/// @brief Painting material fractions (issue 7): checks off the wire, the edit-log form that
/// recovery replays, and the scene's paint path (validate, log, apply, replicate, ack once
/// durable). The Scene's part runs on the compute thread.
#include "scene/paint.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "scene/answer_once.h"
#include "scene/log_payload.h"
#include "scene/scene.h"
#include "sculpt/codec/frame.h"
#include "sculpt/core/check.h"
#include "sculpt/levelset/region.h"
#include "store/edit_log.h"

namespace sculpt::server {
namespace {

// A serialised EditRecord never starts with 0x00 or 0x01 (field number 0 is not a valid tag);
// sweeps take 0x00 (skins.cc).
constexpr size_t kMaxNameBytes = 64;

Vec3 V(const v1::Vec3f& v) { return {v.x(), v.y(), v.z()}; }

v1::PaintAck Refused(const Status& st, uint64_t client_seq) {
  const codec::FieldError fe = codec::SplitFieldError(st);
  v1::PaintAck a;
  a.set_client_seq(client_seq);
  a.set_accepted(false);
  v1::Error* e = a.mutable_error();
  e->set_code(st.code() == Status::Code::kNotFound             ? v1::ERROR_CODE_NOT_FOUND
              : st.code() == Status::Code::kInvalidArgument    ? v1::ERROR_CODE_INVALID_ARGUMENT
              : st.code() == Status::Code::kFailedPrecondition ? v1::ERROR_CODE_FAILED_PRECONDITION
                                                               : v1::ERROR_CODE_INTERNAL);
  e->set_field(fe.field);
  e->set_value(fe.value);
  e->set_allowed_range(fe.allowed_range);
  e->set_message(fe.message);
  e->set_client_seq(client_seq);
  return a;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Checks off the wire

Status ValidatePaintEdit(const v1::PaintEdit& e, const codec::StrokeLimits& limits, int materials) {
  if (e.object().empty() || e.object().size() > kMaxNameBytes) {
    return InvalidArgument("PaintEdit.object=" + e.object() + " outside names of 1..64 bytes");
  }
  if (materials <= 0) {
    return FailedPrecondition("PaintEdit.object=" + e.object() +
                              " outside scenes that declare materials (this one declares none)");
  }
  if (e.tool() != v1::TOOL_KIND_SPHERE && e.tool() != v1::TOOL_KIND_ELLIPSOID &&
      e.tool() != v1::TOOL_KIND_BOX) {
    return InvalidArgument("PaintEdit.tool=" + std::to_string(e.tool()) +
                           " outside {1 (SPHERE), 2 (ELLIPSOID), 3 (BOX)}");
  }
  const double dx = limits.voxel_size;
  const double lo = 0.5 * dx;
  const double hi = levelset::kMaxPaintToolVoxels * dx;
  SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.tool_size.x", e.tool_size().x(), lo, hi));
  if (e.tool() != v1::TOOL_KIND_SPHERE) {
    SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.tool_size.y", e.tool_size().y(), lo, hi));
    SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.tool_size.z", e.tool_size().z(), lo, hi));
  }
  const Vec3 p = V(e.position());
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("PaintEdit.position", p));
  const double m = limits.bounds_margin;
  const double pc[3] = {p.x, p.y, p.z};
  const double bl[3] = {limits.bounds.min.x, limits.bounds.min.y, limits.bounds.min.z};
  const double bh[3] = {limits.bounds.max.x, limits.bounds.max.y, limits.bounds.max.z};
  const char* axis[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    SCULPT_RETURN_IF_ERROR(
        CheckRange(std::string("PaintEdit.position.") + axis[a], pc[a], bl[a] - m, bh[a] + m));
  }
  if (e.fractions_size() > 0) {
    // A fill: the vector itself goes into the sculpture, so it must lie in the simplex (seed 001
    // (4.2)): negative, NaN or a sum off 1 by more than 1e-6 is refused by name.
    return levelset::ValidateFractionVector(
        "PaintEdit.fractions", std::span<const double>(e.fractions().data(), e.fractions_size()),
        materials);
  }
  if (e.material() >= static_cast<uint32_t>(materials)) {
    return InvalidArgument("PaintEdit.material=" + std::to_string(e.material()) + " outside [0, " +
                           std::to_string(materials - 1) + "]");
  }
  return CheckRange("PaintEdit.weight", e.weight(), 0.0, 1.0);
}

levelset::ToolShape ToolFromPaint(const v1::PaintEdit& e) {
  const Vec3 c = V(e.position());
  const Vec3 s = V(e.tool_size());
  switch (e.tool()) {
    case v1::TOOL_KIND_ELLIPSOID:
      return levelset::ToolShape::Ellipsoid(c, s);
    case v1::TOOL_KIND_BOX:
      return levelset::ToolShape::Box(c, s);
    default:
      return levelset::ToolShape::Sphere(c, s.x);
  }
}

StatusOr<levelset::MaterialEditResult> ApplyPaint(levelset::Sculpture& sculpture,
                                                  const v1::PaintEdit& e) {
  const levelset::ToolShape tool = ToolFromPaint(e);
  if (e.fractions_size() > 0) {
    return levelset::FillMaterial(
        sculpture, tool, std::span<const double>(e.fractions().data(), e.fractions_size()));
  }
  return levelset::PaintMaterial(sculpture, tool, static_cast<int>(e.material()), e.weight());
}

// ---------------------------------------------------------------------------------------------
// Paints in the edit log

bool IsPaintPayload(const std::string& payload) { return HasLogTag(payload, LogTag::kPaint); }

std::string PaintPayload(const v1::PaintRecord& r) { return TaggedPayload(LogTag::kPaint, r); }

StatusOr<v1::PaintRecord> ParsePaintPayload(uint64_t seq, const std::string& payload) {
  return ParseTaggedPayload<v1::PaintRecord>(LogTag::kPaint, seq, payload, "a paint");
}

Status ReplayPaintPayload(levelset::Sculpture& sculpture, uint64_t seq,
                          const std::string& payload) {
  SCULPT_ASSIGN_OR_RETURN(v1::PaintRecord r, ParsePaintPayload(seq, payload));
  auto res = ApplyPaint(sculpture, r.edit());
  if (!res.ok())
    spdlog::warn("paint at seq {} refused on replay: {}", seq, res.status().ToString());
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// The scene's paint path

void Scene::ReplicateLeaves(const std::string& object, const levelset::Sculpture& sculpture,
                            const std::vector<levelset::Int3>& dirty, uint64_t seq,
                            uint64_t client_id, uint64_t client_seq) {
  const levelset::LeafVersions& versions = versions_[object];
  const levelset::ReplayState after = levelset::CaptureReplayState(sculpture);
  std::shared_ptr<const std::string> whole;  // shared by every whole-object replica
  auto frame = [&](const std::vector<levelset::Int3>& cells) {
    v1::ServerMessage m;
    v1::LeafDelta* d = m.mutable_leaf_delta();
    d->set_object(object);
    d->set_global_seq(seq);
    d->set_records(levelset::EncodeLeafRecords(sculpture, cells, &versions));
    d->set_record_count(static_cast<uint32_t>(cells.size()));
    d->set_volume(after.volume);
    d->set_reference_volume(after.reference_volume);
    d->set_edits_since_reinit(after.edits_since_reinit);
    d->set_client_id(client_id);
    d->set_client_seq(client_seq);
    auto f = std::make_shared<std::string>();
    codec::AppendMessage(m, f.get());
    repl_stats_.leaf_deltas++;
    repl_stats_.leaf_delta_bytes += f->size();
    return std::shared_ptr<const std::string>(std::move(f));
  };
  for (auto& [id, sub] : subs_) {
    if (sub.object != object) continue;
    if (sub.whole) {
      if (!whole) whole = frame(dirty);
      sub.sink.send(whole);
      continue;
    }
    std::vector<levelset::Int3> cells;
    for (const levelset::Int3& c : dirty) {
      const levelset::VoxelBox cb{c,
                                  {c.x + levelset::kLeafDim - 1, c.y + levelset::kLeafDim - 1,
                                   c.z + levelset::kLeafDim - 1}};
      if (sub.held.Intersects(cb)) cells.push_back(c);
    }
    if (!cells.empty()) sub.sink.send(frame(cells));
  }
}

void Scene::Paint(uint64_t client_id, v1::PaintEdit e, std::function<void(v1::PaintAck)> done) {
  auto once = AnswerOnce(std::move(done));
  auto cb = std::make_shared<std::function<void(v1::PaintAck)>>(once);
  auto fail = [once, seq = e.client_seq()](const Status& st) { once(Refused(st, seq)); };
  Post("paint", fail, [this, client_id, e = std::move(e), cb] {
    auto obj = sculptures_.find(e.object());
    if (obj == sculptures_.end()) {
      return (*cb)(
          Refused(NotFound("PaintEdit.object=" + e.object() + " outside the scene's objects"),
                  e.client_seq()));
    }
    levelset::Sculpture& sculpture = obj->second;
    uint64_t& last = last_paint_seq_[client_id];
    v1::PaintAck ack;
    ack.set_client_seq(e.client_seq());
    uint64_t seq = next_seq_ - 1;
    if (e.client_seq() <= last) {
      // Already applied: acknowledged once everything logged so far is durable.
      ack.set_accepted(true);
      ack.set_duplicate(true);
    } else {
      // The object's own check (its material count) before anything reaches the log.
      if (levelset::MaterialCount(sculpture) == 0) {
        return (*cb)(Refused(FailedPrecondition("PaintEdit.object=" + e.object() +
                                                " outside objects with materials"),
                             e.client_seq()));
      }
      seq = next_seq_++;
      v1::PaintRecord rec;
      rec.set_global_seq(seq);
      rec.set_client_id(client_id);
      *rec.mutable_edit() = e;
      if (const Status a = log_->Append(seq, PaintPayload(rec)); !a.ok()) {
        spdlog::critical("edit log append failed at seq {}: {}", seq, a.ToString());
        return (*cb)(Refused(a, e.client_seq()));
      }
      // Applied from the logged message, exactly as recovery will.
      auto res = ApplyPaint(sculpture, rec.edit());
      applied_seq_ = seq;
      ++edits_since_snapshot_;
      last = e.client_seq();
      ack.set_global_seq(seq);
      if (res.ok()) {
        versions_[e.object()].Record(res->dirty_leaves, seq);
        if (!viewers_.empty()) MarkDirtyChunks(e.object(), res->dirty_leaves);
        if (!subs_.empty()) {
          ReplicateLeaves(e.object(), sculpture, res->dirty_leaves, seq, client_id, e.client_seq());
        }
        ack.set_accepted(true);
        ack.set_changed_voxels(static_cast<uint32_t>(res->changed_voxels));
        ack.set_dirty_leaves(static_cast<uint32_t>(res->dirty_leaves.size()));
      } else {
        ack = Refused(res.status(), e.client_seq());
        ack.set_global_seq(seq);
      }
      std::lock_guard<std::mutex> lock(info_mu_);
      RefreshInfoLocked();
    }
    {
      // Acknowledged once durable, in order with the strokes.
      std::lock_guard<std::mutex> lock(pending_mu_);
      pending_.push_back({seq, StrokeOutcome{}, [cb, ack](const StrokeOutcome&) { (*cb)(ack); }});
    }
    ReleaseDurable(log_->durable_seq());
    MaybeSnapshot();
  });
}

}  // namespace sculpt::server
