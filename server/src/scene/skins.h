/// @brief Ball skins on the server (issue 6): replaying logged sweeps, and the skin files written
/// beside snapshots. The records' and files' storage format lives in sculpt/codec/log_records.h;
/// the skin messages off the wire are decoded before the scene by sculpt/codec/skin_messages.h.
#ifndef SCULPT_SERVER_SCENE_SKINS_H_
#define SCULPT_SERVER_SCENE_SKINS_H_

#include <cstdint>
#include <string>

#include "sculpt/codec/log_records.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::server {

/// Recovery: applies a logged sweep as the live server did. A sweep the kernel refuses, or a
/// malformed record, is skipped with a warning (Ok, nothing applied), as live.
Status ReplaySweep(levelset::Sculpture& sculpture, uint64_t seq, const codec::SweepRecord& record);

/// Writes a skin's state to `path` atomically (temporary file, fsync, rename). Internal on I/O
/// errors.
Status SaveSkinFile(const std::string& path, const codec::SavedSkin& saved);
/// Reads what SaveSkinFile wrote; NotFound when absent, DataLoss when it does not parse.
StatusOr<codec::SavedSkin> LoadSkinFile(const std::string& path);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_SKINS_H_
