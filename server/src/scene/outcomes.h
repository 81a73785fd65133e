/// @brief What became of an edit the scene was given, as domain results: the session turns them
/// into the wire's acks (net/wire_acks.h), the scene never builds a wire message for them.
#ifndef SCULPT_SERVER_SCENE_OUTCOMES_H_
#define SCULPT_SERVER_SCENE_OUTCOMES_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "scene/edit_history.h"
#include "sculpt/core/status.h"

namespace sculpt::server {

/// What became of a ball edit or a sweep of a skin.
struct SkinOutcome {
  /// Not ok: refused, naming the field; nothing was applied.
  Status status;
  uint64_t client_seq = 0;
  /// The edit's sequence in the log (0 for a duplicate or an edit refused before logging).
  uint64_t global_seq = 0;
  bool duplicate = false;
  uint32_t changed_sections = 0;  // ball edit: sections rebuilt
  uint32_t balls = 0;             // ball edit: balls after it
  double volume_after = 0;        // sweep: the object's volume after it
  uint32_t dirty_leaves = 0;      // sweep
};

/// What became of a paint or fill.
struct PaintOutcome {
  /// Not ok: refused, naming the field; nothing was applied.
  Status status;
  uint64_t client_seq = 0;
  /// The paint's sequence in the log (0 for a duplicate or a paint refused before logging).
  uint64_t global_seq = 0;
  bool duplicate = false;
  uint32_t changed_voxels = 0;
  uint32_t dirty_leaves = 0;
};

/// A model intent the validity check refused (hetero::Rejection, as the ack reports it).
struct ModelRejection {
  std::string reason;  // the reason code, e.g. "SKIN_INTERSECT"
  int32_t cell = -1;
  int32_t direction = -1;
  int32_t span = -1;
  std::string detail;
};

/// What became of a model intent.
struct ModelOutcome {
  /// Not ok: refused, naming the field (or by validity: then `rejection` says why).
  Status status;
  uint64_t client_seq = 0;
  /// The intent's sequence in the log (accepted and not a duplicate).
  uint64_t global_seq = 0;
  bool duplicate = false;
  uint32_t moved_coefficients = 0;
  /// The model after it (unchanged when refused); 0 when the model is unknown.
  uint64_t model_version = 0;
  uint64_t model_hash = 0;
  std::optional<ModelRejection> rejection;
};

/// What became of an undo or redo (codec::UndoCommand). EditHistory's own UndoOutcome is the
/// history's side of it; this is what the requester is told.
struct UndoCommandOutcome {
  /// Not ok: refused, naming the field (nothing to undo or redo, beyond the depth, no such
  /// object); nothing was applied.
  Status status;
  uint64_t client_seq = 0;
  bool redo = false;
  /// The undo's own sequence in the log: set when accepted (not a duplicate), and for a refusal
  /// that came after it was logged.
  uint64_t global_seq = 0;
  bool duplicate = false;
  // Accepted and not a duplicate:
  uint64_t target_seq = 0;  // the edit taken back or put back
  uint32_t replayed = 0;    // later edits replayed on top of the change, in all and per author
  std::map<std::string, uint32_t> replayed_by;
  uint32_t undo_depth = 0;  // what the author can still undo / redo on the object after it
  uint32_t redo_depth = 0;
};

/// The answer to a history view (codec::HistoryQuery).
struct HistoryOutcome {
  /// Not ok: refused, naming the field (an unknown object); no entries then.
  Status status;
  uint64_t request_id = 0;
  std::string object;
  /// Newest first, at most the query's limit, filtered by its author.
  std::vector<HistoryEntry> entries;
  uint32_t matching = 0;  // entries held that match the author filter
  uint32_t held = 0;      // entries held, every author's
  std::string cleared;    // why the history was last emptied (empty: never)
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_OUTCOMES_H_
