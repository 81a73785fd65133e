/// @brief Edit outcomes → sculpt.v1 acks.
#include "net/wire_acks.h"

#include "net/wire_error.h"

namespace sculpt::server {

v1::SkinAck ToWireAck(const SkinOutcome& o) {
  v1::SkinAck a;
  a.set_client_seq(o.client_seq);
  a.set_accepted(o.status.ok());
  if (!o.status.ok()) {
    *a.mutable_error() = ToWireError(o.status, o.client_seq);
  } else {
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
  a.set_client_seq(o.client_seq);
  a.set_accepted(o.status.ok());
  if (!o.status.ok()) {
    *a.mutable_error() = ToWireError(o.status, o.client_seq);
  } else {
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

}  // namespace sculpt::server
