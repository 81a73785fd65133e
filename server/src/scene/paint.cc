/// @brief Painting material fractions (issue 7): checks off the wire, the edit-log form that
/// recovery replays, and the scene's paint path (validate, log, apply, replicate, ack once
/// durable). The Scene's part runs on the compute thread.
#include "scene/paint.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "net/wire_error.h"
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
  v1::PaintAck a;
  a.set_client_seq(client_seq);
  a.set_accepted(false);
  *a.mutable_error() = ToWireError(st, client_seq);
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

std::string PaintPayload(const v1::PaintRecord& r) { return TaggedPayload(LogTag::kPaint, r); }

Status ReplayPaint(levelset::Sculpture& sculpture, uint64_t seq, const v1::PaintRecord& r) {
  auto res = ApplyPaint(sculpture, r.edit());
  if (!res.ok())
    spdlog::warn("paint at seq {} refused on replay: {}", seq, res.status().ToString());
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// The scene's paint path

// A paint: checked against the object (its material count) before anything reaches the log,
// applied from the logged message exactly as recovery applies it, replicated as changed leaves
// (it has no replay form).
struct Scene::PaintOp final : EditOp {
  PaintOp(uint64_t client, v1::PaintEdit e, std::function<void(v1::PaintAck)> d)
      : client(client), edit(std::move(e)), done(std::move(d)) {}
  const char* operation() const override { return "paint"; }
  ResendStream stream() const override { return ResendStream::kPaints; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return edit.client_seq(); }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    auto obj = scene.sculptures_.find(edit.object());
    if (obj == scene.sculptures_.end()) {
      return NotFound("PaintEdit.object=" + edit.object() + " outside the scene's objects");
    }
    if (levelset::MaterialCount(obj->second) == 0) {
      return FailedPrecondition("PaintEdit.object=" + edit.object() +
                                " outside objects with materials");
    }
    record.set_global_seq(first_seq);
    record.set_client_id(client);
    *record.mutable_edit() = edit;
    records->push_back(PaintPayload(record));
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    Applied a;
    a.object = edit.object();
    auto res = ApplyPaint(scene.sculptures_.at(edit.object()), record.edit());
    if (!res.ok()) {
      a.status = res.status();
      return a;
    }
    changed_voxels = res->changed_voxels;
    a.dirty_leaves = std::move(res->dirty_leaves);
    dirty_leaves = a.dirty_leaves.size();
    return a;
  }

  void Answer(const CommitOutcome& o) override {
    v1::PaintAck ack;
    if (!o.status.ok()) {
      ack = Refused(o.status, o.client_seq);
    } else {
      ack.set_client_seq(o.client_seq);
      ack.set_accepted(true);
      ack.set_duplicate(o.duplicate);
      ack.set_changed_voxels(static_cast<uint32_t>(changed_voxels));
      ack.set_dirty_leaves(static_cast<uint32_t>(dirty_leaves));
    }
    if (o.records > 0) ack.set_global_seq(o.global_seq_first);
    done(ack);
  }

  uint64_t client;
  v1::PaintEdit edit;
  std::function<void(v1::PaintAck)> done;
  v1::PaintRecord record;
  uint64_t changed_voxels = 0;
  size_t dirty_leaves = 0;
};

void Scene::Paint(uint64_t client_id, v1::PaintEdit e, std::function<void(v1::PaintAck)> done) {
  Commit(std::make_shared<PaintOp>(client_id, std::move(e), AnswerOnce(std::move(done))));
}

}  // namespace sculpt::server
