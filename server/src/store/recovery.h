/// @brief Recover: rebuild a scene at start-up from the newest snapshots plus the edit log tail.
#ifndef SCULPT_SERVER_STORE_RECOVERY_H_
#define SCULPT_SERVER_STORE_RECOVERY_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"
#include "store/edit_log.h"
#include "store/snapshot_store.h"

namespace sculpt::server::store {

// How sculptd drives the store (the compute thread owns the log and the objects):
//   start-up:  Recover() -> sculptures, last_seq, the open log and snapshot store; then the
//              resend table (resend_table.h) is merged into the resend filter.
//   each edit: log->Append(seq, payload) (a multi-record edit: log->AppendGroup, recovered whole
//              or not at all), apply, fan out; acknowledge from log->OnDurable.
//   snapshot:  log->Sync() (so the snapshot holds only durable edits), SaveResendTable and the
//              side files at seq, then per object snapshots->WriteAsync(seq, name,
//              sculpture.Clone(), done), then log->Roll(); when every object's snapshot of the
//              round at seq S reported Ok, log->DropSegmentsBefore(S') where S' is the previous
//              complete round, so a damaged newest snapshot still has the previous one plus
//              the longer tail to fall back to.

/// The parts of a data directory.
inline constexpr char kLogSubdir[] = "log";
inline constexpr char kSnapshotSubdir[] = "snapshots";

struct RecoveryOptions {
  /// The scene's objects. Each gets its newest snapshot or, without one, make_initial(). A
  /// snapshot of an object not listed is ignored with a warning.
  std::vector<std::string> objects;
  EditLogOptions log;
  SnapshotStoreOptions snapshots;
  /// Called once per object after it is loaded (from its snapshot at `snapshot_seq`, or built
  /// with seq 0) and before the log tail is replayed onto it: where side state kept beside a
  /// snapshot (the undo history) is loaded to match. Optional.
  std::function<void(const std::string& object, uint64_t snapshot_seq)> on_loaded;
  /// The ownership epoch a record was written under (cluster mode, issue 17; 0 for none), or the
  /// error of a payload that does not decode. Optional: when set, Recover reads every record the
  /// log holds (not only the tail past the snapshots) and requires epochs that never go down
  /// along it; see Recover.
  std::function<StatusOr<uint64_t>(const LogRecord& record)> epoch_of;
};

/// A scene as it was after the last record in the log (or the newest snapshot, if later).
struct RecoveredScene {
  std::map<std::string, levelset::Sculpture> sculptures;
  /// Seq of the snapshot each object was loaded from; 0 when built by make_initial.
  std::map<std::string, uint64_t> snapshot_seq;
  /// The largest seq in the log or in a snapshot: the next edit gets last_seq + 1.
  uint64_t last_seq = 0;
  /// The opened log and snapshot store, ready for the server to continue with.
  std::unique_ptr<EditLog> log;
  std::unique_ptr<SnapshotStore> snapshots;
  RecoveryReport report;
  /// With RecoveryOptions::epoch_of: where each run of one epoch begins in the log, first seq ->
  /// epoch (the first record's epoch at its seq, then an entry at each record whose epoch differs
  /// from the one before it); empty for an empty log.
  std::map<uint64_t, uint64_t> epoch_runs;
  /// The highest epoch in the log (0: none, or no epoch_of).
  uint64_t highest_epoch = 0;
};

/// Builds an object with no snapshot from the scene description.
using MakeInitialFn = std::function<StatusOr<levelset::Sculpture>(const std::string& object)>;
/// Names the object a record edits (the payload is the caller's; the store never parses it).
using RouteFn = std::function<StatusOr<std::string>(const LogRecord& record)>;
/// Applies a record to its object. Must reproduce what the live server did with the record:
/// return Ok for an edit the live server rejected after logging it; any error stops recovery.
using ApplyFn = std::function<Status(levelset::Sculpture& sculpture, const LogRecord& record)>;

/// Recovers the scene stored in `data_dir` (`<data_dir>/snapshots`, `<data_dir>/log`; both are
/// created when missing, so a new directory gives the initial scene at seq 0).
///
/// Routing is split from applying so that recovery can skip, per object, the records its
/// snapshot already holds: each record with seq > the oldest snapshot's seq is passed to
/// `route`; if seq > the snapshot seq of the named object, `apply` runs on that object.
/// Records are replayed in seq order on the calling thread.
///
/// Errors: InvalidArgument for bad options (no objects, a bad or repeated name); the log's
/// DataLoss for corruption; DataLoss when a snapshot is older than the start of the log (the
/// edits between them are gone) or no snapshot exists while the log was trimmed;
/// FailedPrecondition when a record names an object the scene lacks; make_initial's, route's or
/// apply's error with the object and seq prepended.
///
/// With options.epoch_of, a record whose epoch is lower than that of a record before it was
/// written by an owner after a newer owner had taken the scene over (a stale owner): DataLoss
/// naming the record's seq, its epoch, the highest epoch before it and the seq that carried it;
/// nothing from that record on is applied. It is refused, not cut off like a torn tail: a torn
/// tail was never durable, so never acknowledged, while this record (and any after it) is whole
/// and durable and may have been acknowledged; only an operator can tell which copy of the scene
/// is right. Epoch 0 (no ownership: a single process) is never refused and raises nothing, so
/// a data directory may serve alone again after serving in a cluster. epoch_of's error is
/// returned with the seq prepended.
StatusOr<RecoveredScene> Recover(const std::string& data_dir, const RecoveryOptions& options,
                                 const MakeInitialFn& make_initial, const RouteFn& route,
                                 const ApplyFn& apply);

}  // namespace sculpt::server::store

#endif  // SCULPT_SERVER_STORE_RECOVERY_H_
