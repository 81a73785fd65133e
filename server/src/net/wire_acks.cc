/// @brief Edit outcomes → sculpt.v1 acks.
#include "net/wire_acks.h"

#include "net/wire_error.h"
#include "sculpt/codec/stroke.h"

namespace sculpt::server {
namespace {

// The fields every edit ack shares: the request's client_seq, whether it was accepted and, if
// not, the error. True when accepted.
template <typename Ack>
bool SetAcceptance(Ack& a, const Status& status, uint64_t client_seq) {
  a.set_client_seq(client_seq);
  a.set_accepted(status.ok());
  if (!status.ok()) *a.mutable_error() = ToWireError(status, client_seq);
  return status.ok();
}

}  // namespace

v1::SkinAck ToWireAck(const SkinOutcome& o) {
  v1::SkinAck a;
  if (SetAcceptance(a, o.status, o.client_seq)) {
    a.set_duplicate(o.duplicate);
    a.set_changed_sections(o.changed_sections);
    a.set_balls(o.balls);
    a.set_volume_after(o.volume_after);
    a.set_dirty_leaves(o.dirty_leaves);
  }
  a.set_global_seq(o.global_seq);
  return a;
}

v1::PaintAck ToWireAck(const PaintOutcome& o) {
  v1::PaintAck a;
  if (SetAcceptance(a, o.status, o.client_seq)) {
    a.set_duplicate(o.duplicate);
    a.set_changed_voxels(o.changed_voxels);
    a.set_dirty_leaves(o.dirty_leaves);
  }
  a.set_global_seq(o.global_seq);
  return a;
}

v1::ModelAck ToWireAck(const ModelOutcome& o) {
  v1::ModelAck a;
  a.set_client_seq(o.client_seq);
  if (o.rejection) {
    a.set_accepted(false);
    a.set_reason(o.rejection->reason);
    a.set_cell(o.rejection->cell);
    a.set_direction(o.rejection->direction);
    a.set_span(o.rejection->span);
    a.set_detail(o.rejection->detail);
  } else if (!o.status.ok()) {
    a.set_accepted(false);
    *a.mutable_error() = ToWireError(o.status, o.client_seq);
  } else {
    a.set_accepted(true);
    a.set_duplicate(o.duplicate);
    a.set_global_seq(o.global_seq);
    a.set_moved_coefficients(o.moved_coefficients);
  }
  a.set_model_version(o.model_version);
  a.set_model_hash(o.model_hash);
  return a;
}

v1::UndoAck ToWireAck(const UndoCommandOutcome& o) {
  v1::UndoAck a;
  a.set_redo(o.redo);
  if (!SetAcceptance(a, o.status, o.client_seq)) {
    a.set_global_seq(o.global_seq);
    return a;
  }
  a.set_duplicate(o.duplicate);
  if (o.duplicate) return a;
  a.set_global_seq(o.global_seq);
  a.set_target_seq(o.target_seq);
  a.set_replayed(o.replayed);
  for (const auto& [author, n] : o.replayed_by) {
    v1::ReplayedEdits* r = a.add_replayed_by();
    r->set_author(author);
    r->set_edits(n);
  }
  a.set_undo_depth(o.undo_depth);
  a.set_redo_depth(o.redo_depth);
  return a;
}

v1::HistoryAnswer ToWireAnswer(const HistoryOutcome& o) {
  v1::HistoryAnswer a;
  a.set_request_id(o.request_id);
  a.set_object(o.object);
  if (!o.status.ok()) {
    *a.mutable_error() = ToWireError(o.status, 0);
    return a;
  }
  a.set_matching(o.matching);
  a.set_held(o.held);
  a.set_cleared(o.cleared);
  for (const HistoryEntry& in : o.entries) {
    v1::HistoryEntry* e = a.add_entries();
    e->set_seq(in.seq);
    e->set_author(in.author);
    e->set_kind(codec::EditKindToProto(in.kind));
    e->set_sweep(in.sweep);
    e->set_poses(in.poses);
    e->set_time_ms(in.wall_ms);
    e->set_undone(in.undone);
    e->set_undoable(in.undoable);
    e->set_kind_name(in.kind_name);
    e->set_user(in.user);
    e->set_epoch(in.epoch);
  }
  return a;
}

}  // namespace sculpt::server
