/// @brief ResendTable: the newest client sequence of each (client, edit stream) at a snapshot,
/// saved beside the snapshots so that resends are recognised after the log before it is dropped.
#ifndef SCULPT_SERVER_STORE_RESEND_TABLE_H_
#define SCULPT_SERVER_STORE_RESEND_TABLE_H_

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>

#include "sculpt/core/status.h"

namespace sculpt::server::store {

/// File name of the table inside a data directory.
inline constexpr char kResendTableFile[] = "resend_table.bin";
/// Largest number of entries a reader believes.
inline constexpr uint32_t kMaxResendEntries = 1u << 22;

/// (stream, client id) -> newest client_seq applied. The stream is the caller's small number
/// per edit kind (strokes, paints, ...).
struct ResendTable {
  uint64_t seq = 0;  // the global seq the table is complete up to
  std::map<std::pair<uint8_t, uint64_t>, uint64_t> last;
};

/// Writes `table` to `path` through `<path>.tmp`: written, fsynced, renamed, directory fsynced.
/// Internal naming the path for I/O errors.
Status SaveResendTable(const std::string& path, const ResendTable& table);

/// Reads a table written by SaveResendTable. NotFound when the file does not exist; DataLoss
/// naming the file for a bad magic, size or checksum (sizes are checked before allocation).
StatusOr<ResendTable> LoadResendTable(const std::string& path);

}  // namespace sculpt::server::store

#endif  // SCULPT_SERVER_STORE_RESEND_TABLE_H_
