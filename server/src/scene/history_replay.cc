/// @brief HistoryReplay: logged edits through an object's undo history, as live.
#include "scene/history_replay.h"

#include <spdlog/spdlog.h>

#include "scene/commit.h"
#include "scene/edit_history.h"
#include "scene/skins.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::server {

Status HistoryReplay::Apply(levelset::Sculpture& sculpture, EditHistory& history, uint64_t seq,
                            const codec::EditLogRecord& record) {
  const auto* r = std::get_if<codec::StrokePoseRecord>(&record);
  if (!r) batch_.clear();
  if (auto* w = std::get_if<codec::SweepRecord>(&record)) {
    return ReplaySweep(sculpture, history, seq, *w);
  }
  if (auto* p = std::get_if<codec::PaintRecord>(&record)) {
    auto res = history.ApplyPaint(sculpture, seq, HistoryAuthor(p->client_id), p->paint);
    if (!res.ok()) {
      spdlog::warn("paint at seq {} refused on replay: {}", seq, res.status().ToString());
    }
    return Status::Ok();
  }
  if (auto* u = std::get_if<codec::UndoRecord>(&record)) {
    if (u->target_book != codec::kUndoObjectBook) return Status::Ok();
    const std::string author = HistoryAuthor(u->client_id);
    auto out = u->redo ? history.Redo(sculpture, author) : history.Undo(sculpture, author, seq);
    if (!out.ok()) {
      spdlog::warn("{} at seq {} refused on replay: {}", u->redo ? "redo" : "undo", seq,
                   out.status().ToString());
    }
    return Status::Ok();
  }
  if (!r) return Status::Ok();
  if (r->pose_index == 0 || r->pose_count <= 1) batch_.clear();
  batch_.push_back(r->edit);
  if (r->completes()) {
    // An edit the live server refused after logging it is refused identically here.
    (void)history.Apply(sculpture, seq, HistoryAuthor(r->client_id), batch_, settings_,
                        r->commit_ms);
    batch_.clear();
  }
  return Status::Ok();
}

}  // namespace sculpt::server
