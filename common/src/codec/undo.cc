/// @brief Undo request decoding (the log record is log_records.h's UndoRecord).
#include "sculpt/codec/undo.h"

#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {

StatusOr<UndoCommand> DecodeUndo(const v1::UndoRequest& request) {
  // The size, not the name, goes into the error: the name is the client's and may hold anything.
  if (request.object().empty() || request.object().size() > kMaxUndoObjectBytes) {
    return Outside("UndoRequest.object",
                   std::string("(") + std::to_string(request.object().size()) + " bytes)",
                   std::string("names of 1..") + std::to_string(kMaxUndoObjectBytes) + " bytes");
  }
  UndoCommand command;
  command.client_seq = request.client_seq();
  command.object = request.object();
  command.redo = request.redo();
  return command;
}

}  // namespace sculpt::codec
