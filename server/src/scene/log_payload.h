/// @brief Edit-log records other than EditRecords: one tag byte, then the record message. A
/// serialized EditRecord never starts with these bytes (its first field tag is 0x08), so
/// recovery tells them apart by the first byte.
#ifndef SCULPT_SERVER_SCENE_LOG_PAYLOAD_H_
#define SCULPT_SERVER_SCENE_LOG_PAYLOAD_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"

namespace sculpt::server {

enum class LogTag : char {
  kSweep = '\x00',     // v1::SkinSweepRecord
  kPaint = '\x01',     // v1::PaintRecord
  kModel = '\x02',     // v1::ModelRecord
  kSkinEdit = '\x03',  // v1::SkinEditRecord
  kUndo = '\x04',      // v1::UndoRecord
};

inline bool HasLogTag(const std::string& payload, LogTag tag) {
  return !payload.empty() && payload[0] == static_cast<char>(tag);
}

template <typename Record>
std::string TaggedPayload(LogTag tag, const Record& record) {
  std::string out(1, static_cast<char>(tag));
  record.AppendToString(&out);
  return out;
}

/// DataLoss naming the record's sequence and `what` when the tag differs or the bytes do not
/// parse.
template <typename Record>
StatusOr<Record> ParseTaggedPayload(LogTag tag, uint64_t seq, const std::string& payload,
                                    const char* what) {
  Record r;
  if (!HasLogTag(payload, tag) ||
      !r.ParseFromArray(payload.data() + 1, static_cast<int>(payload.size() - 1))) {
    return DataLoss("edit log record " + std::to_string(seq) + " (" + what + ") does not parse");
  }
  return r;
}

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_LOG_PAYLOAD_H_
