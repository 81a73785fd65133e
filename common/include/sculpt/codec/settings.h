/// @brief Edit settings on the wire: the server sends its levelset::EditSettings in SceneInfo so a
/// replica replays edits with exactly the server's kernel configuration.
#ifndef SCULPT_CODEC_SETTINGS_H_
#define SCULPT_CODEC_SETTINGS_H_

#include "sculpt/core/status.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {

v1::EditSettingsMsg SettingsToProto(const levelset::EditSettings& s);

/// Untrusted input: InvalidArgument naming the field, its value and the allowed range for an
/// enum out of range, and whatever levelset::ValidateEditSettings refuses. Validated here, once:
/// a replica replays every edit with the result without checking it again.
StatusOr<levelset::ValidEditSettings> SettingsFromProto(const v1::EditSettingsMsg& m);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_SETTINGS_H_
