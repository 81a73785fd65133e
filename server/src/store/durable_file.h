/// @brief The byte layer under the store's files: little-endian integers, CRC-32C, and writes
/// that survive a crash (fdatasync, rename, directory fsync).
#ifndef SCULPT_SERVER_STORE_DURABLE_FILE_H_
#define SCULPT_SERVER_STORE_DURABLE_FILE_H_

#include <boost/crc.hpp>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>

#include "sculpt/core/status.h"

namespace sculpt::server::store {

/// CRC-32C (Castagnoli), fed incrementally with process_bytes(): better burst-error detection
/// than zlib's CRC-32 for the same cost. Every checksum in the data directory is one.
using Crc32cState = boost::crc_optimal<32, 0x1EDC6F41, 0xFFFFFFFF, 0xFFFFFFFF, true, true>;

/// CRC-32C of `size` bytes at `data`.
inline uint32_t Crc32c(const void* data, size_t size) {
  Crc32cState crc;
  crc.process_bytes(data, size);
  return crc.checksum();
}
inline uint32_t Crc32c(std::string_view bytes) { return Crc32c(bytes.data(), bytes.size()); }

/// Writes `v` as sizeof(T) little-endian bytes at `p` (a char or uint8_t buffer).
template <typename T, typename Byte>
void PutLittleEndian(Byte* p, T v) {
  static_assert(std::is_unsigned_v<T> && sizeof(Byte) == 1);
  for (size_t i = 0; i < sizeof(T); ++i) p[i] = static_cast<Byte>(v >> (8 * i));
}

/// Reads sizeof(T) little-endian bytes at `p`.
template <typename T, typename Byte>
T GetLittleEndian(const Byte* p) {
  static_assert(std::is_unsigned_v<T> && sizeof(Byte) == 1);
  T v = 0;
  for (size_t i = 0; i < sizeof(T); ++i) {
    v |= static_cast<T>(static_cast<unsigned char>(p[i])) << (8 * i);
  }
  return v;
}

/// fsync of a file or (directory = true) a directory, so that data, or a rename or unlink
/// inside the directory, survives a power loss. Internal naming the path on failure.
Status FsyncPath(const std::string& path, bool directory);

/// fsync of a directory (FsyncPath(dir, true)).
inline Status FsyncDirectory(const std::string& dir) { return FsyncPath(dir, true); }

/// Replaces `path` with `bytes` so that a crash leaves the old file or the new one whole: written
/// to `<path>.tmp`, fdatasynced, renamed, the directory fsynced. Internal naming the path and the
/// step that failed.
Status WriteFileDurably(const std::string& path, std::string_view bytes);

}  // namespace sculpt::server::store

#endif  // SCULPT_SERVER_STORE_DURABLE_FILE_H_
