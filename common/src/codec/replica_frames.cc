/// @brief Builds the shared replication frames: LeafDelta, EditBroadcast, MeshChunk.
#include "sculpt/codec/replica_frames.h"

#include <utility>

#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
SharedFrame EncodeLeafDelta(LeafDeltaFrame delta) {
  v1::ServerMessage m;
  v1::LeafDelta* d = m.mutable_leaf_delta();
  d->set_object(std::move(delta.object));
  d->set_global_seq(delta.global_seq);
  d->set_records(std::move(delta.records));
  d->set_record_count(delta.record_count);
  d->set_replace_region(delta.replace_region);
  if (delta.region) {
    const levelset::VoxelBox& box = *delta.region;
    for (int v : {box.min.x, box.min.y, box.min.z}) d->add_region_min(v);
    for (int v : {box.max.x, box.max.y, box.max.z}) d->add_region_max(v);
  }
  d->set_volume(delta.state.volume);
  d->set_reference_volume(delta.state.reference_volume);
  d->set_edits_since_reinit(delta.state.edits_since_reinit);
  d->set_client_id(delta.client_id);
  d->set_client_seq(delta.client_seq);
  for (const auto& [key, client_seq] : delta.resend_table) {
    v1::ResendEntry* e = d->add_resend_table();
    e->set_stream(key.first);
    e->set_client_id(key.second);
    e->set_client_seq(client_seq);
  }
  d->set_epoch(delta.epoch);
  for (auto& [path, data] : delta.book_files) {
    v1::BookFile* f = d->add_book_files();
    f->set_path(std::move(path));
    f->set_data(std::move(data));
  }
  d->set_object_history(std::move(delta.object_history));
  return EncodeSharedFrame(m);
}

SharedFrame EncodeLogRecords(const LogRecordsFrame& frame) {
  v1::ServerMessage m;
  v1::LogRecords* r = m.mutable_log_records();
  r->set_first_seq(frame.first_seq);
  if (frame.records) {
    for (const std::string& payload : *frame.records) r->add_records(payload);
  }
  r->set_epoch(frame.epoch);
  return EncodeSharedFrame(m);
}

SharedFrame EncodeEditBroadcast(const EditBroadcastFrame& broadcast) {
  v1::ServerMessage m;
  v1::EditBroadcast* b = m.mutable_edit();
  b->set_object(broadcast.object);
  b->set_global_seq_first(broadcast.global_seq_first);
  if (!b->mutable_stroke()->ParseFromArray(broadcast.stroke.data(),
                                           static_cast<int>(broadcast.stroke.size()))) {
    b->clear_stroke();
  }
  b->mutable_stroke()->clear_object();  // the broadcast names it once
  b->set_client_id(broadcast.client_id);
  b->set_volume(broadcast.before.volume);
  b->set_reference_volume(broadcast.before.reference_volume);
  b->set_edits_since_reinit(broadcast.before.edits_since_reinit);
  b->set_leaves_hash(broadcast.leaves_hash);
  b->set_dirty_leaves(broadcast.dirty_leaves);
  b->set_epoch(broadcast.epoch);
  return EncodeSharedFrame(m);
}

SharedFrame EncodeMeshChunk(MeshChunkFrame chunk) {
  v1::ServerMessage m;
  v1::MeshChunk* c = m.mutable_mesh_chunk();
  c->set_object(std::move(chunk.object));
  for (int32_t k : chunk.key) c->add_key(k);
  c->set_version(chunk.version);
  c->set_chunk_voxels(chunk.chunk_voxels);
  c->set_draco(std::move(chunk.draco));
  c->set_vertices(chunk.vertices);
  c->set_faces(chunk.faces);
  c->set_encode_ms(chunk.encode_ms);
  return EncodeSharedFrame(m);
}

}  // namespace sculpt::codec
