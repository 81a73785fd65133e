/// @brief Painting material fractions (issue 7): replaying a logged paint, and
/// the scene's paint path (check against the object, log, apply, replicate, answer once
/// durable). The Scene's part runs on the compute thread.
#include "scene/paint.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>

#include "scene/answer_once.h"
#include "scene/edit_history.h"
#include "scene/scene.h"
#include "sculpt/codec/frame.h"
#include "sculpt/core/check.h"
#include "sculpt/levelset/region.h"
#include "store/edit_log.h"

namespace sculpt::server {
namespace {

// The server's wall clock, ms since 1970: when a paint was committed (the history view).
uint64_t WallClockMs() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

}  // namespace

StatusOr<levelset::MaterialEditResult> ApplyPaint(levelset::Sculpture& sculpture,
                                                  const codec::Paint& p) {
  const levelset::ToolShape tool = p.Tool();
  if (!p.fractions.empty()) return levelset::FillMaterial(sculpture, tool, p.fractions);
  return levelset::PaintMaterial(sculpture, tool, static_cast<int>(p.material), p.weight);
}

// ---------------------------------------------------------------------------------------------
// Paints in the edit log

Status ReplayPaint(levelset::Sculpture& sculpture, uint64_t seq, const codec::PaintRecord& r) {
  // Checked when it was made, against the limits of its time.
  auto res = ApplyPaint(sculpture, r.paint);
  if (!res.ok())
    spdlog::warn("paint at seq {} refused on replay: {}", seq, res.status().ToString());
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// The scene's paint path

// A paint: checked against the object (its material count) before anything reaches the log,
// applied from the logged message exactly as recovery applies it (through the object's undo
// history, which keeps the pre-image of the fractions it writes), replicated as changed leaves
// (it has no replay form).
struct Scene::PaintOp final : EditOp {
  PaintOp(uint64_t client, codec::Paint p, std::function<void(PaintOutcome)> d)
      : client(client), paint(std::move(p)), done(std::move(d)) {}
  const char* operation() const override { return "paint"; }
  ResendStream stream() const override { return ResendStream::kPaints; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return paint.client_seq; }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    auto obj = scene.sculptures_.find(paint.object);
    if (obj == scene.sculptures_.end()) {
      return Outside("PaintEdit.object", paint.object, "the scene's objects",
                     Status::Code::kNotFound);
    }
    if (levelset::MaterialCount(obj->second) == 0) {
      return Outside("PaintEdit.object", paint.object, "objects with materials",
                     Status::Code::kFailedPrecondition);
    }
    codec::PaintRecord record;
    record.global_seq = first_seq;
    record.client_id = client;
    record.paint = paint;
    records->push_back(codec::EncodeLogRecord(record));
    seq = first_seq;
    // Applied as recovery will apply the record (the wire's floats, exactly).
    logged = codec::AsLogged(paint);
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    Applied a;
    a.object = paint.object;
    auto res = scene.HistoryOf(paint.object)
                   .ApplyPaint(scene.sculptures_.at(paint.object), seq, HistoryAuthor(client),
                               logged, WallClockMs());
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
    PaintOutcome a;
    a.status = o.status;
    a.client_seq = o.client_seq;
    if (o.status.ok()) {
      a.duplicate = o.duplicate;
      a.changed_voxels = static_cast<uint32_t>(changed_voxels);
      a.dirty_leaves = static_cast<uint32_t>(dirty_leaves);
    }
    // Also for a paint the kernel refused after it was logged: it holds that sequence.
    if (o.records > 0) a.global_seq = o.global_seq_first;
    done(std::move(a));
  }

  uint64_t client;
  codec::Paint paint;
  std::function<void(PaintOutcome)> done;
  codec::Paint logged;
  uint64_t seq = 0;
  uint64_t changed_voxels = 0;
  size_t dirty_leaves = 0;
};

void Scene::Paint(uint64_t client_id, codec::Paint e, std::function<void(PaintOutcome)> done) {
  Commit(std::make_shared<PaintOp>(client_id, std::move(e), AnswerOnce(std::move(done))));
}

}  // namespace sculpt::server
