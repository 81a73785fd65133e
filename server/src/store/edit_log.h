/// @brief EditLog: the append-only, checksummed, segmented log of validated edits that sculptd
/// writes before it acknowledges an edit, and reads back at start-up to replay the tail.
#ifndef SCULPT_SERVER_STORE_EDIT_LOG_H_
#define SCULPT_SERVER_STORE_EDIT_LOG_H_

#include <sys/types.h>
#include <sys/uio.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "sculpt/core/latency_histogram.h"
#include "sculpt/core/status.h"

namespace sculpt::server::store {

/// When appended records reach the disk. Under both policies sculptd acknowledges an edit only
/// once durable_seq() covers it (OnDurable), so nothing acknowledged is lost to a process crash
/// or to a power loss (given a disk that honours flushes). They differ in what is not yet
/// acknowledged:
/// - kAlways: Append returns only after fdatasync, so an edit is applied and fanned out only
///   once it is on disk. A power loss loses nothing that anyone saw. Cost: one fdatasync
///   (about 0.5 ms on the dev VM's ext4) on the compute thread per edit.
/// - kGroup: Append returns after write(); the compute thread applies and fans out at once and
///   the acknowledgement waits for the next group fdatasync. A process crash (kill -9, abort)
///   loses nothing written, since the kernel holds the page cache; a power loss or kernel panic
///   loses the edits of at most the last group window (about group_ms plus one fdatasync),
///   which were never acknowledged to their authors but may have been shown to other clients.
struct FsyncPolicy {
  enum class Mode {
    /// Append returns after fdatasync: each record is durable when Append returns.
    kAlways,
    /// Append returns after write(); a background thread fdatasyncs at most once every group_ms
    /// (at once after a quiet period) and reports progress through durable_seq() / OnDurable.
    kGroup,
  };
  Mode mode = Mode::kGroup;
  /// Group window in milliseconds, in [kMinGroupMs, kMaxGroupMs]; used by kGroup only.
  int group_ms = 5;
};

inline constexpr int kMinGroupMs = 1;
inline constexpr int kMaxGroupMs = 1000;

/// Parses a configuration value: "always" or "group". InvalidArgument naming the value otherwise.
StatusOr<FsyncPolicy::Mode> ParseFsyncMode(std::string_view text);
/// InvalidArgument naming the field, the value and the range for a bad policy.
Status ValidateFsyncPolicy(const FsyncPolicy& policy);

/// Default size at which the log starts a new segment file.
inline constexpr uint64_t kDefaultSegmentBytes = 64ull << 20;
/// Largest payload Append accepts (and the largest length a reader believes).
inline constexpr uint32_t kMaxRecordPayload = 16u << 20;
/// Sizes of the segment header and of the header before each record's payload.
inline constexpr uint64_t kSegmentHeaderBytes = 32;
inline constexpr uint64_t kRecordHeaderBytes = 16;
/// Set in a record's length field when the next record belongs to the same group (an edit
/// logged as several records, e.g. a stroke's poses): recovery sees a group whole or not at all.
inline constexpr uint32_t kGroupContinues = 1u << 31;
/// Set in the length field of a segment's end marker: a record without payload whose seq is the
/// first seq of the segment that follows, written once that segment exists. A last segment that
/// ends in a marker means a newer segment was lost.
inline constexpr uint32_t kSegmentEnd = 1u << 30;

struct EditLogOptions {
  FsyncPolicy fsync;
  /// A segment is closed and a new one started when the next record would take it past this
  /// size (a record larger than this gets a segment of its own). At least
  /// kSegmentHeaderBytes + kRecordHeaderBytes.
  uint64_t segment_bytes = kDefaultSegmentBytes;
  /// Tests only: replaces ::writev for every write of the log (inject ENOSPC and the like).
  std::function<ssize_t(int fd, const iovec* iov, int count)> writev_for_testing;
};

/// What start-up found. EditLog::Open fills the log fields; Recover() adds the snapshot fields.
struct RecoveryReport {
  /// Segment files scanned and the records they hold after any tail was dropped.
  uint64_t segments = 0;
  uint64_t records = 0;
  /// The log holds every record with seq > log_base_seq (the part before it was dropped after
  /// a snapshot covered it); first and last seq of the records it holds (0 when empty).
  uint64_t log_base_seq = 0;
  uint64_t first_seq = 0;
  uint64_t last_seq = 0;
  /// A torn final record (crash in the middle of a write) cut off the last segment.
  uint64_t dropped_tail_bytes = 0;
  std::string dropped_tail_file;
  std::string dropped_tail_reason;
  /// Filled by Recover(): records applied on top of the snapshots, and snapshot files that
  /// could not be read (each "file: reason"), so an older snapshot was used.
  uint64_t replayed_records = 0;
  std::vector<std::string> skipped_snapshots;
  /// Everything else worth a line in the start-up log (also sent to spdlog::warn).
  std::vector<std::string> warnings;
};

/// What EditLog::Repair found and did (or, with dry_run, would do).
struct RepairReport {
  /// One line per change: the file, the offset or the whole file, and the seqs it held.
  std::vector<std::string> actions;
  /// Every acknowledged edit the repair gives up, as seq ranges ("seq 11..40 (30 records)").
  std::vector<std::string> discarded;
  /// True when the log needed no change.
  bool clean = true;
};

/// One record: the caller's global sequence number and its opaque payload (sculptd stores a
/// serialized protobuf; the log never looks inside).
struct LogRecord {
  uint64_t seq = 0;
  std::string payload;
};

/// The edit log of one data directory: segment files `log-<first seq, 20 digits>.sclog`.
///
/// On disk (all integers little-endian):
///   segment header, 32 bytes: "SCLPTLOG" | u32 version (1) | u32 header size (32) |
///                             u64 base seq | u32 reserved (0) | u32 CRC32C of the 28 bytes before
///   then records:             u32 payload length | u32 CRC32C(u64 seq bytes + payload) | u64 seq |
///                             payload
/// The length's top bit (kGroupContinues) says the next record belongs to the same group; the
/// CRC covers seq and payload only. A group never spans two segments. A closed segment ends in
/// an end marker (kSegmentEnd, no payload, seq = the next segment's first seq).
/// `base seq` is the last seq written before the segment began: the segments chain (each base
/// equals the previous segment's last seq), so a missing segment is detected, and the first
/// segment's base says from where on the log is complete.
///
/// Thread safety: Append, Roll, StartAfter and ReadFrom/ForEachFrom are called from one thread
/// (the scene's compute thread). durable_seq(), last_seq(), Sync(), DropSegmentsBefore() and
/// OnDurable() may be called from any thread. The OnDurable callback runs on the thread that made
/// the records durable (the group sync thread, the Append caller under kAlways, or a Sync caller)
/// and must not call back into the log except durable_seq() / last_seq().
class EditLog {
 public:
  using DurableCallback = std::function<void(uint64_t durable_seq)>;

  /// Opens (creating it if needed) the log in `dir`, verifies every record, and makes what is on
  /// disk durable. A torn final record of the last segment is cut off (the file is truncated back
  /// to the last good record) with spdlog::warn and noted in `report` (may be null). Returns
  /// DataLoss naming the file and the offset for a corrupt record followed by more data, a bad
  /// segment header, a missing segment or a non-increasing sequence; FailedPrecondition for a
  /// segment of another format version; InvalidArgument for bad options; Internal for I/O errors.
  static StatusOr<std::unique_ptr<EditLog>> Open(const std::string& dir, FsyncPolicy policy,
                                                 RecoveryReport* report);
  static StatusOr<std::unique_ptr<EditLog>> Open(const std::string& dir,
                                                 const EditLogOptions& options,
                                                 RecoveryReport* report);

  /// Makes the log in `dir` (not open elsewhere) one that Open accepts by giving up the least:
  /// a damaged record, a gap between segments or a torn group cuts its segment at the last
  /// complete group before it, and every later segment is renamed to `<name>.discarded` (the log
  /// must stay contiguous); an end marker naming a lost newer segment is removed. With dry_run
  /// nothing changes. Internal for I/O errors.
  static StatusOr<RepairReport> Repair(const std::string& dir, bool dry_run);

  /// Stops the sync thread, makes every written record durable and closes the file.
  ~EditLog();
  EditLog(const EditLog&) = delete;
  EditLog& operator=(const EditLog&) = delete;

  /// Appends one record with one write() call. kAlways: returns after fdatasync (durable).
  /// kGroup: returns after the write; the record is durable once durable_seq() >= seq.
  /// FailedPrecondition if seq <= last_seq(); InvalidArgument for a payload over
  /// kMaxRecordPayload; ResourceExhausted for a full disk (field edit_log.free_bytes, the free
  /// bytes, the directory): nothing of the record stays and a later Append succeeds once space
  /// is freed; Internal for another I/O error, after which every call fails (see Sync).
  Status Append(uint64_t seq, std::string_view payload);

  /// Appends payloads[i] at seq first_seq + i as one group, in one write() call: start-up
  /// recovers all of the group or none of it (a group cut short by a crash is a torn tail and is
  /// cut off whole). Durability and errors as Append; InvalidArgument for an empty group.
  Status AppendGroup(uint64_t first_seq, const std::vector<std::string>& payloads);

  /// fdatasyncs now and advances durable_seq() to every record written so far. A failed
  /// fdatasync poisons the log: the kernel may have dropped the unwritten pages, so neither a
  /// retry nor a later Append could be trusted; the server must stop acknowledging.
  Status Sync();

  /// The next Append starts a new segment (call it right after the record a snapshot is taken
  /// at, so DropSegmentsBefore can delete the older segments once the snapshot is on disk).
  /// Does nothing if the current segment holds no records.
  void Roll();

  /// Deletes every closed segment whose records all have seq <= `seq` (a snapshot at `seq`
  /// covers them). Never deletes the segment being appended to. Internal on an unlink error.
  Status DropSegmentsBefore(uint64_t seq);

  /// For an empty log only (no records): states that the records up to `seq` are covered by
  /// snapshots, so the first segment records `seq` as its base and Append requires seq > it.
  /// FailedPrecondition if the log holds records.
  Status StartAfter(uint64_t seq);

  /// Calls `visit` with each record whose seq > after_seq, in order, reading the segments again
  /// and checking every CRC (DataLoss naming file and offset on a mismatch). A non-ok Status
  /// from `visit` stops the walk and is returned. Call from the appending thread.
  Status ForEachFrom(uint64_t after_seq,
                     const std::function<Status(const LogRecord& record)>& visit) const;
  /// ForEachFrom collected into a vector (for tests and small logs).
  StatusOr<std::vector<LogRecord>> ReadFrom(uint64_t after_seq) const;

  /// Registers the callback called with the new durable seq each time it advances (strictly
  /// increasing values). Replaces any previous callback.
  void OnDurable(DurableCallback callback);

  /// Last seq known to be on disk.
  uint64_t durable_seq() const { return durable_seq_.load(std::memory_order_acquire); }
  /// Last seq appended (or the StartAfter base, or the first segment's base when empty).
  uint64_t last_seq() const { return written_seq_.load(std::memory_order_acquire); }
  /// Seq after which the log is complete: the first segment's base.
  uint64_t base_seq() const;
  /// Number of segment files.
  size_t segment_count() const;
  const std::string& dir() const { return dir_; }
  const FsyncPolicy& policy() const { return options_.fsync; }
  /// Durations of the fdatasync calls that made appended records durable (the group sync,
  /// Sync(), each Append under kAlways) since Open; the scan at Open is not counted.
  LatencyHistogram::Snapshot sync_seconds() const { return sync_seconds_.Read(); }

 private:
  struct Segment {
    std::string path;
    uint64_t base_seq = 0;   // last seq before this segment
    uint64_t first_seq = 0;  // from the file name
    uint64_t last_seq = 0;   // 0 while it holds no records
    uint64_t bytes = 0;      // valid bytes (header + whole records)
    uint64_t next_first = 0; // the end marker's seq; 0 while the segment is open
  };

  EditLog(std::string dir, const EditLogOptions& options);
  Status Scan(RecoveryReport* report);
  Status StartSegment(uint64_t first_seq);
  Status AppendRecords(uint64_t first_seq, const std::string_view* payloads, size_t count);
  /// fdatasync of the active file; caller holds file_mu_. Returns the seq now durable.
  StatusOr<uint64_t> SyncLocked();
  Status Poison(Status status);
  void NotifyDurable(uint64_t seq);
  void SyncLoop();

  const std::string dir_;
  const EditLogOptions options_;

  // Guards fd_ changes, segments_ and poisoned_ against the sync thread, Sync() and
  // DropSegmentsBefore(). Append writes without it (a fdatasync in progress must not stall the
  // compute thread): only the appending thread changes fd_, and it does so under the lock.
  mutable std::mutex file_mu_;
  int fd_ = -1;
  std::vector<Segment> segments_;  // the last one is the active segment while fd_ >= 0
  Status poisoned_;
  std::atomic<bool> is_poisoned_{false};

  // Appending thread only: the active segment's size and last seq (copied into segments_ when
  // it is closed), and whether the next Append starts a new segment.
  std::string active_path_;
  uint64_t active_bytes_ = 0;
  uint64_t active_last_seq_ = 0;
  bool roll_requested_ = false;

  std::atomic<uint64_t> written_seq_{0};
  std::atomic<uint64_t> durable_seq_{0};
  LatencyHistogram sync_seconds_;

  std::mutex callback_mu_;
  DurableCallback callback_;
  uint64_t notified_seq_ = 0;

  // Group sync thread.
  std::mutex wake_mu_;
  std::condition_variable wake_cv_;
  std::atomic<bool> wake_pending_{false};
  bool stop_ = false;
  std::thread sync_thread_;
};

}  // namespace sculpt::server::store

#endif  // SCULPT_SERVER_STORE_EDIT_LOG_H_
