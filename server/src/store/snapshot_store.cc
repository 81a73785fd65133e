/// @brief SnapshotStore: durable `.vdb` snapshot files, the coalescing background writer and
/// newest-K retention.
#include "store/snapshot_store.h"

#include "store/durable_file.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

namespace sculpt::server::store {
namespace {

namespace fs = std::filesystem;

constexpr size_t kSeqDigits = 20;
constexpr size_t kMaxObjectName = 64;
constexpr int kMaxKeep = 1000;
constexpr const char* kPartialSuffix = ".writing";

// The container around the OpenVDB bytes (all integers little-endian):
//   "SCLPSNAP" | u32 version (1) | u32 header size (40) | u64 seq | u64 payload bytes |
//   u32 CRC32C(payload) | u32 CRC32C(the 36 header bytes before it) | payload (.vdb bytes)
// Nothing parses the payload before both checksums match, so a damaged file is reported and
// skipped instead of reaching OpenVDB's reader (which trusts sizes it reads).
constexpr char kSnapMagic[8] = {'S', 'C', 'L', 'P', 'S', 'N', 'A', 'P'};
constexpr uint32_t kSnapVersion = 1;
constexpr uint64_t kSnapHeaderBytes = 40;
// OpenVDB's file magic (int64 0x56444220): snapshots written before the container.
constexpr unsigned char kVdbMagic[8] = {0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0};

uint32_t Crc(const void* data, size_t size) { return Crc32c(data, size); }
void PutU32(char* p, uint32_t v) { PutLittleEndian(p, v); }
void PutU64(char* p, uint64_t v) { PutLittleEndian(p, v); }
uint32_t GetU32(const char* p) { return GetLittleEndian<uint32_t>(p); }
uint64_t GetU64(const char* p) { return GetLittleEndian<uint64_t>(p); }

std::string SnapshotFileName(uint64_t seq, const std::string& object) {
  char seq_text[32];
  std::snprintf(seq_text, sizeof(seq_text), "%020" PRIu64, seq);
  return "snap-" + std::string(seq_text) + "-" + object + ".vdb";
}

// "snap-" + 20 digits + "-" + object + ".vdb".
bool ParseSnapshotFileName(const std::string& name, uint64_t* seq, std::string* object) {
  constexpr size_t kPrefix = 5;
  if (name.size() < kPrefix + kSeqDigits + 1 + 1 + 4 || name.compare(0, kPrefix, "snap-") != 0 ||
      name[kPrefix + kSeqDigits] != '-' || name.compare(name.size() - 4, 4, ".vdb") != 0) {
    return false;
  }
  uint64_t v = 0;
  for (size_t i = kPrefix; i < kPrefix + kSeqDigits; ++i) {
    if (name[i] < '0' || name[i] > '9') return false;
    const uint64_t digit = static_cast<uint64_t>(name[i] - '0');
    if (v > (UINT64_MAX - digit) / 10) return false;
    v = v * 10 + digit;
  }
  std::string obj =
      name.substr(kPrefix + kSeqDigits + 1, name.size() - 4 - kPrefix - kSeqDigits - 1);
  if (!ValidateObjectName(obj).ok()) return false;
  *seq = v;
  *object = std::move(obj);
  return true;
}

Status Errno(const std::string& what, const std::string& path) {
  return Internal("snapshot store: " + what + " " + path + ": " + std::strerror(errno));
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

Status WriteAll(int fd, const char* data, size_t size, const std::string& path) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Errno("writing", path);
    }
    data += n;
    size -= static_cast<size_t>(n);
  }
  return Status::Ok();
}

// Reads up to `size` bytes at `offset`; DataLoss when the file is shorter.
Status ReadAt(int fd, uint64_t offset, size_t size, char* out, const std::string& path) {
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd, out + done, size - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return Errno("reading", path);
    if (n == 0) return DataLoss("snapshot " + path + " shrank while read");
    done += static_cast<size_t>(n);
  }
  return Status::Ok();
}

// Writes the container to `path` and fsyncs it.
Status WriteContainer(const std::string& path, uint64_t seq, const std::string& vdb) {
  char header[kSnapHeaderBytes];
  std::memcpy(header, kSnapMagic, sizeof(kSnapMagic));
  PutU32(header + 8, kSnapVersion);
  PutU32(header + 12, static_cast<uint32_t>(kSnapHeaderBytes));
  PutU64(header + 16, seq);
  PutU64(header + 24, vdb.size());
  PutU32(header + 32, Crc(vdb.data(), vdb.size()));
  PutU32(header + 36, Crc(header, 36));
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Errno("creating", path);
  Status s = WriteAll(fd, header, sizeof(header), path);
  if (s.ok()) s = WriteAll(fd, vdb.data(), vdb.size(), path);
  if (s.ok() && ::fsync(fd) != 0) s = Errno("fsync of", path);
  if (::close(fd) != 0 && s.ok()) s = Errno("closing", path);
  return s;
}

}  // namespace

StatusOr<levelset::Sculpture> LoadSnapshotFile(const std::string& path, uint64_t expected_seq,
                                               uint64_t max_bytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Errno("opening", path);
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st;
  if (::fstat(fd, &st) != 0) return Errno("stat of", path);
  const uint64_t size = static_cast<uint64_t>(st.st_size);
  char header[kSnapHeaderBytes] = {};
  if (size < sizeof(kSnapMagic)) {
    return DataLoss("snapshot " + path + " is " + std::to_string(size) + " bytes, shorter than " +
                    "its header");
  }
  SCULPT_RETURN_IF_ERROR(ReadAt(fd, 0, sizeof(kSnapMagic), header, path));
  if (std::memcmp(header, kVdbMagic, sizeof(kVdbMagic)) == 0) {
    // Written by a sculptd without checksums; OpenVDB's own checks are all it gets.
    spdlog::warn("snapshot {} has no checksum (an older format); loading it unverified", path);
    return levelset::Sculpture::LoadVdb(path);
  }
  if (std::memcmp(header, kSnapMagic, sizeof(kSnapMagic)) != 0) {
    return DataLoss("snapshot " + path + ": bad magic (not a Sculpt snapshot)");
  }
  if (size < kSnapHeaderBytes) {
    return DataLoss("snapshot " + path + " is " + std::to_string(size) + " bytes, shorter than " +
                    "its " + std::to_string(kSnapHeaderBytes) + "-byte header");
  }
  SCULPT_RETURN_IF_ERROR(ReadAt(fd, 0, kSnapHeaderBytes, header, path));
  if (GetU32(header + 36) != Crc(header, 36)) {
    return DataLoss("snapshot " + path + ": header checksum mismatch");
  }
  if (GetU32(header + 8) != kSnapVersion || GetU32(header + 12) != kSnapHeaderBytes) {
    return FailedPrecondition("snapshot " + path + " has format version " +
                              std::to_string(GetU32(header + 8)) + "; this build reads version " +
                              std::to_string(kSnapVersion));
  }
  const uint64_t seq = GetU64(header + 16);
  if (seq != expected_seq) {
    return DataLoss("snapshot " + path + " holds seq " + std::to_string(seq) +
                    " but its name says " + std::to_string(expected_seq));
  }
  // The payload size is checked against the file and a cap before anything is allocated.
  const uint64_t payload = GetU64(header + 24);
  if (payload != size - kSnapHeaderBytes || payload > max_bytes) {
    return DataLoss("snapshot " + path + ": payload size=" + std::to_string(payload) +
                    " but the file holds " + std::to_string(size - kSnapHeaderBytes) +
                    " bytes after the header (at most " + std::to_string(max_bytes) + ")");
  }
  std::string vdb(payload, '\0');
  SCULPT_RETURN_IF_ERROR(ReadAt(fd, kSnapHeaderBytes, vdb.size(), vdb.data(), path));
  if (Crc(vdb.data(), vdb.size()) != GetU32(header + 32)) {
    return DataLoss("snapshot " + path + ": checksum mismatch in its " + std::to_string(payload) +
                    " bytes of grid data");
  }
  auto sculpture = levelset::Sculpture::DeserializeVdb(vdb);
  if (!sculpture.ok()) {
    return DataLoss("snapshot " + path + " (checksum good) does not load: " +
                    sculpture.status().ToString());
  }
  return sculpture;
}

Status ValidateObjectName(const std::string& object) {
  if (object.empty() || object.size() > kMaxObjectName) {
    return Outside("snapshot object name length", std::to_string(object.size()),
                   std::string("[1, ") + std::to_string(kMaxObjectName) + "]");
  }
  if (object[0] == '.') {
    return InvalidArgument("snapshot object name=\"" + object + "\" must not start with '.'");
  }
  for (char c : object) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-' || c == '.';
    if (!ok) {
      return Outside("snapshot object name", std::string("\"") + object + "\" has a character",
                     "[A-Za-z0-9_.-]");
    }
  }
  return Status::Ok();
}

SnapshotStore::SnapshotStore(std::string dir, SnapshotStoreOptions options)
    : dir_(std::move(dir)), options_(options) {}

StatusOr<std::unique_ptr<SnapshotStore>> SnapshotStore::Open(const std::string& dir,
                                                             SnapshotStoreOptions options) {
  if (options.keep < 1 || options.keep > kMaxKeep) {
    return Outside("SnapshotStoreOptions.keep", std::to_string(options.keep),
                   std::string("[1, ") + std::to_string(kMaxKeep) + "]");
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Internal("snapshot store: creating directory " + dir + ": " + ec.message());
  // A crash mid-write leaves a partial file under a name LoadNewest never reads; remove it.
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("snap-", 0) == 0 &&
        (EndsWith(name, kPartialSuffix) || EndsWith(name, std::string(kPartialSuffix) + ".tmp") ||
         EndsWith(name, ".vdb.tmp"))) {
      spdlog::warn("snapshot store: removing {} left by an interrupted write",
                   entry.path().string());
      fs::remove(entry.path(), ec);
      if (ec) {
        return Internal("snapshot store: removing " + entry.path().string() + ": " + ec.message());
      }
    }
  }
  if (ec) return Internal("snapshot store: listing " + dir + ": " + ec.message());
  std::unique_ptr<SnapshotStore> store(new SnapshotStore(dir, options));
  store->writer_ = std::thread([raw = store.get()] { raw->WriterLoop(); });
  return store;
}

SnapshotStore::~SnapshotStore() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (writer_.joinable()) writer_.join();
}

Status SnapshotStore::Write(uint64_t seq, const std::string& object,
                            const levelset::Sculpture& sculpture) {
  SCULPT_RETURN_IF_ERROR(ValidateObjectName(object));
  const std::string path = (fs::path(dir_) / SnapshotFileName(seq, object)).string();
  const std::string partial = path + kPartialSuffix;
  std::lock_guard<std::mutex> io(io_mu_);
  // The file is synced under a name nobody reads, and only then renamed to its final name,
  // which therefore never points at unsynced data.
  SCULPT_ASSIGN_OR_RETURN(std::string vdb, sculpture.SerializeVdb());
  Status s = WriteContainer(partial, seq, vdb);
  if (s.ok() && std::rename(partial.c_str(), path.c_str()) != 0) s = Errno("renaming", partial);
  if (!s.ok()) {
    ::unlink(partial.c_str());
    return s;
  }
  // The rename is durable only once the directory is synced; the log is trimmed after this.
  SCULPT_RETURN_IF_ERROR(FsyncPath(dir_, true));
  return DeleteOld(object);
}

Status SnapshotStore::DeleteOld(const std::string& object) {
  SCULPT_ASSIGN_OR_RETURN(std::vector<SnapshotFile> files, List());
  std::vector<const SnapshotFile*> mine;
  for (const auto& f : files) {
    if (f.object == object) mine.push_back(&f);
  }
  if (mine.size() <= static_cast<size_t>(options_.keep)) return Status::Ok();
  // List() sorts by seq ascending within an object: the oldest come first.
  for (size_t i = 0; i + static_cast<size_t>(options_.keep) < mine.size(); ++i) {
    if (::unlink(mine[i]->path.c_str()) != 0 && errno != ENOENT) {
      return Errno("removing old snapshot", mine[i]->path);
    }
  }
  return Status::Ok();
}

void SnapshotStore::WriteAsync(uint64_t seq, std::string object, levelset::Sculpture clone,
                               std::function<void(Status)> done) {
  Status bad_name = ValidateObjectName(object);
  if (!bad_name.ok()) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (first_error_.ok()) first_error_ = bad_name;
    }
    if (done) done(bad_name);
    return;
  }
  Job job;
  job.seq = seq;
  job.object = object;
  job.sculpture = std::make_unique<levelset::Sculpture>(std::move(clone));
  job.done = std::move(done);
  Job dropped;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = queued_.find(object);
    if (it == queued_.end()) {
      order_.push_back(object);
      queued_.emplace(object, std::move(job));
    } else {
      // Coalesce: the newer snapshot makes the queued one pointless; keep its place in line.
      ++superseded_;
      if (job.seq >= it->second.seq) {
        dropped = std::exchange(it->second, std::move(job));
      } else {
        dropped = std::move(job);
      }
    }
  }
  cv_.notify_all();
  if (dropped.done) {
    const uint64_t kept = std::max(seq, dropped.seq);
    dropped.done(
        Status(Status::Code::kUnavailable, "snapshot of " + object + " at seq " +
                                               std::to_string(dropped.seq) + " superseded by seq " +
                                               std::to_string(kept) + " before it was written"));
  }
}

void SnapshotStore::WriterLoop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    cv_.wait(lock, [&] { return stop_ || !order_.empty(); });
    if (order_.empty()) return;  // stop_ and drained: queued snapshots are written first
    const std::string object = std::move(order_.front());
    order_.pop_front();
    auto it = queued_.find(object);
    Job job = std::move(it->second);
    queued_.erase(it);
    writing_ = true;
    lock.unlock();

    Status s = Write(job.seq, job.object, *job.sculpture);
    if (!s.ok()) {
      spdlog::error("snapshot of {} at seq {} failed: {}", job.object, job.seq, s.ToString());
    }
    job.sculpture.reset();  // free the clone before waiting for the next one
    if (job.done) job.done(s);

    lock.lock();
    writing_ = false;
    ++async_writes_;
    if (!s.ok() && first_error_.ok()) first_error_ = s;
    cv_.notify_all();
  }
}

Status SnapshotStore::WaitIdle() {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [&] { return order_.empty() && !writing_; });
  return std::exchange(first_error_, Status::Ok());
}

uint64_t SnapshotStore::async_writes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return async_writes_;
}

uint64_t SnapshotStore::superseded() const {
  std::lock_guard<std::mutex> lock(mu_);
  return superseded_;
}

StatusOr<std::vector<SnapshotFile>> SnapshotStore::List() const {
  std::vector<SnapshotFile> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir_, ec)) {
    SnapshotFile f;
    if (entry.is_regular_file() &&
        ParseSnapshotFileName(entry.path().filename().string(), &f.seq, &f.object)) {
      f.path = entry.path().string();
      files.push_back(std::move(f));
    }
  }
  if (ec) return Internal("snapshot store: listing " + dir_ + ": " + ec.message());
  std::sort(files.begin(), files.end(), [](const SnapshotFile& a, const SnapshotFile& b) {
    return a.object != b.object ? a.object < b.object : a.seq < b.seq;
  });
  return files;
}

StatusOr<std::vector<Snapshot>> SnapshotStore::LoadNewest(std::vector<std::string>* skipped) const {
  SCULPT_ASSIGN_OR_RETURN(std::vector<SnapshotFile> files, List());
  std::vector<Snapshot> out;
  size_t end = files.size();
  while (end > 0) {
    // files[begin, end) are one object's snapshots, oldest first.
    size_t begin = end - 1;
    while (begin > 0 && files[begin - 1].object == files[end - 1].object) --begin;
    std::string reasons;
    bool loaded = false;
    for (size_t i = end; i-- > begin;) {
      StatusOr<levelset::Sculpture> s =
          LoadSnapshotFile(files[i].path, files[i].seq, options_.max_bytes);
      if (s.ok()) {
        out.push_back(Snapshot{files[i].object, files[i].seq, std::move(s).value()});
        loaded = true;
        break;
      }
      const std::string why = files[i].path + ": " + s.status().ToString();
      spdlog::warn("snapshot {} does not load; trying an older one: {}", files[i].path,
                   s.status().ToString());
      if (skipped != nullptr) skipped->push_back(why);
      reasons += (reasons.empty() ? "" : "; ") + why;
    }
    if (!loaded) {
      return DataLoss("no snapshot of object " + files[end - 1].object + " in " + dir_ +
                      " loads (" + reasons + "); move them away to rebuild the object from the " +
                      "scene and the edit log");
    }
    end = begin;
  }
  std::reverse(out.begin(), out.end());
  return out;
}

}  // namespace sculpt::server::store
