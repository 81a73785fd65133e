/// @brief ResendTable file: "SCLPRSND" | u32 version | u32 entries | u64 seq | entries of
/// (u8 stream, u64 client, u64 client_seq) | u32 CRC32C of everything before it.
#include "store/resend_table.h"

#include "store/durable_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace sculpt::server::store {
namespace {

constexpr char kMagic[8] = {'S', 'C', 'L', 'P', 'R', 'S', 'N', 'D'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeader = 8 + 4 + 4 + 8;
constexpr size_t kEntry = 1 + 8 + 8;

void Put(std::string* out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out->push_back(static_cast<char>(v >> (8 * i)));
}
uint64_t Get(const std::string& in, size_t at, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) {
    v |= static_cast<uint64_t>(static_cast<unsigned char>(in[at + static_cast<size_t>(i)]))
         << (8 * i);
  }
  return v;
}
uint32_t Crc(const char* data, size_t size) { return Crc32c(std::string_view(data, size)); }

}  // namespace

Status SaveResendTable(const std::string& path, const ResendTable& table) {
  std::string bytes(kMagic, sizeof(kMagic));
  Put(&bytes, kVersion, 4);
  Put(&bytes, table.last.size(), 4);
  Put(&bytes, table.seq, 8);
  for (const auto& [key, client_seq] : table.last) {
    Put(&bytes, key.first, 1);
    Put(&bytes, key.second, 8);
    Put(&bytes, client_seq, 8);
  }
  Put(&bytes, Crc(bytes.data(), bytes.size()), 4);
  return WriteFileDurably(path, bytes);
}

StatusOr<ResendTable> LoadResendTable(const std::string& path) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) {
    if (!std::filesystem::exists(path)) return NotFound("resend table " + path);
    return Internal("resend table: size of " + path + ": " + ec.message());
  }
  if (size < kHeader + 4 || size > kHeader + 4 + uint64_t{kMaxResendEntries} * kEntry) {
    return DataLoss("resend table " + path + ": size " + std::to_string(size) + " bytes is not " +
                    "a table's");
  }
  std::string bytes(size, '\0');
  {
    std::ifstream in(path, std::ios::binary);
    if (!in.read(bytes.data(), static_cast<std::streamsize>(size))) {
      return Internal("resend table: reading " + path);
    }
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0 || Get(bytes, 8, 4) != kVersion) {
    return DataLoss("resend table " + path + ": bad magic or version");
  }
  const uint64_t count = Get(bytes, 12, 4);
  if (kHeader + count * kEntry + 4 != size) {
    return DataLoss("resend table " + path + ": " + std::to_string(count) + " entries but " +
                    std::to_string(size) + " bytes");
  }
  if (Crc(bytes.data(), size - 4) != Get(bytes, size - 4, 4)) {
    return DataLoss("resend table " + path + ": checksum mismatch");
  }
  ResendTable table;
  table.seq = Get(bytes, 16, 8);
  for (uint64_t i = 0; i < count; ++i) {
    const size_t at = kHeader + i * kEntry;
    table.last[{static_cast<uint8_t>(Get(bytes, at, 1)), Get(bytes, at + 1, 8)}] =
        Get(bytes, at + 9, 8);
  }
  return table;
}

}  // namespace sculpt::server::store
