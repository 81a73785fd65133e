/// @brief libFuzzer target for edit-log segment recovery: the input is written as a segment file,
/// then EditLog::Repair (dry run), EditLog::Open (scan, torn-tail handling) and ReadFrom decode it.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <spdlog/spdlog.h>

#include "store/edit_log.h"

namespace {
// Every rejected segment is logged; at thousands of inputs a second that drowns the output.
const bool kQuietLog = (spdlog::set_level(spdlog::level::off), true);
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace fs = std::filesystem;
  // /dev/shm keeps the per-input files off the disk; fall back to the temp dir.
  const fs::path base = fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
  const fs::path dir = base / ("sculpt-fuzz-edit-log-" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    std::ofstream out(dir / "log-00000000000000000001.sclog", std::ios::binary);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  namespace store = sculpt::server::store;
  (void)store::EditLog::Repair(dir.string(), /*dry_run=*/true);
  {
    store::RecoveryReport report;
    auto log = store::EditLog::Open(dir.string(), store::FsyncPolicy{}, &report);
    // The log is closed at the end of this block, before its files are removed.
    auto records = log.ok() ? (*log)->ReadFrom(0) : log.status();
    if (records.ok()) {
      uint64_t previous = 0;
      for (const auto& record : *records) {
        // Recovery hands records on in strictly increasing sequence order.
        if (record.seq <= previous) std::abort();
        previous = record.seq;
      }
    }
  }
  fs::remove_all(dir);
  return 0;
}
