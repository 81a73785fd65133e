/// @brief ModelBook: the hyperpatch models of a scene's `model` objects (issue 7, seed 001 §8.1,
/// §10.4-10.5), with a content hash and the model files written beside snapshots.
/// sculpt/codec/model_messages.h decodes the ModelIntent off the wire and
/// sculpt/codec/log_records.h holds its edit-log record; the scene's model edit kind
/// (Scene::EditModel) lives in models.cc.
#ifndef SCULPT_SERVER_SCENE_MODELS_H_
#define SCULPT_SERVER_SCENE_MODELS_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "config/server_config.h"
#include "scene/book_history.h"
#include "sculpt/codec/log_records.h"
#include "sculpt/codec/model_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/grid_editor.h"
#include "sculpt/hetero/validity.h"

namespace sculpt::server {

/// FNV-1a over the model's content (materials, coefficient positions and fractions bit for bit,
/// cells' pool indices, corner flags); cell versions are not content and are left out.
uint64_t ModelHash(const hetero::CompositeModel& model);

/// A model as saved beside the snapshots: the edit-log sequence it includes, its version and
/// the model itself (model_io's JSON).
struct SavedModel {
  uint64_t seq = 0;
  uint64_t version = 0;
  hetero::CompositeModel model;
};
/// Writes `path` atomically (temporary file, fsync, rename). Internal on I/O errors.
Status SaveModelFile(const std::string& path, uint64_t seq, uint64_t version,
                     const hetero::CompositeModel& model);
/// Reads what SaveModelFile wrote; NotFound when absent, DataLoss when it does not parse.
StatusOr<SavedModel> LoadModelFile(const std::string& path);

/// A scene object's hyperpatch model as the scene holds it.
struct ModelSummary {
  uint64_t version = 0;  // intents accepted since the scene first loaded the model
  uint64_t hash = 0;     // ModelHash
  size_t cells = 0;
  size_t coefficients = 0;
  std::string json;  // hetero::ModelToJson
};

/// The hyperpatch models of a scene's `model` objects: each model with its validity checker, its
/// version (intents accepted since the scene first loaded it) and the log sequence its file held
/// at start. An intent is checked against the model and applied to a copy (PrepareIntent,
/// changing nothing), then the copy is put in place (ApplyIntent). Models are saved beside each
/// snapshot (Save) and the intents logged after a file's sequence replayed at start (Replay).
/// The voxelised sculptures are not theirs: an intent does not re-voxelise its object.
/// Thread safety: none of its own. The scene calls it on its compute thread only, between two
/// edits.
class ModelBook {
 public:
  /// A model's version and ModelHash, as an intent's answer reports them.
  struct Stamp {
    uint64_t version = 0;
    uint64_t hash = 0;
  };
  /// An intent checked against its model and applied to a copy, ready to put in place; or, when
  /// the copy came out invalid, the library's reason (`rejection`) with the model as it stays.
  struct IntentPlan {
    std::string object;
    hetero::CompositeModel next;
    hetero::ValidityChecker next_checker;
    uint64_t version = 0;  // the model's version once applied
    size_t moved = 0;      // coefficients the intent moves
    std::optional<hetero::Rejection> rejection;
    Stamp now;  // the model before the intent (a rejection's answer reports it)
  };

  /// Loads the model of every `objects` entry whose primitive is "model": from its file under
  /// data_dir/models when one was saved (model, version and the log sequence the file holds),
  /// else from the object's model JSON at version 0. DataLoss naming a file that does not parse;
  /// the library's error, prefixed with "scene.objects <name>.model=<path>", for a model JSON
  /// that does not load. Forgets every model it held before.
  Status Open(const std::vector<ObjectConfig>& objects, const std::string& data_dir);

  /// Recovery: applies an intent logged at `seq` unless its model's file already holds it. An
  /// intent on an object without a model is ignored; one the library refuses is skipped with a
  /// warning (as the live server refused it).
  void Replay(uint64_t seq, const codec::ModelRecord& record);
  /// Writes every model, as of log sequence `seq`, to data_dir/models/<object>.json
  /// (atomically). False (each failure logged) if a file was not saved; true without models.
  bool Save(uint64_t seq) const;
  /// The same files under `dir` instead of the data directory (a standby's copy of them).
  bool SaveTo(const std::string& dir, uint64_t seq) const;

  /// Checks `edit` against its model and applies it to a copy in `plan`, changing nothing. Ok
  /// with the plan ready to apply; NotFound naming ModelIntent.object for an object without a
  /// model; InvalidArgument naming ModelIntent.corner or ModelIntent.cell (outside the model's
  /// coefficients or cells) or the field the library refuses; FailedPrecondition naming
  /// ModelIntent when the intent would leave the model invalid (plan->rejection holds the
  /// reason, plan->now the model as it stays).
  Status PrepareIntent(const codec::ModelEdit& edit, IntentPlan* plan) const;
  /// Puts a prepared intent in place (nothing else may change the model between the two calls)
  /// and returns the model's new version and hash. Records `intent` (logged at `seq`) as
  /// `author`'s newest undoable intent on the object (not recorded without an author).
  Stamp ApplyIntent(IntentPlan plan, uint64_t seq = 0, const std::string& author = {},
                    const hetero::EditIntent& intent = {}, uint64_t wall_ms = 0);

  /// Per-author undo and redo of model intents (issue 15, BookHistory): each model keeps its
  /// recent intents with the model before each, saved beside the model file at each Save
  /// (data_dir/models/<object>.history) and loaded by Open with it. Intents kept per author and
  /// model (set before Open).
  void set_undo_depth(size_t depth) { undo_depth_ = depth; }
  bool has_model(const std::string& object) const { return models_.count(object) != 0; }
  /// The sequence of the intent an undo (redo) by `author` would take back (put back), and for
  /// a redo the sequence of the undo that took it back (`undone_at`, may be null). NotFound for
  /// an object without a model, else BookHistory's errors.
  StatusOr<uint64_t> UndoTarget(const std::string& object, const std::string& author, bool redo,
                                uint64_t* undone_at = nullptr) const;
  /// Takes back (puts back) that intent: the model is rebuilt from before it with the later
  /// intents re-applied (one that would now leave the model invalid is skipped), its version
  /// raised. `at_seq` is the undo's own sequence. UndoTarget's errors, nothing changed.
  StatusOr<UndoOutcome> Undo(const std::string& object, const std::string& author, bool redo,
                             uint64_t at_seq);
  /// Recovery: the logged undo or redo of an intent at `seq`, unless the model's file holds it.
  void ReplayUndo(uint64_t seq, const codec::UndoRecord& record);
  /// Undoable and redoable intents of `author` on `object` (0, 0 without a model).
  std::pair<size_t, size_t> UndoDepth(const std::string& object, const std::string& author) const;
  /// The model's intents as the history view lists them (empty without a model).
  std::vector<HistoryEntry> Entries(const std::string& object, const std::string& author) const;
  /// The object's model version and hash now; nullopt for an object without a model.
  std::optional<Stamp> StampOf(const std::string& object) const;

  /// The object's model; NotFound ("object <name> holds no hyperpatch model") without one.
  StatusOr<ModelSummary> Info(const std::string& object) const;
  bool empty() const { return models_.empty(); }

 private:
  struct State {
    hetero::CompositeModel model;
    hetero::ValidityChecker checker;
  };
  using History = BookHistory<State, hetero::EditIntent>;
  struct Entry {
    hetero::CompositeModel model;
    hetero::ValidityChecker checker;
    uint64_t version = 0;
    uint64_t file_seq = 0;  // the model file held the log up to this seq at start-up
    History history{"model intent", 64};
  };

  std::string data_dir_;
  size_t undo_depth_ = 64;
  std::map<std::string, Entry> models_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_MODELS_H_
