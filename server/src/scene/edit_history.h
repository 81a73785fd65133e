/// @brief EditHistory: per-author undo and redo of level-set edit batches and paints on one object
/// (issue 15), by restoring pre-images (signed distances and material fractions) and replaying
/// the later edits that the change reaches.
#ifndef SCULPT_SERVER_SCENE_EDIT_HISTORY_H_
#define SCULPT_SERVER_SCENE_EDIT_HISTORY_H_

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "sculpt/codec/paint_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/cell_image.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/sweep.h"

namespace sculpt::server {

struct EditHistoryOptions {
  /// Undoable edits kept per author (the issue asks for at least 64). Older ones fall off.
  int depth_per_author = 64;
  /// Edits kept over all authors. An undo replays edits after the undone one, so the history
  /// keeps every edit after the oldest undoable one; beyond this count (or max_bytes) the oldest
  /// fall off whoever made them, which bounds memory and the worst undo.
  int max_edits = 4096;
  /// Bytes of pre-images and requests kept over all authors.
  uint64_t max_bytes = uint64_t{256} << 20;
};

/// InvalidArgument naming the field, value and range: depth_per_author in [1, 4096], max_edits
/// in [1, 1000000], max_bytes in [1 MiB, 64 GiB].
Status ValidateEditHistoryOptions(const EditHistoryOptions& options);

/// What an undo or a redo did.
struct UndoOutcome {
  uint64_t seq = 0;    // global sequence of the edit taken back or re-applied
  std::string author;  // its author (the caller)
  /// Later edits replayed because they read what the change touched (or the volume it moved),
  /// in all and per author (the caller's own later edits included).
  uint32_t replayed = 0;
  std::map<std::string, uint32_t> replayed_by;
  /// Leaf cells (origins, sorted z, y, x) whose contents may differ from before the call: what
  /// the server replicates (EncodeLeafRecords over them) and a replica hashes (LeavesHash).
  std::vector<levelset::Int3> dirty_leaves;
  /// The sculpture's tracked scalars afterwards (volume, reference volume, reinit counter).
  levelset::ReplayState state;
  double elapsed_ms = 0;
};

/// One line of the history view (`sculpt history`).
struct HistoryEntry {
  uint64_t seq = 0;
  std::string author;
  levelset::EditKind kind = levelset::EditKind::kPress;  // a sweep: kAdd or kSubtract
  bool sweep = false;
  bool paint = false;  // a paint or fill of material fractions (`kind` then means nothing)
  /// What the history view prints: "press", "add", ..., "sweep-add", "sweep-subtract", "paint",
  /// "fill", "ball edit", "model intent".
  std::string kind_name;
  uint32_t poses = 0;
  bool undone = false;
  bool undoable = false;  // on its author's undo stack (within the depth)
  uint64_t wall_ms = 0;   // server wall clock at commit, ms since 1970 (0: unknown)
  std::string user;       // the authenticated user behind `author` (named users), else empty
  uint64_t epoch = 0;     // cluster mode: the ownership epoch its record was logged under
};

/// What an edit is about to read and overwrite, taken by Prepare before it is applied.
/// Opaque to callers: pass it to Commit.
struct PreparedEdit {
  std::vector<levelset::EditRequest> requests;  // a batch, or
  std::optional<levelset::SweepRequest> sweep;  // a sweep, or
  std::optional<codec::Paint> paint;            // a paint or fill (as logged)
  levelset::EditSettings settings;
  levelset::ReplayState before;
  levelset::VoxelBox footprint;
  levelset::CellImage image;
  /// Empty when the edit can be recorded; otherwise why not (Commit then clears the history).
  std::string not_undoable;
  /// Server wall clock at commit (ms since 1970), shown by the history view; the caller sets it.
  uint64_t wall_ms = 0;
};

/// The undo history of one sculpted object: every level-set edit batch applied to it, in order,
/// with what undo needs to take it back as if it had never been made. Undo restores the
/// pre-image of the leaves the edit wrote and replays, in order and with the same kernel
/// (ReplayEdits), every later edit that reads a restored or replayed leaf or whose volume
/// compensation reads tracked scalars that changed; the result is bit-identical to applying the
/// log without that edit, and the tracked volume and reference volume are what they would have
/// been. Redo is the same with the edit put back at its place in the order, so with nothing in
/// between it returns to the exact state before the undo.
/// Every write to the object's SDF must go through Commit (or be followed by Clear): an
/// unrecorded write would be lost by the next undo that rewinds its leaves.
/// Thread safety: not thread-safe; the owner of the sculpture (the scene's compute thread) calls
/// it, with the same one-writer rule as the sculpture.
class EditHistory {
 public:
  explicit EditHistory(EditHistoryOptions options = {});

  /// Right before ApplyEdits(sculpture, requests, settings): captures the tracked scalars, the
  /// footprint and a pre-image of the footprint's leaves, material fractions included (about
  /// 0.1 ms for a press). Never fails; an edit that cannot be undone (global compensation, which
  /// reads and writes the whole object) is marked so and Commit clears the history.
  PreparedEdit Prepare(const levelset::Sculpture& sculpture,
                       const std::vector<levelset::EditRequest>& requests,
                       const levelset::EditSettings& settings) const;
  /// Right after that edit succeeded: records it under `author` as its newest undoable edit
  /// (clearing the author's redo stack, as a new stroke does in every editor) with the global
  /// sequence the log gave it (and prepared.wall_ms as its time). `sculpture` is the object after
  /// the edit. Trims the history to its bounds. Do not call for an edit the kernel refused (it
  /// changed nothing).
  void Commit(PreparedEdit prepared, uint64_t seq, const std::string& author,
              const levelset::EditResult& result, const levelset::Sculpture& sculpture);
  /// Prepare, ApplyEdits, Commit. The kernel's error otherwise (nothing recorded then).
  /// `wall_ms` is the commit time the history view shows (0: unknown).
  StatusOr<levelset::EditResult> Apply(levelset::Sculpture& sculpture, uint64_t seq,
                                       const std::string& author,
                                       const std::vector<levelset::EditRequest>& requests,
                                       const levelset::ValidEditSettings& settings,
                                       uint64_t wall_ms = 0);
  /// The same for a sweep (levelset::ApplySweep), which reads and writes its block voxel by
  /// voxel and moves volume and reference volume together: Commit takes it like a batch.
  PreparedEdit PrepareSweep(const levelset::Sculpture& sculpture,
                            const levelset::SweepRequest& request) const;
  StatusOr<levelset::EditResult> ApplySweep(levelset::Sculpture& sculpture, uint64_t seq,
                                            const std::string& author,
                                            const levelset::SweepRequest& request,
                                            uint64_t wall_ms = 0);
  /// The same for a paint or fill of material fractions (ApplyPaint, paint.h), which reads and
  /// writes only the fractions of the voxels inside its tool and moves no tracked scalar; its
  /// footprint is the tool's voxel box. The kernel's error otherwise (nothing recorded then).
  PreparedEdit PreparePaint(const levelset::Sculpture& sculpture, const codec::Paint& paint) const;
  StatusOr<levelset::EditResult> ApplyPaint(levelset::Sculpture& sculpture, uint64_t seq,
                                            const std::string& author, const codec::Paint& paint,
                                            uint64_t wall_ms = 0);

  /// Takes back `author`'s most recent edit that is not undone. FailedPrecondition when the
  /// author has nothing to undo; OutOfRange when its edits within reach are exhausted and older
  /// ones fell off the history (depth_per_author or the history's bounds), naming the depth;
  /// Internal if a replay fails (not expected: every replayed edit was accepted before), the
  /// sculpture then holding a partial result. The sculpture and history are unchanged on the
  /// first two.
  /// `at_seq` is the global sequence of the undo itself (RedoUndoneAt reports it).
  StatusOr<UndoOutcome> Undo(levelset::Sculpture& sculpture, const std::string& author,
                             uint64_t at_seq = 0);
  /// Re-applies `author`'s most recently undone edit at its place in the order.
  /// FailedPrecondition when there is none (never undone, or a new edit by the author since).
  StatusOr<UndoOutcome> Redo(levelset::Sculpture& sculpture, const std::string& author);
  /// The `at_seq` of the undo that took back the edit Redo(author) would re-apply (0 when
  /// unknown or none): how the scene orders it against the author's undone ball edits and model
  /// intents.
  uint64_t RedoUndoneAt(const std::string& author) const;

  /// The global sequence of the edit Undo(author) / Redo(author) would take back or re-apply,
  /// with the same errors, without changing anything: the pipeline's prepare step (check, then
  /// log the undo record naming its target).
  StatusOr<uint64_t> UndoTarget(const std::string& author) const;
  StatusOr<uint64_t> RedoTarget(const std::string& author) const;
  /// Sequence of the oldest edit held (0 when empty): recovery must replay the log from at or
  /// before it for the history to be rebuilt whole after a restart.
  uint64_t OldestSeq() const { return records_.empty() ? 0 : records_.front().seq; }

  /// The whole history (edits, pre-images, scalars, author stacks) as bytes to keep beside a
  /// snapshot of the object: a restart from that snapshot then undoes what was undoable before
  /// it, as if there had been no restart. For this build's own bytes only (the layout holds the
  /// kernel's structs as they are in memory); Parse still checks bounds and returns DataLoss
  /// naming the field for anything truncated or inconsistent, InvalidArgument for bad options.
  std::string Serialize() const;
  static StatusOr<EditHistory> Parse(std::string_view bytes, EditHistoryOptions options = {});

  /// Forgets everything (after a write that bypassed Commit: a load, ReinitializeRegion, a
  /// global-compensation edit). `why` is quoted by later "nothing to undo" errors.
  void Clear(const std::string& why = "cleared");

  size_t undo_depth(const std::string& author) const;
  size_t redo_depth(const std::string& author) const;
  /// Edits held (every author's, undone ones included).
  size_t size() const { return records_.size(); }
  /// Heap bytes held by pre-images and requests.
  uint64_t MemoryBytes() const { return bytes_; }
  /// The held edits, oldest first; only `author`'s when it is not empty.
  std::vector<HistoryEntry> Entries(const std::string& author = {}) const;
  /// Why the history was last cleared (empty if never): edits before that cannot be undone.
  const std::string& cleared_reason() const { return cleared_; }
  const EditHistoryOptions& options() const { return options_; }

 private:
  enum class Stack : uint8_t { kNone, kUndo, kRedo };
  struct Record {
    uint64_t seq = 0;
    uint64_t wall_ms = 0;  // commit time, for the history view
    std::string author;
    std::vector<levelset::EditRequest> requests;  // empty for a sweep
    std::optional<levelset::SweepRequest> sweep;
    std::optional<codec::Paint> paint;
    levelset::EditSettings settings;
    levelset::VoxelBox footprint;
    /// Scalars at its place in the current order (before and after it; for an undone edit
    /// `before` is what it would start from if redone).
    levelset::ReplayState before;
    levelset::ReplayState after;
    double volume_change = 0;
    double island_volume_removed = 0;
    bool reinitialised = false;
    /// The leaves it wrote, as they were before it (in the current order).
    levelset::CellImage image;
    bool active = true;
    Stack stack = Stack::kUndo;
    uint64_t undone_at = 0;  // the sequence of the undo that took it back (0: unknown)
  };
  struct AuthorStacks {
    std::vector<uint64_t> undo;  // record ids, oldest first
    std::vector<uint64_t> redo;  // record ids, most recently undone last
    uint64_t fell_off = 0;
  };
  class CellSet;

  Record& At(uint64_t id) { return records_[id - first_id_]; }
  StatusOr<UndoOutcome> Rebuild(levelset::Sculpture& sculpture, uint64_t id, bool activate);
  Status ReplayOne(levelset::Sculpture& sculpture, size_t index, bool rewind_self,
                   levelset::ReplayState& state, CellSet& region, UndoOutcome& out);
  bool NeedsReplay(const Record& r, const levelset::ReplayState& state,
                   const CellSet& region) const;
  static levelset::ReplayState Transfer(const Record& r, const levelset::ReplayState& state);
  void Trim();
  void DropFront();
  static uint64_t RecordBytes(const Record& r);

  EditHistoryOptions options_;
  std::deque<Record> records_;
  uint64_t first_id_ = 0;  // id of records_.front()
  uint64_t bytes_ = 0;
  std::unordered_map<std::string, AuthorStacks> authors_;
  std::string cleared_;  // why the history was last cleared, if ever
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_EDIT_HISTORY_H_
