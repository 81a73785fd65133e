/// @brief The file an object's stroke undo history is kept in beside each of its snapshots
/// (data_dir/history/<object>.<seq>.bin), written by the owner's snapshot rounds and by a
/// standby's copy, and sent with a region load to the standby (LeafDelta.object_history).
#ifndef SCULPT_SERVER_SCENE_HISTORY_FILE_H_
#define SCULPT_SERVER_SCENE_HISTORY_FILE_H_

#include <cstdint>
#include <string>
#include <string_view>

#include "scene/edit_history.h"
#include "sculpt/core/status.h"

namespace sculpt::server {

/// `history` as kept with the snapshot of round `seq`: magic, seq, payload size, CRC32C of the
/// payload, then EditHistory::Serialize's bytes.
std::string HistoryFileBytes(const EditHistory& history, uint64_t seq);

/// The history in `bytes` (HistoryFileBytes) kept with the snapshot at `snapshot_seq`. DataLoss
/// saying why when it is not a history file, was kept at another sequence, fails its size or
/// checksum, or does not parse (EditHistory::Parse's error); InvalidArgument for bad options.
StatusOr<EditHistory> ParseHistoryFile(std::string_view bytes, uint64_t snapshot_seq,
                                       EditHistoryOptions options);

/// Where the history of `object` kept with the snapshot of round `seq` lives in `data_dir`.
std::string HistoryFilePath(const std::string& data_dir, const std::string& object, uint64_t seq);
/// Before history files were kept per round: one per object, overwritten at every round.
std::string LegacyHistoryFilePath(const std::string& data_dir, const std::string& object);

/// Writes `bytes` durably as HistoryFilePath(data_dir, object, seq) and removes the object's
/// files of older rounds but the newest three (as many as the snapshot store keeps) and its
/// legacy file. Internal on an I/O error (logged; older files are then left).
Status WriteHistoryFile(const std::string& data_dir, const std::string& object, uint64_t seq,
                        const std::string& bytes);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_HISTORY_FILE_H_
