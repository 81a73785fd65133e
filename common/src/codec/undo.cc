/// @brief Undo request decoding and its log record.
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

void AppendUndoRecord(uint64_t global_seq, uint64_t client_id, const UndoCommand& command,
                      const std::string& author, std::string* out) {
  v1::UndoRecord record;
  record.set_global_seq(global_seq);
  record.set_client_id(client_id);
  v1::UndoRequest* request = record.mutable_request();
  request->set_client_seq(command.client_seq);
  request->set_object(command.object);
  request->set_redo(command.redo);
  record.set_author(author);
  record.AppendToString(out);
}

}  // namespace sculpt::codec
