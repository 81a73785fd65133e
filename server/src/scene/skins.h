/// @brief SkinBook: the scene's ball skins (issue 6) with their contour subscribers and the
/// subscribers of object slices; replaying logged sweeps, and the skin files written beside
/// snapshots. The records' and files' storage format lives in sculpt/codec/log_records.h; the
/// skin messages off the wire are decoded before the scene by sculpt/codec/skin_messages.h.
#ifndef SCULPT_SERVER_SCENE_SKINS_H_
#define SCULPT_SERVER_SCENE_SKINS_H_

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "config/server_config.h"
#include "scene/book_history.h"
#include "scene/commit.h"
#include "scene/replica_sink.h"
#include "sculpt/codec/log_records.h"
#include "sculpt/codec/skin_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/slice.h"
#include "sculpt/levelset/sweep.h"
#include "sculpt/skin/skin.h"

namespace sculpt::server {

class EditHistory;

/// The ball skins of a scene and who watches them: each skin with its sketch plane, its version
/// (ball edits applied since the scene first built it), the log sequence its file held at start
/// and its contour subscribers; and each object's slice subscribers. A ball edit rebuilds at
/// most two sections of a copy of its skin (PrepareBallEdit, changing nothing), then puts the
/// copy in place and sends the skin's subscribers only the sections that changed
/// (ApplyBallEdit). Skins are saved beside each snapshot (Save) and the ball edits logged after
/// a file's sequence replayed at start (Replay).
/// Thread safety: none of its own. The scene calls it on its compute thread only, between two
/// edits, as it did with these members inline; sinks are called there and must only post.
class SkinBook {
 public:
  /// A ball edit checked against its skin, ready to apply: the rebuilt skin and what changed.
  struct BallEditPlan {
    std::string skin;
    skin::Skin next;          // the skin with the edit applied
    skin::SkinChange change;  // the sections rebuilt
    uint64_t version = 0;     // the skin's version once applied
  };

  /// Builds `skins`, each from its file under data_dir/skins when one was saved (balls, version
  /// and the log sequence the file holds), else from its configured balls at version 0. The
  /// client sequences files of older servers carry are raised in `resend` (may be null).
  /// DataLoss naming a file that does not parse; InvalidArgument naming scene.skins and the skin
  /// when its balls do not build (or the method's own error for an unknown method). Forgets
  /// every skin and subscriber it held before.
  Status Open(const std::vector<SkinConfig>& skins, const std::string& data_dir,
              ResendFilter* resend);

  /// Recovery: applies a ball edit logged at `seq` unless its skin's file already holds it. An
  /// edit naming a skin the scene does not define, or refused by the skin, is skipped with a
  /// warning (as the live server refused it).
  void Replay(uint64_t seq, const codec::BallEditRecord& record);
  /// Writes every skin, as of log sequence `seq`, to data_dir/skins/<name>.pb (atomically). False
  /// (each failure logged) if a file was not saved; true when there are no skins.
  bool Save(uint64_t seq) const;
  /// The same files under `dir` instead of the data directory (a standby's copy of them).
  bool SaveTo(const std::string& dir, uint64_t seq) const;

  /// Checks `edit` against its skin and applies it to a copy, changing nothing. NotFound naming
  /// SkinBallEdit.skin for an unknown skin; InvalidArgument naming SkinBallEdit.index (outside
  /// [0, balls - 1], or [0, balls] for ADD), SkinBallEdit.op (an ADD to a skin of kMaxSkinBalls)
  /// or SkinBallEdit.ball (a ball not admissible with its neighbours, with the skin's reason).
  StatusOr<BallEditPlan> PrepareBallEdit(const codec::BallEdit& edit) const;
  /// Puts a prepared edit in place (nothing else may change the skin between the two calls),
  /// sets its version, and sends the skin's contour subscribers an update holding the changed
  /// sections and the whole chain. Records `edit` (logged at `seq`) as `author`'s newest
  /// undoable ball edit of the skin (not recorded without an author). Returns the skin's ball
  /// count.
  size_t ApplyBallEdit(BallEditPlan plan, uint64_t seq = 0, const std::string& author = {},
                       const codec::BallEdit& edit = {}, uint64_t wall_ms = 0);

  /// Per-author undo and redo of ball edits (issue 15, BookHistory): each skin keeps its recent
  /// ball edits with the chain before each, saved beside the skin file at each Save
  /// (data_dir/skins/<name>.history) and loaded by Open with it. Ball edits kept per author and
  /// skin (set before Open).
  void set_undo_depth(size_t depth) { undo_depth_ = depth; }
  bool has_skin(const std::string& name) const { return skins_.count(name) != 0; }
  /// The sequence of the ball edit of `skin` that an undo (or redo) by `author` would take back
  /// (put back): NotFound naming UndoRequest.object for an unknown skin, else BookHistory's.
  StatusOr<uint64_t> UndoTarget(const std::string& skin, const std::string& author,
                                bool redo) const;
  /// Takes back (puts back) that ball edit: the chain is rebuilt from before it with the later
  /// ball edits re-applied, the version raised, and contour subscribers get the whole skin.
  /// `at_seq` is the undo's own sequence. UndoTarget's errors, nothing changed.
  StatusOr<UndoOutcome> Undo(const std::string& skin, const std::string& author, bool redo,
                             uint64_t at_seq);
  /// Recovery: the logged undo or redo of a ball edit at `seq`, unless the skin's file holds it.
  void ReplayUndo(uint64_t seq, const codec::UndoRecord& record);
  /// Undoable and redoable ball edits of `author` on `skin` (0, 0 for an unknown skin).
  std::pair<size_t, size_t> UndoDepth(const std::string& skin, const std::string& author) const;
  /// The skin's history view (newest last), and why it was last cleared. NotFound naming
  /// HistoryRequest.object for an unknown skin.
  StatusOr<std::vector<HistoryEntry>> Entries(const std::string& skin, const std::string& author,
                                              std::string* cleared, size_t* held) const;
  /// Balls of `skin` now; 0 for an unknown skin.
  size_t ball_count(const std::string& skin) const;

  /// The kernel request sweeping `sweep.skin`'s outline on its plane (mode, kind, depth and axis
  /// from `sweep`); not checked against any object. NotFound naming SkinSweep.skin.
  StatusOr<levelset::SweepRequest> SweepRequestFor(const codec::SkinSweepRequest& sweep) const;

  /// Registers (or, with request.unsubscribe, removes) the session's contour subscription
  /// decoded by codec::DecodeContourSubscribe: a skin's gets the skin's snapshot now and an
  /// update after each ball edit; a slice of request.object (`sculpture`, null when the scene
  /// has no such object) gets the cut at sequence `seq` now and again after every edit whose
  /// leaves its plane crosses (SendSlices). A new subscription replaces the session's earlier one
  /// to the same skin or object. `answer` gets the outcome exactly once, before any frame:
  /// NotFound naming ContourSubscribe.skin or ContourSubscribe.slice.object; the encoder's or
  /// the slicer's error.
  void Subscribe(ReplicaSink sink, const codec::ContourRequest& request,
                 const levelset::Sculpture* sculpture, uint64_t seq,
                 const std::function<void(Status)>& answer);
  /// Forgets every skin and slice subscription of the session (none: nothing happens).
  void Unsubscribe(uint64_t session_id);
  /// Re-sends `object`'s slices whose plane crosses the world box of the leaves an edit changed,
  /// cut from `sculpture` (the object now) and stamped with sequence `seq`.
  void SendSlices(const std::string& object, const levelset::Sculpture& sculpture,
                  const std::vector<levelset::Int3>& changed, uint64_t seq);

  /// A copy of the skin named `name`; NotFound naming "skin".
  StatusOr<skin::Skin> Copy(const std::string& name) const;
  /// The skin's version (ball edits applied since the scene first built it); 0 for an unknown
  /// skin.
  uint64_t version(const std::string& skin) const;
  /// Skin and slice subscriptions held.
  size_t subscriber_count() const;

 private:
  using History = BookHistory<skin::Skin, codec::BallEdit>;
  struct Entry {
    levelset::SweepPlane plane;
    skin::Skin skin;
    uint64_t version = 0;
    uint64_t file_seq = 0;                 // the skin file held the log up to this seq at start-up
    std::map<uint64_t, ReplicaSink> subs;  // by session
    History history{"ball edit", 64};
    skin::SkinOptions options;  // how the chain is built (a saved history's chains are rebuilt)
  };
  // Sends the skin's contour subscribers the whole skin (after an undo or redo).
  void SendWhole(const std::string& name, Entry& entry);
  // Loads the undo history kept with the skin's file (none, or another round's: empty).
  void LoadHistory(const std::string& name, Entry& entry);
  struct SliceSub {
    ReplicaSink sink;
    levelset::SliceRequest request;
  };
  // The skin named `name`, or NotFound naming `field`, the request field that named it.
  StatusOr<const Entry*> Find(const std::string& field, const std::string& name) const;

  std::string data_dir_;
  size_t undo_depth_ = 64;
  std::map<std::string, Entry> skins_;
  std::map<std::string, std::map<uint64_t, SliceSub>> slices_;  // object -> session -> sub
};

/// Recovery: applies a logged sweep as the live server did, through the object's undo history
/// under its author (so undo and redo after a restart replay the same). A sweep the kernel
/// refuses, or a malformed record, is skipped with a warning (Ok, nothing applied or recorded).
Status ReplaySweep(levelset::Sculpture& sculpture, EditHistory& history, uint64_t seq,
                   const codec::SweepRecord& record);

/// Writes a skin's state to `path` atomically (temporary file, fsync, rename). Internal on I/O
/// errors.
Status SaveSkinFile(const std::string& path, const codec::SavedSkin& saved);
/// Reads what SaveSkinFile wrote; NotFound when absent, DataLoss when it does not parse.
StatusOr<codec::SavedSkin> LoadSkinFile(const std::string& path);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_SKINS_H_
