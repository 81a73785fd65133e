/// @brief The scene's one commit pipeline: the interface each edit kind supplies (EditOp), the
/// resend filter every kind shares, and the one decoder of edit-log records that routing,
/// recovery and the resend scan use.
///
/// Scene::Commit runs every edit the same way, on the compute thread:
///   dedupe (ResendFilter) → Prepare (check against the scene as it is and build the log
///   records, changing nothing) → assign sequences → append (one group) → Apply → record leaf
///   versions → mark viewer chunks → replicate → ack once durable → maybe snapshot.
/// A kind therefore only says how it is checked, what it logs, how it applies and how its
/// requester is answered; the ordering guarantees (logged before applied, acked only when
/// durable, a resend never applied twice) live in one place.
#ifndef SCULPT_SERVER_SCENE_COMMIT_H_
#define SCULPT_SERVER_SCENE_COMMIT_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "scene/replication_hub.h"
#include "sculpt/codec/log_records.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"

namespace sculpt::server {

class Scene;

/// The client sequences an edit kind numbers on its own; the resend table keeps these numbers
/// on disk, so they never change.
enum class ResendStream : uint8_t {
  kStrokes = 0,
  kPaints = 1,
  kModels = 2,
  kBallEdits = 3,
  kSweeps = 4,
  kUndos = 5,  // undo and redo requests share one sequence
};
inline constexpr size_t kResendStreams = 6;

/// The name an author's strokes are filed under in the undo history: its client id (bound to the
/// authenticated user on a server with named users).
inline std::string HistoryAuthor(uint64_t client_id) { return std::to_string(client_id); }

/// The newest client sequence committed per (stream, client). A request whose client_seq is not
/// above it is a resend: acknowledged as a duplicate, never applied again.
class ResendFilter {
 public:
  using Key = std::pair<uint8_t, uint64_t>;  // stream, client id

  bool IsResend(ResendStream stream, uint64_t client_id, uint64_t client_seq) const {
    auto it = last_.find({static_cast<uint8_t>(stream), client_id});
    return it != last_.end() && client_seq <= it->second;
  }
  /// Raises the client's newest sequence (never lowers it).
  void Record(ResendStream stream, uint64_t client_id, uint64_t client_seq) {
    uint64_t& last = last_[{static_cast<uint8_t>(stream), client_id}];
    if (client_seq > last) last = client_seq;
  }
  /// The client's newest committed sequence in `stream`; 0 when it has none.
  uint64_t CommittedUpTo(ResendStream stream, uint64_t client_id) const {
    auto it = last_.find({static_cast<uint8_t>(stream), client_id});
    return it != last_.end() ? it->second : 0;
  }
  /// The table as saved beside snapshots (store::ResendTable::last).
  const std::map<Key, uint64_t>& entries() const { return last_; }

 private:
  std::map<Key, uint64_t> last_;
};

/// One edit-log record, decoded, with what routing, recovery and the resend scan ask of every
/// kind. The storage format is codec's (sculpt/codec/log_records.h); a stroke is one
/// StrokePoseRecord per pose, logged as one group.
struct LoggedEdit {
  ResendStream stream = ResendStream::kStrokes;
  uint64_t client_id = 0;
  uint64_t client_seq = 0;
  /// The object whose sculpture the record changes; empty for a ball edit (skins only).
  std::string object;
  /// The record completes its edit (every record but a stroke's poses before its last): only a
  /// complete edit makes a resend a duplicate.
  bool completes = true;
  codec::EditLogRecord record;
};

/// DataLoss naming the sequence when the payload does not parse.
StatusOr<LoggedEdit> DecodeLogRecord(uint64_t seq, const std::string& payload);

/// What the requester of an edit hears (besides its kind's own details).
struct CommitOutcome {
  /// Not ok: refused, before anything was logged (global_seq_first = 0), or by the kernel after
  /// the records were logged (then recovery refuses it identically).
  Status status;
  uint64_t client_seq = 0;
  uint64_t global_seq_first = 0;
  uint64_t global_seq_last = 0;
  uint32_t records = 0;
  bool duplicate = false;
};

/// What an applied edit changed, for the pipeline's common steps after Apply.
struct Applied {
  /// Not ok: the kernel refused the edit after it was logged (nothing changed).
  Status status;
  /// The object whose sculpture changed; empty when none did (skins, models).
  std::string object;
  std::vector<levelset::Int3> dirty_leaves;
  /// The object's bounds may have moved (the scene info is refreshed either way).
  bool bounds_may_change = false;
  /// Set for edits replicas can replay (strokes): what an EditBroadcast carries. Without it,
  /// replicas get the changed leaves.
  using Replay = EditReplay;
  std::optional<Replay> replay;
};

/// One edit kind on the pipeline. Calls come from the compute thread, in this order: Prepare;
/// if it succeeded and the log took the records, Apply; then Answer exactly once (at once for a
/// duplicate or a refusal, else once the records are durable).
class EditOp {
 public:
  virtual ~EditOp() = default;
  /// Names the operation in logs and in the INTERNAL error of a task that threw.
  virtual const char* operation() const = 0;
  virtual ResendStream stream() const = 0;
  virtual uint64_t client_id() const = 0;
  virtual uint64_t client_seq() const = 0;
  /// Checks the edit against the scene as it is and appends its log record(s) for the
  /// sequences `first_seq`, `first_seq` + 1, ... to `records`, changing nothing in the scene.
  /// A refusal names the field, the value and the allowed range.
  virtual Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) = 0;
  /// Applies what Prepare built, exactly as recovery replays the records.
  virtual Applied Apply(Scene& scene) = 0;
  /// A resend of an edit already committed: takes what its answer reports about the scene.
  virtual void Duplicate(Scene& /*scene*/) {}
  /// Answers the requester (at once, or from the log's durability thread: it reads only what
  /// Prepare, Apply or Duplicate stored).
  virtual void Answer(const CommitOutcome& outcome) = 0;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_COMMIT_H_
