/// @brief Undo and redo requests (issue 15) decoded at the edge: an untrusted
/// sculpt.v1.UndoRequest becomes an UndoCommand, and an accepted one its edit-log record.
#ifndef SCULPT_CODEC_UNDO_H_
#define SCULPT_CODEC_UNDO_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"

namespace sculpt::v1 {
class UndoRequest;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// Longest object name an undo may name, in bytes.
inline constexpr size_t kMaxUndoObjectBytes = 64;

/// An undo (or, with `redo`, a redo) of the sender's most recent edit on an object, checked.
/// The wire has one message for both.
struct UndoCommand {
  uint64_t client_seq = 0;
  std::string object;  // 1..64 bytes (the scene says whether it exists)
  bool redo = false;
};

/// InvalidArgument naming UndoRequest.object, its size and the allowed sizes when the object
/// name is empty or longer than 64 bytes (the name itself is not echoed).
StatusOr<UndoCommand> DecodeUndo(const v1::UndoRequest& request);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_UNDO_H_
