/// @brief What became of an edit the scene was given, as domain results: the session turns them
/// into the wire's acks (net/wire_acks.h), the scene never builds a wire message for them.
#ifndef SCULPT_SERVER_SCENE_OUTCOMES_H_
#define SCULPT_SERVER_SCENE_OUTCOMES_H_

#include <cstdint>

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

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_OUTCOMES_H_
