/// @brief HistoryReplay: applies an object's logged edits through its stroke undo history as
/// the live server applied them (recovery's log tail, and a standby copy's records).
#ifndef SCULPT_SERVER_SCENE_HISTORY_REPLAY_H_
#define SCULPT_SERVER_SCENE_HISTORY_REPLAY_H_

#include <cstdint>
#include <vector>

#include "sculpt/codec/log_records.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"

namespace sculpt::levelset {
class Sculpture;
}  // namespace sculpt::levelset

namespace sculpt::server {

class EditHistory;

/// The live server applies a stroke's poses as one batch once all are logged, and every
/// stroke, paint, sweep and object undo or redo through the object's EditHistory; replaying
/// the same records in order through the same history gives the same voxels and the same
/// history, so an undo after it replays to the owner's state. Recovery replays an object's log
/// tail with it; a standby's copy replays the records the owner ships it (paints, sweeps,
/// undos, strokes the kernel refused), so its history is the owner's.
/// Thread safety: none; one per replayed stream, on the thread that owns the sculpture.
class HistoryReplay {
 public:
  explicit HistoryReplay(const levelset::ValidEditSettings& settings) : settings_(settings) {}

  /// Applies the record logged at `seq` to `sculpture` through `history`. A stroke's poses
  /// before its last are gathered; a stroke cut short (a pose 0 or another kind before its
  /// last pose) is dropped, as it was neither applied nor acknowledged live. An edit the
  /// kernel refuses is refused as live (warned, nothing recorded). Ball edits, model intents
  /// and undos of their books change no voxels and are left to their books. Always Ok.
  Status Apply(levelset::Sculpture& sculpture, EditHistory& history, uint64_t seq,
               const codec::EditLogRecord& record);

 private:
  levelset::ValidEditSettings settings_;
  std::vector<levelset::EditRequest> batch_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_HISTORY_REPLAY_H_
