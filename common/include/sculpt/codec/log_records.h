/// @brief The edit log's records and the skin files beside snapshots as domain types, and the one
/// place that knows their storage format. A stroke's pose is a serialized sculpt.v1.EditRecord
/// (its first byte is the field tag 0x08, never a LogTag); every other record is one LogTag byte,
/// then its protobuf message. EncodeLogRecord writes exactly the bytes the server has always
/// written, so existing logs, side files and replicas stay readable.
#ifndef SCULPT_CODEC_LOG_RECORDS_H_
#define SCULPT_CODEC_LOG_RECORDS_H_

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "sculpt/codec/model_messages.h"
#include "sculpt/codec/paint_messages.h"
#include "sculpt/codec/skin_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sweep.h"

namespace sculpt::codec {

/// The first byte of every record that is not a stroke's pose (the values are on disk).
enum class LogTag : char {
  kSweep = '\x00',
  kPaint = '\x01',
  kModel = '\x02',
  kSkinEdit = '\x03',
  kUndo = '\x04',
};

/// One pose of a stroke; a stroke is logged as one group of these.
struct StrokePoseRecord {
  uint64_t global_seq = 0;
  uint64_t client_id = 0;
  uint64_t client_seq = 0;
  std::string object;
  uint32_t pose_index = 0;
  /// Poses in the stroke; 0 in logs written before strokes were grouped (the pose stands alone).
  uint32_t pose_count = 0;
  /// The server's wall clock when the stroke was logged (ms since 1970), on its last pose; 0
  /// on the others and in older logs.
  uint64_t commit_ms = 0;
  /// The pose's kernel edit. Encoding rounds its numbers to float; decoding gives the rounded
  /// edit, which is what the live server, recovery and replicas all apply (AsLogged).
  levelset::EditRequest edit;

  /// The last pose of its stroke (or a pose standing alone): the stroke is complete with it.
  bool completes() const { return pose_index + 1 >= pose_count; }
  std::string user = {};  // the authenticated user who made it (named users), else empty
  /// Cluster mode: the ownership epoch under which the owner sequenced it (AppendRecordEpoch);
  /// 0 on a single process and in older logs. Every kind below has the same field.
  uint64_t epoch = 0;
};

/// A paint or fill (issue 7).
struct PaintRecord {
  uint64_t global_seq = 0;
  uint64_t client_id = 0;
  /// Encoded in its wire form (floats for the tool); decoded unchecked (the live server checked
  /// it against the limits of its time). Apply AsLogged(paint) live.
  Paint paint;
  std::string user = {};  // the authenticated user who made it (named users), else empty
  uint64_t epoch = 0;      // cluster mode: see StrokePoseRecord::epoch
};

/// A sweep of a skin's outline into an object (issue 6): the outline and plane travel in the
/// record, so recovery needs no skin.
struct SweepRecord {
  uint64_t global_seq = 0;
  uint64_t client_id = 0;
  uint64_t client_seq = 0;
  std::string object;
  /// The kernel request (doubles, exact both ways). A revolution's axis is logged; an
  /// extrusion's is not (it decodes as the defaults).
  levelset::SweepRequest request;
  /// Not ok (InvalidArgument naming the field) for a record whose plane, outline or axis has the
  /// wrong number of values: `request` is then incomplete and recovery skips the sweep.
  Status request_status;
  std::string user = {};  // the authenticated user who made it (named users), else empty
  uint64_t epoch = 0;      // cluster mode: see StrokePoseRecord::epoch
};

/// An accepted model intent (issue 7) and the model version it produced.
struct ModelRecord {
  uint64_t global_seq = 0;
  uint64_t client_id = 0;
  ModelEdit edit;  // decoded unchecked: the live server checked it
  uint64_t model_version = 0;
  std::string user = {};  // the authenticated user who made it (named users), else empty
  uint64_t epoch = 0;      // cluster mode: see StrokePoseRecord::epoch
};

/// A ball edit of a skin (issue 6) and the skin version it produced.
struct BallEditRecord {
  uint64_t global_seq = 0;
  uint64_t client_id = 0;
  /// `skin` and `client_seq` are always decoded; the other fields only when `edit_status` is ok.
  BallEdit edit;
  /// The check DecodeSkinBallEdit makes of the logged edit, as the live server made it.
  Status edit_status;
  uint64_t skin_version = 0;
  std::string user = {};  // the authenticated user who made it (named users), else empty
  uint64_t epoch = 0;      // cluster mode: see StrokePoseRecord::epoch
};

/// The histories an undo takes from (UndoRecord.target_book; the values are on disk).
inline constexpr uint32_t kUndoObjectBook = 0;
inline constexpr uint32_t kUndoModelBook = 1;
inline constexpr uint32_t kUndoSkinBook = 2;

/// An undo or redo request (issue 15).
struct UndoRecord {
  uint64_t global_seq = 0;
  uint64_t client_id = 0;
  uint64_t client_seq = 0;
  std::string object;
  bool redo = false;  // false: undo
  std::string author;
  /// What it takes back or puts back, as the live server chose it: the object's stroke and paint
  /// history (kUndoObjectBook; older logs), its model's intents (kUndoModelBook) or a skin's ball
  /// edits (kUndoSkinBook, `object` then names the skin), and the edit's sequence (0: older
  /// logs, the history's own choice).
  uint32_t target_book = 0;
  uint64_t target_seq = 0;
  std::string user = {};  // the authenticated user who made it (named users), else empty
  uint64_t epoch = 0;      // cluster mode: see StrokePoseRecord::epoch
};

/// One edit-log record, decoded.
using EditLogRecord = std::variant<StrokePoseRecord, PaintRecord, SweepRecord, ModelRecord,
                                   BallEditRecord, UndoRecord>;

/// The record's storage bytes (the edit log's payload).
std::string EncodeLogRecord(const StrokePoseRecord& record);
std::string EncodeLogRecord(const PaintRecord& record);
std::string EncodeLogRecord(const SweepRecord& record);
std::string EncodeLogRecord(const ModelRecord& record);
std::string EncodeLogRecord(const BallEditRecord& record);
std::string EncodeLogRecord(const UndoRecord& record);

/// Adds the authenticated user who made the edit to an encoded record (field 100 of every record
/// message, appended: a protobuf field may follow the message's other fields), so the log names
/// who made each edit. An empty name adds nothing.
void AppendRecordUser(std::string* payload, std::string_view user);

/// Cluster mode (issue 17): adds the ownership epoch under which the edit was sequenced to an
/// encoded record of any kind (field 16 of every record message, appended as AppendRecordUser
/// appends the user; it decodes into the record's `epoch`). Epoch 0 adds nothing, so a single
/// process writes the bytes it always wrote. EncodeLogRecord never writes `epoch` (nor `user`):
/// this is the one writer of the field.
void AppendRecordEpoch(std::string* payload, uint64_t epoch);

/// The epoch a decoded record carries (0: single process or older log).
inline uint64_t RecordEpoch(const EditLogRecord& record) {
  return std::visit([](const auto& r) { return r.epoch; }, record);
}

/// Tells the kinds apart by the first byte and decodes one payload. DataLoss naming `seq` (and
/// the kind, for a tagged record) when the bytes do not parse.
StatusOr<EditLogRecord> DecodeLogRecord(uint64_t seq, std::string_view payload);

/// What an edit becomes once logged and read back (its numbers rounded to the record's floats):
/// the live server applies this, so it agrees with recovery and replicas bit for bit.
levelset::EditRequest AsLogged(const levelset::EditRequest& edit);
Paint AsLogged(const Paint& paint);

/// A skin's state as saved beside the snapshots (data_dir/skins/<name>.pb).
struct SavedSkin {
  uint64_t seq = 0;      // the edit-log sequence the file includes
  uint64_t version = 0;  // ball edits applied since the scene first built the skin
  std::vector<SkinBall> balls;
  /// Older files only: the newest ball-edit and sweep client_seq per client_id at `seq` (the
  /// resend table holds them now).
  std::map<uint64_t, uint64_t> last_edit_seq;
  std::map<uint64_t, uint64_t> last_sweep_seq;
};
std::string EncodeSavedSkin(const SavedSkin& skin);
/// DataLoss when the bytes do not parse.
StatusOr<SavedSkin> DecodeSavedSkin(std::string_view bytes);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_LOG_RECORDS_H_
