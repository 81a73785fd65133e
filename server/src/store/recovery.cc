/// @brief Recover: newest snapshots, then the log tail replayed per object past its snapshot.
#include "store/recovery.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <utility>

namespace sculpt::server::store {
namespace {

void Warn(RecoveryReport* report, std::string message) {
  spdlog::warn("recovery: {}", message);
  report->warnings.push_back(std::move(message));
}

}  // namespace

StatusOr<RecoveredScene> Recover(const std::string& data_dir, const RecoveryOptions& options,
                                 const MakeInitialFn& make_initial, const RouteFn& route,
                                 const ApplyFn& apply) {
  if (options.objects.empty()) {
    return InvalidArgument("RecoveryOptions.objects is empty; the scene must name its objects");
  }
  std::set<std::string> names;
  for (const std::string& object : options.objects) {
    SCULPT_RETURN_IF_ERROR(ValidateObjectName(object));
    if (!names.insert(object).second) {
      return InvalidArgument("RecoveryOptions.objects names \"" + object + "\" twice");
    }
  }
  const std::filesystem::path root(data_dir);

  RecoveredScene scene;
  RecoveryReport& report = scene.report;
  SCULPT_ASSIGN_OR_RETURN(
      scene.snapshots, SnapshotStore::Open((root / kSnapshotSubdir).string(), options.snapshots));
  SCULPT_ASSIGN_OR_RETURN(std::vector<Snapshot> loaded,
                          scene.snapshots->LoadNewest(&report.skipped_snapshots));
  bool any_snapshot = false;
  uint64_t newest_snapshot = 0;
  for (Snapshot& snap : loaded) {
    if (names.count(snap.object) == 0) {
      Warn(&report, "snapshot of object " + snap.object + " at seq " + std::to_string(snap.seq) +
                        " ignored: the scene does not define the object");
      continue;
    }
    any_snapshot = true;
    newest_snapshot = std::max(newest_snapshot, snap.seq);
    scene.snapshot_seq[snap.object] = snap.seq;
    scene.sculptures.emplace(snap.object, std::move(snap.sculpture));
  }
  for (const std::string& object : options.objects) {
    if (scene.sculptures.count(object) != 0) continue;
    StatusOr<levelset::Sculpture> initial = make_initial(object);
    if (!initial.ok()) {
      return WithContext(initial.status(), "building the initial object " + object);
    }
    scene.snapshot_seq[object] = 0;
    scene.sculptures.emplace(object, std::move(initial).value());
  }

  SCULPT_ASSIGN_OR_RETURN(scene.log,
                          EditLog::Open((root / kLogSubdir).string(), options.log, &report));
  EditLog& log = *scene.log;

  // The log is complete only after its base (older segments were dropped once a snapshot
  // covered them). A snapshot older than that would silently miss the edits in between.
  const uint64_t base = log.base_seq();
  if (base > 0 && !any_snapshot) {
    return DataLoss("edit log in " + (root / kLogSubdir).string() + " starts after seq " +
                    std::to_string(base) + " but " + (root / kSnapshotSubdir).string() +
                    " holds no usable snapshot: the edits up to seq " + std::to_string(base) +
                    " are gone; restore the snapshots or move the log away to start over");
  }
  uint64_t replay_from = UINT64_MAX;
  for (const auto& [object, seq] : scene.snapshot_seq) {
    replay_from = std::min(replay_from, seq);
    if (seq == 0) {
      if (base > 0) {
        Warn(&report, "object " + object + " has no snapshot and is built from the scene; the " +
                          "log holds its edits only after seq " + std::to_string(base) +
                          " (fine for an object new to the scene)");
      }
      continue;
    }
    if (seq < base) {
      return DataLoss("snapshot of object " + object + " is at seq " + std::to_string(seq) +
                      " but the edit log starts after seq " + std::to_string(base) +
                      ": the edits in between are gone (a newer snapshot failed to load?)");
    }
  }

  const uint64_t log_last = log.last_seq();
  if (report.records == 0 && any_snapshot) {
    // An empty log (e.g. moved away by an operator): new records continue after the snapshots,
    // and the log's first segment records that it is complete from the oldest one on.
    uint64_t oldest = UINT64_MAX;
    for (const auto& [object, seq] : scene.snapshot_seq) {
      if (seq > 0) oldest = std::min(oldest, seq);
    }
    if (oldest > log_last) SCULPT_RETURN_IF_ERROR(log.StartAfter(oldest));
  } else if (newest_snapshot > log_last) {
    Warn(&report, "the newest snapshot (seq " + std::to_string(newest_snapshot) +
                      ") is ahead of the edit log (last seq " + std::to_string(log_last) +
                      "): it holds edits whose records were lost before they were durable");
  }

  if (options.on_loaded) {
    for (const auto& [object, seq] : scene.snapshot_seq) options.on_loaded(object, seq);
  }
  // Epochs are checked along the whole log: a stale owner's record before the snapshots is in
  // their state already, and starting would serve it.
  uint64_t highest_at = 0;  // the first seq of scene.highest_epoch
  const uint64_t walk_from = options.epoch_of ? 0 : replay_from;
  Status replay = log.ForEachFrom(walk_from, [&](const LogRecord& record) -> Status {
    if (options.epoch_of) {
      StatusOr<uint64_t> epoch = options.epoch_of(record);
      if (!epoch.ok()) {
        return WithContext(epoch.status(),
                           "reading the epoch of edit log record seq " + std::to_string(record.seq));
      }
      // Epoch 0 is no ownership at all (a single process): a data directory may serve alone
      // before and after it served in a cluster, and no stale owner writes epoch 0.
      if (*epoch != 0 && *epoch < scene.highest_epoch) {
        return DataLoss(
            "edit log in " + (root / kLogSubdir).string() + ": record seq " +
            std::to_string(record.seq) + " has epoch " + std::to_string(*epoch) +
            ", lower than epoch " + std::to_string(scene.highest_epoch) + " of seq " +
            std::to_string(highest_at) +
            " before it: a stale owner wrote it after a newer owner had taken the scene over. "
            "Nothing from seq " + std::to_string(record.seq) +
            " on was replayed; compare with the scene's current owner, and move this data "
            "directory aside (or cut its log before seq " + std::to_string(record.seq) +
            ") to start from it");
      }
      if (scene.epoch_runs.empty() || *epoch != scene.epoch_runs.rbegin()->second) {
        scene.epoch_runs.emplace(record.seq, *epoch);
      }
      if (*epoch > scene.highest_epoch) {
        scene.highest_epoch = *epoch;
        highest_at = record.seq;
      }
      if (record.seq <= replay_from) return Status::Ok();  // in every object's snapshot
    }
    StatusOr<std::string> object = route(record);
    if (!object.ok()) {
      return WithContext(object.status(),
                         "routing edit log record seq " + std::to_string(record.seq));
    }
    auto it = scene.sculptures.find(*object);
    if (it == scene.sculptures.end()) {
      return FailedPrecondition("edit log record seq " + std::to_string(record.seq) +
                                " edits object \"" + *object +
                                "\", which the scene does not define; restore it in the scene "
                                "file to replay its edits");
    }
    if (record.seq <= scene.snapshot_seq[*object]) return Status::Ok();
    Status applied = apply(it->second, record);
    if (!applied.ok()) {
      return WithContext(applied, "replaying edit log record seq " + std::to_string(record.seq) +
                                      " on object " + *object);
    }
    ++report.replayed_records;
    return Status::Ok();
  });
  if (!replay.ok()) return replay;

  scene.last_seq = std::max(log.last_seq(), newest_snapshot);
  const auto from_snapshots = std::count_if(scene.snapshot_seq.begin(), scene.snapshot_seq.end(),
                                            [](const auto& entry) { return entry.second > 0; });
  spdlog::info("recovery of {}: {} objects ({} from snapshots), {} records replayed, last seq {}",
               data_dir, scene.sculptures.size(), from_snapshots, report.replayed_records,
               scene.last_seq);
  return scene;
}

}  // namespace sculpt::server::store
