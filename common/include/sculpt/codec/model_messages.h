/// @brief A ModelIntent off the wire (issue 7, seed 001 §10.4) decoded into the hyperpatch
/// library's EditIntent, naming field, value and range. The indices that need the model (corner,
/// cell) are checked where the model lives.
#ifndef SCULPT_CODEC_MODEL_MESSAGES_H_
#define SCULPT_CODEC_MODEL_MESSAGES_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/hetero/grid_editor.h"

namespace sculpt::v1 {
class ModelIntent;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// A validated model intent on one object.
struct ModelEdit {
  uint64_t client_seq = 0;
  std::string object;
  hetero::EditIntent intent;
};

/// Checks the fields that need no model: object name 1..64 bytes, exactly 3 offsets each in
/// {-1, 0, 1}, a finite displacement with every component within ±hetero::kMaxDisplacement,
/// cell >= -1. InvalidArgument "ModelIntent.<field>=<value> outside <range>". The continuity
/// flags are carried only when set_flags is.
StatusOr<ModelEdit> DecodeModelIntent(const v1::ModelIntent& intent);

/// The intent a logged ModelIntent describes, unchecked (recovery: the live server checked it).
ModelEdit ModelEditFromRecord(const v1::ModelIntent& intent);
/// The wire form of a model edit, which the edit log's ModelRecord embeds.
v1::ModelIntent EncodeModelIntent(const ModelEdit& edit);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_MODEL_MESSAGES_H_
