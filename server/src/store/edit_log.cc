/// @brief EditLog: segment files, record framing with CRC32C, group commit and start-up scan.
#include "store/edit_log.h"

#include "store/durable_file.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <limits.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

namespace sculpt::server::store {
namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'S', 'C', 'L', 'P', 'T', 'L', 'O', 'G'};
constexpr uint32_t kFormatVersion = 1;
constexpr uint64_t kMinSegmentBytes = kSegmentHeaderBytes + kRecordHeaderBytes;

void PutU32(uint8_t* p, uint32_t v) { PutLittleEndian(p, v); }
void PutU64(uint8_t* p, uint64_t v) { PutLittleEndian(p, v); }
uint32_t GetU32(const uint8_t* p) { return GetLittleEndian<uint32_t>(p); }
uint64_t GetU64(const uint8_t* p) { return GetLittleEndian<uint64_t>(p); }

uint32_t RecordCrc(const uint8_t* seq_le, const void* payload, size_t size) {
  Crc32cState crc;
  crc.process_bytes(seq_le, 8);
  crc.process_bytes(payload, size);
  return crc.checksum();
}

uint32_t HeaderCrc(const uint8_t* header) {
  Crc32cState crc;
  crc.process_bytes(header, kSegmentHeaderBytes - 4);
  return crc.checksum();
}

std::string SegmentFileName(uint64_t first_seq) {
  char name[64];
  std::snprintf(name, sizeof(name), "log-%020" PRIu64 ".sclog", first_seq);
  return name;
}

// "log-" + 20 digits + ".sclog"; anything else in the directory (a segment an operator renamed
// to move it away, editor backups) is not part of the log.
bool ParseSegmentFileName(const std::string& name, uint64_t* first_seq) {
  constexpr size_t kDigits = 20;
  if (name.size() != 4 + kDigits + 6 || name.compare(0, 4, "log-") != 0 ||
      name.compare(4 + kDigits, 6, ".sclog") != 0) {
    return false;
  }
  uint64_t v = 0;
  for (size_t i = 4; i < 4 + kDigits; ++i) {
    if (name[i] < '0' || name[i] > '9') return false;
    const uint64_t digit = static_cast<uint64_t>(name[i] - '0');
    if (v > (UINT64_MAX - digit) / 10) return false;
    v = v * 10 + digit;
  }
  *first_seq = v;
  return true;
}

Status Errno(const std::string& what, const std::string& path) {
  return Internal("edit log: " + what + " " + path + ": " + std::strerror(errno));
}

std::string CorruptMessage(const std::string& path, uint64_t offset, const std::string& where,
                           const std::string& reason, const std::string& stake = "") {
  const std::string data_dir = fs::path(path).parent_path().parent_path().string();
  return "edit log " + path + " corrupt at offset " + std::to_string(offset) + " (" + where +
         "): " + reason + (stake.empty() ? "" : "; at stake: " + stake) +
         "; refusing to start — `sculptd repair --data " + data_dir +
         " --dry-run` says exactly what a repair would discard (the log must stay contiguous)";
}

// A full disk is the operator's to fix and passes: the error names the directory and the free
// space, and the log stays usable.
Status DiskFull(const std::string& path, uint64_t need, int err) {
  const std::string dir = fs::path(path).parent_path().string();
  struct statvfs vfs;
  const uint64_t free_bytes =
      ::statvfs(dir.c_str(), &vfs) == 0 ? static_cast<uint64_t>(vfs.f_bavail) * vfs.f_frsize : 0;
  return Outside("edit_log.free_bytes", std::to_string(free_bytes),
                 std::string("[") + std::to_string(need) + ", ...) in " + dir + " (writing " +
                     path + ": " + std::strerror(err) + "); edits resume once space is freed",
                 Status::Code::kResourceExhausted);
}

using WritevFn = std::function<ssize_t(int, const iovec*, int)>;

Status WriteFully(int fd, iovec* iov, int count, const std::string& path,
                  const WritevFn& writev_fn = nullptr) {
  uint64_t left_total = 0;
  for (int i = 0; i < count; ++i) left_total += iov[i].iov_len;
  while (count > 0) {
    const int n_iov = std::min(count, IOV_MAX);
    const ssize_t n = writev_fn ? writev_fn(fd, iov, n_iov) : ::writev(fd, iov, n_iov);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == ENOSPC || errno == EDQUOT) return DiskFull(path, left_total, errno);
      return Errno("writing", path);
    }
    size_t left = static_cast<size_t>(n);
    left_total -= left;
    while (count > 0 && left >= iov->iov_len) {
      left -= iov->iov_len;
      ++iov;
      --count;
    }
    if (count > 0) {
      iov->iov_base = static_cast<uint8_t*>(iov->iov_base) + left;
      iov->iov_len -= left;
    }
  }
  return Status::Ok();
}

Status ReadWholeFile(const std::string& path, uint64_t limit, std::string* out) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Errno("opening", path);
  struct stat st;
  if (::fstat(fd, &st) != 0) {
    Status s = Errno("stat of", path);
    ::close(fd);
    return s;
  }
  const uint64_t size = std::min<uint64_t>(static_cast<uint64_t>(st.st_size), limit);
  out->resize(size);
  uint64_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd, out->data() + done, size - done, static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      Status s =
          n < 0 ? Errno("reading", path) : Internal("edit log: " + path + " shrank while read");
      ::close(fd);
      return s;
    }
    done += static_cast<uint64_t>(n);
  }
  ::close(fd);
  return Status::Ok();
}

// A new or deleted directory entry is only durable once the directory itself is synced; a
// record fdatasync'ed into a file whose name is lost would be lost with it.
Status FsyncDir(const std::string& dir) { return FsyncDirectory(dir); }

}  // namespace

StatusOr<FsyncPolicy::Mode> ParseFsyncMode(std::string_view text) {
  if (text == "always") return FsyncPolicy::Mode::kAlways;
  if (text == "group") return FsyncPolicy::Mode::kGroup;
  return Outside("fsync policy", std::string("\"") + std::string(text) + "\"", "{always, group}");
}

Status ValidateFsyncPolicy(const FsyncPolicy& policy) {
  if (policy.mode != FsyncPolicy::Mode::kAlways && policy.mode != FsyncPolicy::Mode::kGroup) {
    return Outside("FsyncPolicy.mode", std::to_string(static_cast<int>(policy.mode)),
                   "{kAlways, kGroup}");
  }
  if (policy.group_ms < kMinGroupMs || policy.group_ms > kMaxGroupMs) {
    return Outside(
        "FsyncPolicy.group_ms", std::to_string(policy.group_ms),
        std::string("[") + std::to_string(kMinGroupMs) + ", " + std::to_string(kMaxGroupMs) + "]");
  }
  return Status::Ok();
}

EditLog::EditLog(std::string dir, const EditLogOptions& options)
    : dir_(std::move(dir)), options_(options) {}

StatusOr<std::unique_ptr<EditLog>> EditLog::Open(const std::string& dir, FsyncPolicy policy,
                                                 RecoveryReport* report) {
  EditLogOptions options;
  options.fsync = policy;
  return Open(dir, options, report);
}

StatusOr<std::unique_ptr<EditLog>> EditLog::Open(const std::string& dir,
                                                 const EditLogOptions& options,
                                                 RecoveryReport* report) {
  SCULPT_RETURN_IF_ERROR(ValidateFsyncPolicy(options.fsync));
  if (options.segment_bytes < kMinSegmentBytes) {
    return Outside("EditLogOptions.segment_bytes", std::to_string(options.segment_bytes),
                   std::string("[") + std::to_string(kMinSegmentBytes) + ", 2^64)");
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Internal("edit log: creating directory " + dir + ": " + ec.message());
  RecoveryReport local;
  if (report == nullptr) report = &local;
  std::unique_ptr<EditLog> log(new EditLog(dir, options));
  SCULPT_RETURN_IF_ERROR(log->Scan(report));
  if (options.fsync.mode == FsyncPolicy::Mode::kGroup) {
    log->sync_thread_ = std::thread([raw = log.get()] { raw->SyncLoop(); });
  }
  return log;
}

Status EditLog::Scan(RecoveryReport* report) {
  std::vector<std::pair<uint64_t, std::string>> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir_, ec)) {
    uint64_t first = 0;
    if (entry.is_regular_file() && ParseSegmentFileName(entry.path().filename().string(), &first)) {
      files.emplace_back(first, entry.path().string());
    }
  }
  if (ec) return Internal("edit log: listing " + dir_ + ": " + ec.message());
  std::sort(files.begin(), files.end());

  uint64_t prev = 0;  // last seq seen; the first segment's base before any record
  std::string buf;
  // The acknowledged edits a damage in file i after seq `after` puts at stake: up to the base of
  // the next segment whose header reads, else everything after `after`.
  auto Stake = [&](size_t i, uint64_t after) -> std::string {
    for (size_t j = i + 1; j < files.size(); ++j) {
      std::string head;
      if (!ReadWholeFile(files[j].second, kSegmentHeaderBytes, &head).ok() ||
          head.size() < kSegmentHeaderBytes) {
        continue;
      }
      const auto* h = reinterpret_cast<const uint8_t*>(head.data());
      if (std::memcmp(h, kMagic, sizeof(kMagic)) != 0 || GetU32(h + 28) != HeaderCrc(h)) continue;
      const uint64_t base = GetU64(h + 16);
      return "seq " + std::to_string(after + 1) + ".." + std::to_string(base) + " (" +
             std::to_string(base > after ? base - after : 0) + " records; " +
             std::to_string(files.size() - j) + " later segment(s) follow)";
    }
    return "every record after seq " + std::to_string(after) + " in this file";
  };
  uint64_t removed_empty_first = 0;  // first seq of an empty last segment removed below
  for (size_t i = 0; i < files.size(); ++i) {
    const bool last = i + 1 == files.size();
    const std::string& path = files[i].second;
    SCULPT_RETURN_IF_ERROR(ReadWholeFile(path, UINT64_MAX, &buf));
    const auto* data = reinterpret_cast<const uint8_t*>(buf.data());
    const uint64_t size = buf.size();
    uint64_t nonzero_end = size;  // one past the file's last non-zero byte
    while (nonzero_end > 0 && data[nonzero_end - 1] == 0) --nonzero_end;

    if (size < kSegmentHeaderBytes) {
      if (!last) {
        return DataLoss(CorruptMessage(path, 0, "segment header",
                                       "header truncated to " + std::to_string(size) + " of " +
                                           std::to_string(kSegmentHeaderBytes) + " bytes"));
      }
      // A segment's header is written and synced before its first record, so a short header is
      // a crash while the segment was being created: nothing in it was ever acknowledged.
      spdlog::warn("edit log {}: header truncated to {} bytes by a crash; removing the file", path,
                   size);
      report->dropped_tail_bytes += size;
      report->dropped_tail_file = path;
      report->dropped_tail_reason = "segment header truncated";
      if (::unlink(path.c_str()) != 0) return Errno("removing", path);
      SCULPT_RETURN_IF_ERROR(FsyncDir(dir_));
      continue;
    }
    if (std::memcmp(data, kMagic, sizeof(kMagic)) != 0) {
      return DataLoss(
          CorruptMessage(path, 0, "segment header", "bad magic (not a Sculpt edit log segment)"));
    }
    const uint32_t version = GetU32(data + 8);
    if (version != kFormatVersion) {
      return FailedPrecondition("edit log " + path + " has format version " +
                                std::to_string(version) + "; this build reads version " +
                                std::to_string(kFormatVersion));
    }
    if (GetU32(data + 12) != kSegmentHeaderBytes || GetU32(data + 28) != HeaderCrc(data)) {
      return DataLoss(CorruptMessage(path, 0, "segment header", "header checksum mismatch"));
    }
    Segment seg;
    seg.path = path;
    seg.base_seq = GetU64(data + 16);
    seg.first_seq = files[i].first;
    if (i == 0) {
      prev = seg.base_seq;
      report->log_base_seq = seg.base_seq;
    } else if (seg.base_seq != prev) {
      return DataLoss(CorruptMessage(path, 0, "segment header",
                                     "segment begins after seq " + std::to_string(seg.base_seq) +
                                         " but the segments before it end at seq " +
                                         std::to_string(prev) + " (a segment is missing)"));
    }

    // What the file holds up to the end of the last complete group: a tear inside a group
    // cuts back to here, so recovery never sees part of a group.
    struct Committed {
      uint64_t offset = kSegmentHeaderBytes;
      uint64_t prev = 0;
      uint64_t records = 0;
      uint64_t first_seq = 0;
      uint64_t seg_last = 0;
    } committed{kSegmentHeaderBytes, prev, report->records, report->first_seq, 0};
    bool group_open = false;
    uint64_t offset = kSegmentHeaderBytes;
    // Cuts the file back to the last complete group (only the last segment can be torn).
    auto cut = [&](const std::string& reason) -> Status {
      const uint64_t dropped = size - committed.offset;
      spdlog::warn(
          "edit log {}: dropping {} bytes at offset {} after seq {}: {} (a write cut short by a "
          "crash; it was never acknowledged)",
          path, dropped, committed.offset, committed.prev, reason);
      report->dropped_tail_bytes += dropped;
      report->dropped_tail_file = path;
      report->dropped_tail_reason = reason;
      prev = committed.prev;
      report->records = committed.records;
      report->first_seq = committed.first_seq;
      seg.last_seq = committed.seg_last;
      offset = committed.offset;
      // Cut the torn bytes off before anything is appended: new records written after them
      // would turn a harmless torn tail into corruption in the middle of the log.
      const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd < 0) return Errno("opening", path);
      const bool ok = ::ftruncate(fd, static_cast<off_t>(offset)) == 0 && ::fsync(fd) == 0;
      Status s = ok ? Status::Ok() : Errno("truncating", path);
      ::close(fd);
      return s;
    };
    while (offset < size) {
      const uint64_t remaining = size - offset;
      std::string torn;  // the record runs past the end of the file
      std::string bad;   // the record is complete but wrong
      bool crc_mismatch = false;
      uint64_t seq = 0;
      uint32_t len = 0;
      bool continues = false;
      bool end_marker = false;
      if (remaining < kRecordHeaderBytes) {
        torn = "truncated record header (" + std::to_string(remaining) + " of " +
               std::to_string(kRecordHeaderBytes) + " bytes)";
      } else {
        const uint32_t field = GetU32(data + offset);
        continues = (field & kGroupContinues) != 0;
        // Exactly the flag: a marker has no payload (other bits there are a bad length).
        end_marker = field == kSegmentEnd;
        len = end_marker ? 0 : field & ~kGroupContinues;
        seq = GetU64(data + offset + 8);
        if (end_marker) {
          if (group_open || remaining != kRecordHeaderBytes ||
              GetU32(data + offset + 4) != RecordCrc(data + offset + 8, nullptr, 0) ||
              seq <= prev) {
            bad = "bad segment end marker";
          }
        } else if (len > kMaxRecordPayload) {
          bad = "bad length " + std::to_string(len) + " (max " + std::to_string(kMaxRecordPayload) +
                ")";
        } else if (remaining - kRecordHeaderBytes < len) {
          torn = "truncated record (" + std::to_string(remaining) + " of " +
                 std::to_string(kRecordHeaderBytes + len) + " bytes)";
        } else if (GetU32(data + offset + 4) !=
                   RecordCrc(data + offset + 8, data + offset + kRecordHeaderBytes, len)) {
          crc_mismatch = true;
          bad = "checksum mismatch";
        }
      }
      const std::string where = remaining >= kRecordHeaderBytes
                                    ? "record seq " + std::to_string(seq)
                                    : "record seq unknown";
      if (!torn.empty() || !bad.empty()) {
        // Only the end of the last segment can be torn: a crash mid-write (or a power loss
        // before the group fdatasync) leaves a short record, a record whose blocks never
        // reached the disk (checksum mismatch with nothing after it), or zero-filled blocks.
        // None of them was acknowledged. Anything else is damage to acknowledged edits.
        // Zero-filled blocks may start anywhere, also inside the record's header or payload:
        // the tail is torn when every byte from somewhere inside this record on is zero.
        const uint64_t record_end =
            offset + kRecordHeaderBytes + (crc_mismatch ? static_cast<uint64_t>(len) : 0);
        const bool zero_tail = last && nonzero_end < record_end;
        if (!last || !(!torn.empty() || zero_tail)) {
          // A whole record with other bytes than written is damage, not a crash (kill -9 leaves
          // the page cache intact; a power loss leaves zeros or a shorter file): stop.
          return DataLoss(CorruptMessage(path, offset, where, torn.empty() ? bad : torn,
                                         Stake(i, prev)));
        }
        const std::string reason =
            !torn.empty() ? torn
                          : "zero-filled tail from offset " + std::to_string(nonzero_end) +
                                " (blocks never written)";
        SCULPT_RETURN_IF_ERROR(cut(reason));
        group_open = false;
        break;
      }
      if (end_marker) {
        seg.next_first = seq;
        offset += kRecordHeaderBytes;
        committed.offset = offset;
        break;
      }
      if (seq <= prev) {
        return DataLoss(CorruptMessage(path, offset, where,
                                       "sequence " + std::to_string(seq) +
                                           " does not increase (previous " + std::to_string(prev) +
                                           ")"));
      }
      if (seg.last_seq == 0 && seq != seg.first_seq) {
        return DataLoss(CorruptMessage(path, offset, where,
                                       "first record is seq " + std::to_string(seq) +
                                           " but the file name says " +
                                           std::to_string(seg.first_seq)));
      }
      prev = seq;
      seg.last_seq = seq;
      if (report->first_seq == 0) report->first_seq = seq;
      ++report->records;
      offset += kRecordHeaderBytes + len;
      group_open = continues;
      if (!group_open) committed = {offset, prev, report->records, report->first_seq, seq};
    }
    if (group_open) {
      // Every record is whole but the group's last one is missing: a crash between two of
      // its records. A group never spans segments, so elsewhere this is damage.
      if (!last) {
        return DataLoss(CorruptMessage(path, committed.offset, "group after seq " +
                                           std::to_string(committed.prev),
                                       "the segment ends inside a group of records"));
      }
      SCULPT_RETURN_IF_ERROR(cut("incomplete group of records (seq " +
                                             std::to_string(committed.prev + 1) + ".." +
                                             std::to_string(prev) + " of a larger edit)"));
    }
    seg.bytes = offset;

    if (!segments_.empty() && segments_.back().next_first != 0 &&
        segments_.back().next_first != seg.first_seq) {
      return DataLoss(CorruptMessage(
          path, 0, "segment header",
          "the segment before it says the next segment begins at seq " +
              std::to_string(segments_.back().next_first) + " (a segment is missing)",
          Stake(i - 1, segments_.back().last_seq)));
    }
    if (seg.last_seq == 0) {
      // A segment without records: the first Append after it was cut off. Remove it so the
      // next Append creates its segment under its own seq; keep its base in `prev`.
      if (last && seg.next_first == 0) {
        if (::unlink(path.c_str()) != 0) return Errno("removing", path);
        SCULPT_RETURN_IF_ERROR(FsyncDir(dir_));
        removed_empty_first = seg.first_seq;
        continue;
      }
      seg.last_seq = seg.base_seq;
    }
    segments_.push_back(std::move(seg));
  }
  if (!segments_.empty() && segments_.back().next_first != 0 &&
      segments_.back().next_first != removed_empty_first) {
    // The newest segment ended in a marker naming a successor that is not there: the edits
    // written to it (all of them acknowledged, possibly) are gone.
    const Segment& closed = segments_.back();
    return DataLoss(
        "edit log " + closed.path + " was closed and continued in " +
        SegmentFileName(closed.next_first) + " from seq " + std::to_string(closed.next_first) +
        ", which is missing: every edit from seq " + std::to_string(closed.next_first) +
        " on is at stake; restore the file, or run `sculptd repair --data " +
        fs::path(dir_).parent_path().string() + " --dry-run` to see what starting without it " +
        "means");
  }

  if (segments_.empty()) report->log_base_seq = prev;
  report->segments = segments_.size();
  report->last_seq = report->records > 0 ? prev : 0;
  written_seq_.store(prev);
  durable_seq_.store(prev);
  notified_seq_ = prev;

  if (!segments_.empty() && segments_.back().next_first == 0) {
    // The last segment continues; a closed one (its successor was created empty and removed
    // above) stays closed and the next Append starts a segment.
    Segment& active = segments_.back();
    fd_ = ::open(active.path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (fd_ < 0) return Errno("opening", active.path);
    // Under kGroup a process crash leaves written records in the page cache only; sync them
    // now, since durable_seq() starts at the last record read.
    if (::fdatasync(fd_) != 0) return Errno("fdatasync of", active.path);
    active_path_ = active.path;
    active_bytes_ = active.bytes;
    active_last_seq_ = active.last_seq;
  }
  if (report->dropped_tail_bytes > 0) {
    report->warnings.push_back(
        "edit log: dropped a torn tail of " + std::to_string(report->dropped_tail_bytes) +
        " bytes from " + report->dropped_tail_file + " (" + report->dropped_tail_reason + ")");
  }
  spdlog::info("edit log {}: {} segments, {} records, seq {}..{} (complete after seq {})", dir_,
               report->segments, report->records, report->first_seq, report->last_seq,
               report->log_base_seq);
  return Status::Ok();
}

StatusOr<RepairReport> EditLog::Repair(const std::string& dir, bool dry_run) {
  RepairReport out;
  std::vector<std::pair<uint64_t, std::string>> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    uint64_t first = 0;
    if (entry.is_regular_file() && ParseSegmentFileName(entry.path().filename().string(), &first)) {
      files.emplace_back(first, entry.path().string());
    }
  }
  if (ec) return Internal("edit log: listing " + dir + ": " + ec.message());
  std::sort(files.begin(), files.end());

  // The first problem: cut file `cut_file` at `cut_offset` and set aside every later file.
  size_t cut_file = files.size();
  uint64_t cut_offset = 0;
  uint64_t cut_size = 0;
  uint64_t last_good = 0;  // last seq kept
  std::string why;
  uint64_t prev = 0;
  uint64_t pending_next = 0;  // the end marker of the previous segment
  bool last_has_marker = false;
  uint64_t last_marker_next = 0;
  std::string buf;
  for (size_t i = 0; i < files.size() && cut_file == files.size(); ++i) {
    const std::string& path = files[i].second;
    SCULPT_RETURN_IF_ERROR(ReadWholeFile(path, UINT64_MAX, &buf));
    const auto* data = reinterpret_cast<const uint8_t*>(buf.data());
    const uint64_t size = buf.size();
    auto stop = [&](uint64_t offset, std::string reason) {
      cut_file = i;
      cut_offset = offset;
      cut_size = size;
      last_good = prev;
      why = std::move(reason);
    };
    if (size < kSegmentHeaderBytes || std::memcmp(data, kMagic, sizeof(kMagic)) != 0 ||
        GetU32(data + 8) != kFormatVersion || GetU32(data + 12) != kSegmentHeaderBytes ||
        GetU32(data + 28) != HeaderCrc(data)) {
      stop(0, "bad or truncated segment header");
      break;
    }
    const uint64_t base = GetU64(data + 16);
    if (i > 0 && (base != prev || (pending_next != 0 && pending_next != files[i].first))) {
      stop(0, "segment begins after seq " + std::to_string(base) + " but the log before it ends " +
                  "at seq " + std::to_string(prev) + " (a segment is missing)");
      break;
    }
    if (i == 0) prev = base;
    uint64_t offset = kSegmentHeaderBytes;
    uint64_t committed = offset;
    uint64_t committed_prev = prev;
    bool group_open = false;
    pending_next = 0;
    while (offset < size) {
      const uint64_t remaining = size - offset;
      if (remaining < kRecordHeaderBytes) {
        stop(committed, "truncated record header");
        break;
      }
      const uint32_t field = GetU32(data + offset);
      const uint64_t seq = GetU64(data + offset + 8);
      if (field == kSegmentEnd && !group_open && remaining == kRecordHeaderBytes &&
          GetU32(data + offset + 4) == RecordCrc(data + offset + 8, nullptr, 0) && seq > prev) {
        pending_next = seq;
        offset += kRecordHeaderBytes;
        committed = offset;
        break;
      }
      const uint32_t len = field & ~kGroupContinues;
      if (len > kMaxRecordPayload || remaining - kRecordHeaderBytes < len ||
          GetU32(data + offset + 4) !=
              RecordCrc(data + offset + 8, data + offset + kRecordHeaderBytes, len) ||
          seq <= prev) {
        prev = committed_prev;
        stop(committed, "damaged record at offset " + std::to_string(offset));
        break;
      }
      prev = seq;
      offset += kRecordHeaderBytes + len;
      group_open = (field & kGroupContinues) != 0;
      if (!group_open) {
        committed = offset;
        committed_prev = prev;
      }
    }
    if (cut_file == files.size() && group_open) {
      prev = committed_prev;
      stop(committed, "incomplete group of records");
    }
    last_has_marker = pending_next != 0;
    last_marker_next = pending_next;
  }

  auto describe_rest = [&](size_t from) {
    // The seqs held by the files set aside, as far as their headers and records read.
    for (size_t j = from; j < files.size(); ++j) {
      std::string b;
      if (!ReadWholeFile(files[j].second, UINT64_MAX, &b).ok()) continue;
      const auto* d = reinterpret_cast<const uint8_t*>(b.data());
      uint64_t first = 0, last = 0, n = 0;
      for (uint64_t off = kSegmentHeaderBytes; off + kRecordHeaderBytes <= b.size();) {
        const uint32_t f = GetU32(d + off);
        const uint32_t len = f & ~kGroupContinues;
        if (f == kSegmentEnd || len > kMaxRecordPayload ||
            b.size() - off - kRecordHeaderBytes < len) {
          break;
        }
        const uint64_t sq = GetU64(d + off + 8);
        if (first == 0) first = sq;
        last = sq;
        ++n;
        off += kRecordHeaderBytes + len;
      }
      out.actions.push_back("set aside " + files[j].second + " as " + files[j].second +
                            ".discarded (" + std::to_string(n) + " readable records" +
                            (n > 0 ? ", seq " + std::to_string(first) + ".." +
                                         std::to_string(last)
                                   : std::string()) +
                            ")");
      if (n > 0) {
        out.discarded.push_back("seq " + std::to_string(first) + ".." + std::to_string(last) +
                                " (" + std::to_string(n) + " records in " + files[j].second + ")");
      }
    }
  };

  if (cut_file < files.size()) {
    out.clean = false;
    const std::string& path = files[cut_file].second;
    // The damaged file's seqs after the cut end where the next readable segment begins.
    std::string upto = "the end of the file";
    for (size_t j = cut_file + 1; j < files.size(); ++j) {
      std::string head;
      if (ReadWholeFile(files[j].second, kSegmentHeaderBytes, &head).ok() &&
          head.size() == kSegmentHeaderBytes &&
          GetU32(reinterpret_cast<const uint8_t*>(head.data()) + 28) ==
              HeaderCrc(reinterpret_cast<const uint8_t*>(head.data()))) {
        upto = "seq " + std::to_string(GetU64(reinterpret_cast<const uint8_t*>(head.data()) + 16));
        break;
      }
    }
    if (cut_offset < kSegmentHeaderBytes) {
      out.actions.push_back("set aside " + path + " as " + path + ".discarded (" + why + ")");
    } else {
      out.actions.push_back("cut " + path + " at offset " + std::to_string(cut_offset) + " (" +
                            why + "): " + std::to_string(cut_size - cut_offset) + " bytes");
    }
    {
      // The records after the cut, as far as their lengths read (a record whose checksum fails
      // is still counted when its length fits): what exactly the cut gives up.
      std::string b;
      uint64_t first = 0, last = 0, n = 0, damaged = 0,
               off = std::max(cut_offset, kSegmentHeaderBytes);
      bool unreadable = false;
      if (ReadWholeFile(path, UINT64_MAX, &b).ok()) {
        const auto* d = reinterpret_cast<const uint8_t*>(b.data());
        while (off < b.size()) {
          if (b.size() - off < kRecordHeaderBytes) {
            unreadable = true;
            break;
          }
          const uint32_t f = GetU32(d + off);
          if (f == kSegmentEnd) break;
          const uint32_t len = f & ~kGroupContinues;
          if (len > kMaxRecordPayload || b.size() - off - kRecordHeaderBytes < len) {
            unreadable = true;
            break;
          }
          const uint64_t sq = GetU64(d + off + 8);
          if (GetU32(d + off + 4) != RecordCrc(d + off + 8, d + off + kRecordHeaderBytes, len)) {
            ++damaged;
          }
          if (first == 0) first = sq;
          last = sq;
          ++n;
          off += kRecordHeaderBytes + len;
        }
      }
      std::string what = "every record after seq " + std::to_string(last_good) + " in " + path;
      if (n > 0) {
        what += ": seq " + std::to_string(first) + ".." + std::to_string(last) + " (" +
                std::to_string(n) + " records, " + std::to_string(damaged) + " damaged)";
      }
      if (unreadable || n == 0) {
        what += (n > 0 ? ", then " : ": ") + std::string("unreadable bytes from offset ") +
                std::to_string(off) + " (up to " + upto + ")";
      }
      out.discarded.push_back(what);
    }
    describe_rest(cut_file + 1);
    if (!dry_run) {
      if (cut_offset < kSegmentHeaderBytes) {
        if (std::rename(path.c_str(), (path + ".discarded").c_str()) != 0) {
          return Errno("renaming", path);
        }
      } else {
        const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
        if (fd < 0) return Errno("opening", path);
        const bool ok = ::ftruncate(fd, static_cast<off_t>(cut_offset)) == 0 && ::fsync(fd) == 0;
        ::close(fd);
        if (!ok) return Errno("truncating", path);
      }
      if (cut_offset < kSegmentHeaderBytes && cut_file > 0 && last_has_marker) {
        // The segment before names the one set aside as its successor; drop that marker.
        const std::string& before = files[cut_file - 1].second;
        const uint64_t size = fs::file_size(before, ec);
        if (ec) return Internal("edit log: size of " + before + ": " + ec.message());
        const int fd = ::open(before.c_str(), O_WRONLY | O_CLOEXEC);
        if (fd < 0) return Errno("opening", before);
        const bool ok = ::ftruncate(fd, static_cast<off_t>(size - kRecordHeaderBytes)) == 0 &&
                        ::fsync(fd) == 0;
        ::close(fd);
        if (!ok) return Errno("truncating", before);
      }
      for (size_t j = cut_file + 1; j < files.size(); ++j) {
        if (std::rename(files[j].second.c_str(), (files[j].second + ".discarded").c_str()) != 0) {
          return Errno("renaming", files[j].second);
        }
      }
      SCULPT_RETURN_IF_ERROR(FsyncDir(dir));
    }
    return out;
  }
  if (last_has_marker) {
    out.clean = false;
    const std::string& path = files.back().second;
    out.actions.push_back("remove the end marker of " + path +
                          " (the last 16 bytes), which names " + SegmentFileName(last_marker_next) +
                          ", a newer segment that is missing");
    out.discarded.push_back("every record from seq " + std::to_string(last_marker_next) +
                            " on that was in the missing " + SegmentFileName(last_marker_next) +
                            " (how many is unknown)");
    if (!dry_run) {
      const uint64_t size = fs::file_size(path, ec);
      if (ec) return Internal("edit log: size of " + path + ": " + ec.message());
      const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd < 0) return Errno("opening", path);
      const bool ok =
          ::ftruncate(fd, static_cast<off_t>(size - kRecordHeaderBytes)) == 0 && ::fsync(fd) == 0;
      ::close(fd);
      if (!ok) return Errno("truncating", path);
    }
  }
  return out;
}

EditLog::~EditLog() {
  {
    std::lock_guard<std::mutex> lock(callback_mu_);
    callback_ = nullptr;  // the owner may be half torn down; nobody is acknowledged any more
  }
  if (sync_thread_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(wake_mu_);
      stop_ = true;
    }
    wake_cv_.notify_all();
    sync_thread_.join();
  }
  Status s = Sync();
  if (!s.ok()) spdlog::error("edit log {}: final sync failed: {}", dir_, s.ToString());
  std::lock_guard<std::mutex> lock(file_mu_);
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status EditLog::Poison(Status status) {
  // Caller holds file_mu_.
  if (poisoned_.ok()) {
    poisoned_ = Internal(status.message() +
                         "; the edit log is unusable until restart (unsynced pages may be gone)");
    is_poisoned_.store(true);
    spdlog::error("edit log {}: {}", dir_, poisoned_.message());
  }
  return poisoned_;
}

StatusOr<uint64_t> EditLog::SyncLocked() {
  if (is_poisoned_.load()) return poisoned_;
  // Read before the sync: every write() that finished before this load is covered by it.
  const uint64_t target = written_seq_.load();
  if (target <= durable_seq_.load() || fd_ < 0) return durable_seq_.load();
  // fdatasync, not fsync: it flushes the data and the file size (all a reader needs) but not
  // the timestamps, which saves a journal commit on most appends. A failure cannot be retried:
  // Linux may mark the lost pages clean, so a second fdatasync would falsely succeed.
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = ::fdatasync(fd_);
  sync_seconds_.Observe(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  if (rc != 0) return Poison(Errno("fdatasync of", segments_.back().path));
  durable_seq_.store(target);
  return target;
}

Status EditLog::Sync() {
  StatusOr<uint64_t> durable = [&] {
    std::lock_guard<std::mutex> lock(file_mu_);
    return SyncLocked();
  }();
  if (!durable.ok()) return durable.status();
  NotifyDurable(*durable);
  return Status::Ok();
}

void EditLog::NotifyDurable(uint64_t seq) {
  std::lock_guard<std::mutex> lock(callback_mu_);
  // Two syncing threads may finish out of order; report only progress.
  if (seq <= notified_seq_) return;
  notified_seq_ = seq;
  if (callback_) callback_(seq);
}

void EditLog::OnDurable(DurableCallback callback) {
  std::lock_guard<std::mutex> lock(callback_mu_);
  callback_ = std::move(callback);
}

Status EditLog::StartSegment(uint64_t first_seq) {
  StatusOr<uint64_t> durable = durable_seq_.load();
  {
    std::lock_guard<std::mutex> lock(file_mu_);
    if (fd_ >= 0) {
      // The old segment reaches the disk before the new one gets a record: otherwise a power
      // loss could keep a later segment while an earlier one loses its tail, a hole in the log.
      durable = SyncLocked();
      if (!durable.ok()) return durable.status();
      segments_.back().bytes = active_bytes_;
      segments_.back().last_seq = active_last_seq_;
    }
    const int old_fd = fd_;
    const std::string path = (fs::path(dir_) / SegmentFileName(first_seq)).string();
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) return Errno("creating", path);
    std::array<uint8_t, kSegmentHeaderBytes> header{};
    std::memcpy(header.data(), kMagic, sizeof(kMagic));
    PutU32(header.data() + 8, kFormatVersion);
    PutU32(header.data() + 12, static_cast<uint32_t>(kSegmentHeaderBytes));
    const uint64_t base = written_seq_.load();
    PutU64(header.data() + 16, base);
    PutU32(header.data() + 24, 0);
    PutU32(header.data() + 28, HeaderCrc(header.data()));
    iovec iov{header.data(), header.size()};
    Status s = WriteFully(fd, &iov, 1, path, options_.writev_for_testing);
    // The header and the directory entry are synced once here, so a record's own fdatasync
    // is enough to make it reachable after a power loss.
    if (s.ok() && ::fdatasync(fd) != 0) s = Errno("fdatasync of", path);
    if (s.ok()) s = FsyncDir(dir_);
    if (!s.ok()) {
      ::close(fd);
      ::unlink(path.c_str());
      return s;
    }
    if (old_fd >= 0) {
      // Only now that the new segment is durable does the old one say it has a successor, so
      // a last segment ending in a marker always means a lost newer one.
      std::array<uint8_t, kRecordHeaderBytes> marker;
      PutU32(marker.data(), kSegmentEnd);
      PutU64(marker.data() + 8, first_seq);
      PutU32(marker.data() + 4, RecordCrc(marker.data() + 8, nullptr, 0));
      iovec miov{marker.data(), marker.size()};
      Status m = WriteFully(old_fd, &miov, 1, segments_.back().path, options_.writev_for_testing);
      if (!m.ok() && ::ftruncate(old_fd, static_cast<off_t>(segments_.back().bytes)) == 0) {
        // Without its marker the old segment is as after a crash right here: still valid.
        spdlog::warn("edit log {}: no end marker written: {}", segments_.back().path,
                     m.ToString());
      } else if (!m.ok() || ::fdatasync(old_fd) != 0) {
        const Status why = m.ok() ? Errno("fdatasync of", segments_.back().path) : m;
        ::close(old_fd);
        fd_ = -1;
        ::close(fd);
        return Poison(why);
      } else {
        segments_.back().bytes += kRecordHeaderBytes;
        segments_.back().next_first = first_seq;
      }
      ::close(old_fd);
      fd_ = -1;
    }
    fd_ = fd;
    active_path_ = path;
    Segment seg;
    seg.path = path;
    seg.base_seq = base;
    seg.first_seq = first_seq;
    seg.bytes = kSegmentHeaderBytes;
    segments_.push_back(std::move(seg));
    active_bytes_ = kSegmentHeaderBytes;
    active_last_seq_ = 0;
    roll_requested_ = false;
  }
  NotifyDurable(*durable);
  return Status::Ok();
}

Status EditLog::Append(uint64_t seq, std::string_view payload) {
  return AppendRecords(seq, &payload, 1);
}

Status EditLog::AppendGroup(uint64_t first_seq, const std::vector<std::string>& payloads) {
  if (payloads.empty()) {
    return InvalidArgument("edit log group at seq=" + std::to_string(first_seq) +
                           " holds no records (allowed [1, ...])");
  }
  std::vector<std::string_view> views(payloads.begin(), payloads.end());
  return AppendRecords(first_seq, views.data(), views.size());
}

Status EditLog::AppendRecords(uint64_t first_seq, const std::string_view* payloads,
                              size_t count) {
  if (is_poisoned_.load()) {
    std::lock_guard<std::mutex> lock(file_mu_);
    return poisoned_;
  }
  const uint64_t last = written_seq_.load();
  if (first_seq <= last) {
    return FailedPrecondition("edit log append seq=" + std::to_string(first_seq) +
                              " must exceed the last seq " + std::to_string(last));
  }
  uint64_t group_bytes = 0;
  for (size_t i = 0; i < count; ++i) {
    if (payloads[i].size() > kMaxRecordPayload) {
      return Outside("edit log payload size", std::to_string(payloads[i].size()),
                     std::string("[0, ") + std::to_string(kMaxRecordPayload) + "] bytes");
    }
    group_bytes += kRecordHeaderBytes + payloads[i].size();
  }
  // A group stays in one segment, so a torn group is always at the end of the last one.
  if (fd_ < 0 || (active_last_seq_ != 0 &&
                  (roll_requested_ || active_bytes_ + group_bytes > options_.segment_bytes))) {
    SCULPT_RETURN_IF_ERROR(StartSegment(first_seq));
  }

  std::vector<std::array<uint8_t, kRecordHeaderBytes>> headers(count);
  std::vector<iovec> iov;
  iov.reserve(2 * count);
  for (size_t i = 0; i < count; ++i) {
    uint8_t* h = headers[i].data();
    const uint32_t flags = i + 1 < count ? kGroupContinues : 0;
    PutU32(h, static_cast<uint32_t>(payloads[i].size()) | flags);
    PutU64(h + 8, first_seq + i);
    PutU32(h + 4, RecordCrc(h + 8, payloads[i].data(), payloads[i].size()));
    iov.push_back({h, kRecordHeaderBytes});
    iov.push_back({const_cast<char*>(payloads[i].data()), payloads[i].size()});
  }
  // Headers and payloads leave in one writev (several past IOV_MAX): no copy of the payloads,
  // and a crash tears at most this group, which the scan at Open cuts off whole.
  Status s = WriteFully(fd_, iov.data(), static_cast<int>(iov.size()), active_path_,
                        options_.writev_for_testing);
  if (!s.ok()) {
    // Remove a partial group (e.g. ENOSPC mid-write) so the next record does not follow
    // garbage; if even that fails the file can no longer be trusted.
    if (::ftruncate(fd_, static_cast<off_t>(active_bytes_)) != 0) {
      std::lock_guard<std::mutex> lock(file_mu_);
      return Poison(s);
    }
    return s;
  }
  const uint64_t last_seq = first_seq + count - 1;
  active_bytes_ += group_bytes;
  active_last_seq_ = last_seq;
  written_seq_.store(last_seq);

  if (options_.fsync.mode == FsyncPolicy::Mode::kAlways) return Sync();
  if (!wake_pending_.exchange(true)) {
    std::lock_guard<std::mutex> lock(wake_mu_);
    wake_cv_.notify_one();
  }
  return Status::Ok();
}

void EditLog::SyncLoop() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::milliseconds(options_.fsync.group_ms);
  Clock::time_point next_allowed = Clock::now();
  std::unique_lock<std::mutex> lock(wake_mu_);
  while (true) {
    wake_cv_.wait(lock, [&] { return stop_ || wake_pending_.load(); });
    if (stop_) return;
    // Group commit: at most one fdatasync per period, shared by every record written until it
    // starts. After a quiet period the first record is synced at once (low latency when idle).
    wake_cv_.wait_until(lock, next_allowed, [&] { return stop_; });
    if (stop_) return;
    // Cleared before Sync reads written_seq_: a record written after that read sets it again.
    wake_pending_.store(false);
    lock.unlock();
    next_allowed = Clock::now() + period;
    Status s = Sync();
    lock.lock();
    if (!s.ok()) return;  // poisoned; Append and Sync report it from now on
  }
}

void EditLog::Roll() {
  if (active_last_seq_ != 0) roll_requested_ = true;
}

Status EditLog::StartAfter(uint64_t seq) {
  std::lock_guard<std::mutex> lock(file_mu_);
  if (!segments_.empty()) {
    return FailedPrecondition("EditLog::StartAfter(" + std::to_string(seq) +
                              ") on a log that holds records (last seq " +
                              std::to_string(written_seq_.load()) + ")");
  }
  if (seq < written_seq_.load()) {
    return FailedPrecondition("EditLog::StartAfter(" + std::to_string(seq) +
                              ") below the log's base seq " + std::to_string(written_seq_.load()));
  }
  written_seq_.store(seq);
  durable_seq_.store(seq);
  return Status::Ok();
}

Status EditLog::DropSegmentsBefore(uint64_t seq) {
  std::lock_guard<std::mutex> lock(file_mu_);
  // Closed segments have an exact last_seq; the last segment is never dropped (it may be the
  // one being appended to, and its base keeps the chain's start).
  size_t n = 0;
  while (n + 1 < segments_.size() && segments_[n].last_seq <= seq) ++n;
  size_t removed = 0;
  Status status;
  for (; removed < n; ++removed) {
    if (::unlink(segments_[removed].path.c_str()) != 0 && errno != ENOENT) {
      status = Errno("removing", segments_[removed].path);
      break;
    }
  }
  // No directory fsync: a removal undone by a power loss brings back a segment that the chain
  // still accepts and a later drop removes again.
  segments_.erase(segments_.begin(), segments_.begin() + static_cast<std::ptrdiff_t>(removed));
  if (removed > 0) {
    spdlog::info("edit log {}: dropped {} segments covered by the snapshot at seq {}", dir_,
                 removed, seq);
  }
  return status;
}

uint64_t EditLog::base_seq() const {
  std::lock_guard<std::mutex> lock(file_mu_);
  return segments_.empty() ? written_seq_.load() : segments_.front().base_seq;
}

size_t EditLog::segment_count() const {
  std::lock_guard<std::mutex> lock(file_mu_);
  return segments_.size();
}

Status EditLog::ForEachFrom(uint64_t after_seq,
                            const std::function<Status(const LogRecord& record)>& visit) const {
  std::vector<Segment> segments;
  {
    std::lock_guard<std::mutex> lock(file_mu_);
    segments = segments_;
  }
  if (!segments.empty() && fd_ >= 0) {
    segments.back().bytes = active_bytes_;
    segments.back().last_seq = active_last_seq_;
  }
  std::string buf;
  LogRecord record;
  for (const Segment& seg : segments) {
    if (seg.last_seq <= after_seq || seg.last_seq == seg.base_seq) continue;
    SCULPT_RETURN_IF_ERROR(ReadWholeFile(seg.path, seg.bytes, &buf));
    if (buf.size() < seg.bytes) {
      return DataLoss(CorruptMessage(
          seg.path, buf.size(), "replay",
          "file is shorter than the " + std::to_string(seg.bytes) + " bytes verified at start-up"));
    }
    const auto* data = reinterpret_cast<const uint8_t*>(buf.data());
    uint64_t offset = kSegmentHeaderBytes;
    while (offset < seg.bytes) {
      // Verified at Open; checked again because the file is read again.
      const uint64_t remaining = seg.bytes - offset;
      const uint32_t field = remaining >= kRecordHeaderBytes ? GetU32(data + offset) : 0;
      const uint32_t len = field == kSegmentEnd ? 0 : field & ~kGroupContinues;
      const uint64_t seq = remaining >= kRecordHeaderBytes ? GetU64(data + offset + 8) : 0;
      if (remaining < kRecordHeaderBytes || len > remaining - kRecordHeaderBytes ||
          GetU32(data + offset + 4) !=
              RecordCrc(data + offset + 8, data + offset + kRecordHeaderBytes, len)) {
        return DataLoss(CorruptMessage(seg.path, offset, "record seq " + std::to_string(seq),
                                       "changed on disk after start-up"));
      }
      if (field == kSegmentEnd) break;  // the segment's end marker
      if (seq > after_seq) {
        record.seq = seq;
        record.payload.assign(buf, offset + kRecordHeaderBytes, len);
        SCULPT_RETURN_IF_ERROR(visit(record));
      }
      offset += kRecordHeaderBytes + len;
    }
  }
  return Status::Ok();
}

StatusOr<std::vector<LogRecord>> EditLog::ReadFrom(uint64_t after_seq) const {
  std::vector<LogRecord> records;
  Status s = ForEachFrom(after_seq, [&](const LogRecord& r) {
    records.push_back(r);
    return Status::Ok();
  });
  if (!s.ok()) return s;
  return records;
}

}  // namespace sculpt::server::store
