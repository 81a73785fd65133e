/// @brief SnapshotStore: per-object `.vdb` snapshots at a sequence number, written by one
/// background thread so that taking a snapshot never stalls edits, with newest-K retention.
#ifndef SCULPT_SERVER_STORE_SNAPSHOT_STORE_H_
#define SCULPT_SERVER_STORE_SNAPSHOT_STORE_H_

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::server::store {

/// The newest readable snapshot of one object.
struct Snapshot {
  std::string object;
  uint64_t seq = 0;
  levelset::Sculpture sculpture;
};

/// A snapshot file found in the directory (not loaded).
struct SnapshotFile {
  std::string object;
  uint64_t seq = 0;
  std::string path;
};

/// Largest snapshot payload a reader believes by default (a size read from disk is checked
/// against this and against the file's size before anything is allocated).
inline constexpr uint64_t kDefaultMaxSnapshotBytes = 16ull << 30;

struct SnapshotStoreOptions {
  /// Snapshots kept per object (the newest ones), in [1, 1000].
  int keep = 3;
  /// Largest snapshot payload LoadNewest reads.
  uint64_t max_bytes = kDefaultMaxSnapshotBytes;
};

/// Reads one snapshot file: checks the header checksum, the seq against `expected_seq` (from the
/// file name), the payload size against the file and `max_bytes`, and the payload checksum, and
/// only then parses the grids. DataLoss naming the file and what is wrong for a damaged file;
/// FailedPrecondition for another format version; Internal for I/O errors. A file written before
/// snapshots had checksums (a bare .vdb) is loaded with a warning.
StatusOr<levelset::Sculpture> LoadSnapshotFile(const std::string& path, uint64_t expected_seq,
                                               uint64_t max_bytes = kDefaultMaxSnapshotBytes);

/// Object names become part of file names: 1 to 64 characters from [A-Za-z0-9_.-], not
/// starting with '.'. InvalidArgument naming the value otherwise.
Status ValidateObjectName(const std::string& object);

/// `snap-<seq, 20 digits>-<object>.vdb` files in one directory. Each holds a checksummed header
/// (magic "SCLPSNAP", seq, payload size and CRC32C) followed by the OpenVDB file bytes.
///
/// A snapshot is written to `<name>.writing` (SaveVdb itself goes through `.tmp`), fsynced,
/// renamed to its final name and the directory fsynced: a final name always holds a complete,
/// durable file, so the edit log may be trimmed once `done` reports Ok.
///
/// Thread safety: every method may be called from any thread. One background thread writes;
/// `done` callbacks must not call WaitIdle() or destroy the store.
class SnapshotStore {
 public:
  /// Creates `dir` if needed and removes leftovers of interrupted writes (`.writing`, `.tmp`).
  /// InvalidArgument for bad options; Internal for I/O errors.
  static StatusOr<std::unique_ptr<SnapshotStore>> Open(const std::string& dir,
                                                       SnapshotStoreOptions options = {});

  /// Writes every queued snapshot, then stops the writer thread.
  ~SnapshotStore();
  SnapshotStore(const SnapshotStore&) = delete;
  SnapshotStore& operator=(const SnapshotStore&) = delete;

  /// Writes `sculpture` as the snapshot of `object` at `seq` on the calling thread, then deletes
  /// all but the newest `keep` snapshots of the object. InvalidArgument for a bad object name;
  /// Internal for I/O errors.
  Status Write(uint64_t seq, const std::string& object, const levelset::Sculpture& sculpture);

  /// Hands a Clone() taken on the compute thread at `seq` to the writer thread and returns at
  /// once. At most one snapshot per object waits behind the one being written: a newer one
  /// replaces it, and the replaced one's `done` is called at once, on the calling thread, with
  /// Unavailable("... superseded ..."), so memory stays bounded by two clones per object.
  /// Otherwise `done` (may be empty) gets the write's Status on the writer thread; Ok means the
  /// file is durable and the log up to `seq` may be dropped for this object.
  void WriteAsync(uint64_t seq, std::string object, levelset::Sculpture clone,
                  std::function<void(Status)> done);

  /// Blocks until nothing is queued or being written. Returns the first write error since the
  /// previous WaitIdle (superseded snapshots are not errors), else Ok.
  Status WaitIdle();

  /// For each object, the newest snapshot that loads. A newest file that fails to load (e.g.
  /// cut short by a power loss during the write) is skipped with spdlog::warn, and described in
  /// `skipped` ("file: reason") if given, and the next older one is tried. DataLoss if every
  /// snapshot of an object fails to load. Objects in name order.
  StatusOr<std::vector<Snapshot>> LoadNewest(std::vector<std::string>* skipped = nullptr) const;

  /// Every snapshot file, by object then seq ascending.
  StatusOr<std::vector<SnapshotFile>> List() const;

  const std::string& dir() const { return dir_; }
  /// Snapshots written by the background thread so far (for tests and metrics).
  uint64_t async_writes() const;
  /// Snapshots replaced in the queue before they were written.
  uint64_t superseded() const;

 private:
  struct Job {
    uint64_t seq = 0;
    std::string object;
    std::unique_ptr<levelset::Sculpture> sculpture;
    std::function<void(Status)> done;
  };

  SnapshotStore(std::string dir, SnapshotStoreOptions options);
  void WriterLoop();
  Status DeleteOld(const std::string& object);

  const std::string dir_;
  const SnapshotStoreOptions options_;
  // Serialises the file work of Write() and the writer thread (same names, retention).
  std::mutex io_mu_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::string, Job> queued_;  // at most one per object
  std::deque<std::string> order_;      // objects of queued_ in arrival order (no starvation)
  bool writing_ = false;
  bool stop_ = false;
  Status first_error_;
  uint64_t async_writes_ = 0;
  uint64_t superseded_ = 0;
  std::thread writer_;
};

}  // namespace sculpt::server::store

#endif  // SCULPT_SERVER_STORE_SNAPSHOT_STORE_H_
