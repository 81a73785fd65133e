/// @brief The replication frames the server fans out (issue 4): LeafDelta and EditBroadcast to
/// replicas, MeshChunk to viewers, each built from domain values into one length-prefixed
/// ServerMessage frame, serialized once and shared by every session that sends it.
#ifndef SCULPT_CODEC_REPLICA_FRAMES_H_
#define SCULPT_CODEC_REPLICA_FRAMES_H_

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sculpt/codec/shared_frame.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"

namespace sculpt::codec {

/// A LeafDelta: leaf records (levelset::EncodeLeafRecords) holding an object's state through
/// `global_seq`, either one edit's changed leaves (client_id, client_seq: its author) or a
/// region a replica loads (region set; replace_region: clear it first).
struct LeafDeltaFrame {
  std::string object;
  uint64_t global_seq = 0;
  std::string records;
  uint32_t record_count = 0;
  std::optional<levelset::VoxelBox> region;
  bool replace_region = false;
  levelset::ReplayState state;  // the server's tracked volumes after global_seq
  uint64_t client_id = 0;
  uint64_t client_seq = 0;
  /// To the scene's standby with a region load: (stream, client id) -> newest client_seq.
  std::map<std::pair<uint8_t, uint64_t>, uint64_t> resend_table;
  uint64_t epoch = 0;  // the sender's ownership epoch (cluster mode), else 0
  /// To the scene's standby with a region load: the scene's skin and model files as of
  /// global_seq, (path relative to the data directory, bytes).
  std::vector<std::pair<std::string, std::string>> book_files;
  /// To the scene's standby with a region load: the object's stroke undo history as of
  /// global_seq (the history file the owner keeps beside a snapshot), empty when not sent.
  std::string object_history;
};

/// LogRecords, to the scene's standby: log payloads of sequences first_seq.. as the owner logged
/// them.
struct LogRecordsFrame {
  uint64_t first_seq = 0;
  const std::vector<std::string>* records = nullptr;
  uint64_t epoch = 0;
};

/// An EditBroadcast: an edit replay replicas apply with the same kernel. `stroke` is the
/// client's serialized Stroke; the frame names the object once (the stroke's own object field
/// is cleared).
struct EditBroadcastFrame {
  std::string object;
  uint64_t global_seq_first = 0;
  std::string_view stroke;
  uint64_t client_id = 0;
  levelset::ReplayState before;  // the tracked volumes the replica replays from
  uint64_t leaves_hash = 0;      // levelset::LeavesHash over the changed leaves
  uint32_t dirty_leaves = 0;
  uint64_t epoch = 0;  // the sender's ownership epoch (cluster mode), else 0
};

/// A MeshChunk: one chunk's Draco mesh at `version` (empty draco: the chunk holds no surface).
struct MeshChunkFrame {
  std::string object;
  int32_t key[3] = {0, 0, 0};
  uint64_t version = 0;
  uint32_t chunk_voxels = 0;
  std::string draco;
  uint32_t vertices = 0;
  uint32_t faces = 0;
  float encode_ms = 0;
};

/// Each returns the frame (4-byte little-endian length, then the serialized ServerMessage).
/// Every value is representable on the wire, so none fails; a stroke that does not parse
/// leaves the broadcast's stroke empty (the server only passes strokes it decoded).
SharedFrame EncodeLeafDelta(LeafDeltaFrame delta);
SharedFrame EncodeEditBroadcast(const EditBroadcastFrame& broadcast);
SharedFrame EncodeLogRecords(const LogRecordsFrame& frame);
SharedFrame EncodeMeshChunk(MeshChunkFrame chunk);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_REPLICA_FRAMES_H_
