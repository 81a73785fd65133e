/// @brief What became of an edit the scene was given, as domain results: the session turns them
/// into the wire's acks (net/wire_acks.h), the scene never builds a wire message for them.
#ifndef SCULPT_SERVER_SCENE_OUTCOMES_H_
#define SCULPT_SERVER_SCENE_OUTCOMES_H_

#include <cstdint>
#include <optional>
#include <string>

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

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_OUTCOMES_H_
