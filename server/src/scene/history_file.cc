/// @brief The stroke undo history file beside each object snapshot.
#include "scene/history_file.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <utility>
#include <vector>

#include "store/durable_file.h"

namespace sculpt::server {
namespace {

constexpr char kHistoryMagic[8] = {'S', 'C', 'L', 'P', 'H', 'I', 'S', 'T'};
constexpr size_t kHistoryHeader = 8 + 8 + 8 + 4;

// One file per object and snapshot round, so a start-up that falls back to an older snapshot
// finds the history kept with that one.
std::filesystem::path HistoryDir(const std::string& data_dir) {
  return std::filesystem::path(data_dir) / "history";
}

// History files kept per object, as many as the snapshot store keeps snapshots.
constexpr size_t kHistoryFilesKept = 3;

}  // namespace

std::string HistoryFilePath(const std::string& data_dir, const std::string& object, uint64_t seq) {
  return (HistoryDir(data_dir) / (object + "." + std::to_string(seq) + ".bin")).string();
}

std::string LegacyHistoryFilePath(const std::string& data_dir, const std::string& object) {
  return (HistoryDir(data_dir) / (object + ".bin")).string();
}

std::string HistoryFileBytes(const EditHistory& history, uint64_t seq) {
  const std::string payload = history.Serialize();
  std::string bytes(kHistoryMagic, sizeof(kHistoryMagic));
  const uint64_t size = payload.size();
  const uint32_t crc = store::Crc32c(payload);
  bytes.append(reinterpret_cast<const char*>(&seq), 8);
  bytes.append(reinterpret_cast<const char*>(&size), 8);
  bytes.append(reinterpret_cast<const char*>(&crc), 4);
  bytes += payload;
  return bytes;
}

StatusOr<EditHistory> ParseHistoryFile(std::string_view bytes, uint64_t snapshot_seq,
                                       EditHistoryOptions options) {
  if (bytes.size() < kHistoryHeader || std::memcmp(bytes.data(), kHistoryMagic, 8) != 0) {
    return DataLoss("not a history file");
  }
  uint64_t seq = 0, size = 0;
  uint32_t crc = 0;
  std::memcpy(&seq, bytes.data() + 8, 8);
  std::memcpy(&size, bytes.data() + 16, 8);
  std::memcpy(&crc, bytes.data() + 24, 4);
  if (seq != snapshot_seq) {
    return DataLoss("kept at seq " + std::to_string(seq) + ", the snapshot is at seq " +
                    std::to_string(snapshot_seq));
  }
  const std::string_view payload = bytes.substr(kHistoryHeader);
  if (size != payload.size() || store::Crc32c(payload) != crc) {
    return DataLoss("size or checksum mismatch");
  }
  return EditHistory::Parse(payload, options);
}

Status WriteHistoryFile(const std::string& data_dir, const std::string& object, uint64_t seq,
                        const std::string& bytes) {
  std::error_code ec;
  std::filesystem::create_directories(HistoryDir(data_dir), ec);
  if (const Status s = store::WriteFileDurably(HistoryFilePath(data_dir, object, seq), bytes);
      !s.ok()) {
    spdlog::error("undo history of {} at seq {} not saved: {}", object, seq, s.ToString());
    return s;
  }
  // Only the rounds whose snapshots are still kept can be started from.
  std::vector<std::pair<uint64_t, std::filesystem::path>> files;
  const std::string prefix = object + ".";
  for (const auto& e : std::filesystem::directory_iterator(HistoryDir(data_dir), ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() <= prefix.size() + 4 || name.rfind(prefix, 0) != 0 ||
        name.substr(name.size() - 4) != ".bin") {
      continue;
    }
    const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - 4);
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    files.emplace_back(std::stoull(digits), e.path());
  }
  std::sort(files.begin(), files.end());
  for (size_t i = 0; i + kHistoryFilesKept < files.size(); ++i) {
    std::filesystem::remove(files[i].second, ec);
  }
  std::filesystem::remove(LegacyHistoryFilePath(data_dir, object), ec);
  return Status::Ok();
}

}  // namespace sculpt::server
