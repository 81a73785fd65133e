/// @brief Ball skins on the server (issue 6): the edit-log forms of sweeps (a leading zero byte,
/// then a v1::SkinSweepRecord) and of ball edits (a leading 0x03 byte, then a v1::SkinEditRecord)
/// that recovery replays, and the skin files written beside snapshots. These records are the
/// storage format and stay protobuf; the skin messages off the wire are decoded before the scene
/// by sculpt/codec/skin_messages.h.
#ifndef SCULPT_SERVER_SCENE_SKINS_H_
#define SCULPT_SERVER_SCENE_SKINS_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/sweep.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

/// The edit-log payload of a sweep record (read back by DecodeLogRecord, commit.h).
std::string SweepPayload(const v1::SkinSweepRecord& record);
/// The kernel request a record describes; InvalidArgument for a malformed record.
StatusOr<levelset::SweepRequest> SweepFromRecord(const v1::SkinSweepRecord& record);
/// Recovery: applies a logged sweep as the live server did. A sweep the kernel refuses is
/// refused identically (Ok, nothing applied), as live.
Status ReplaySweep(levelset::Sculpture& sculpture, uint64_t seq, const v1::SkinSweepRecord& record);

/// The edit-log payload of a ball-edit record (a leading 0x03 byte, then the record).
std::string SkinEditPayload(const v1::SkinEditRecord& record);

/// Writes a skin's state to `path` atomically (temporary file, fsync, rename). Internal on I/O
/// errors.
Status SaveSkinFile(const std::string& path, const v1::SavedSkin& saved);
/// Reads what SaveSkinFile wrote; NotFound when absent, DataLoss when it does not parse.
StatusOr<v1::SavedSkin> LoadSkinFile(const std::string& path);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_SKINS_H_
