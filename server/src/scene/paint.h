/// @brief Painting material fractions on the server (issue 7): applying a decoded paint
/// (sculpt/codec/paint_messages.h decodes the PaintEdit off the wire) and replaying its edit-log
/// record (sculpt/codec/log_records.h holds the storage format). The scene's paint path
/// (Scene::Paint) lives in paint.cc.
#ifndef SCULPT_SERVER_SCENE_PAINT_H_
#define SCULPT_SERVER_SCENE_PAINT_H_

#include <cstdint>
#include <string>

#include "sculpt/codec/log_records.h"
#include "sculpt/codec/paint_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::server {

/// Applies a paint (PaintMaterial) or a fill (FillMaterial, when fractions are set). The
/// kernel's errors; the sculpture is unchanged then.
StatusOr<levelset::MaterialEditResult> ApplyPaint(levelset::Sculpture& sculpture,
                                                  const codec::Paint& paint);

/// Recovery: applies a logged paint as the live server did. A paint the kernel refuses is
/// refused identically (Ok, nothing applied), as live.
Status ReplayPaint(levelset::Sculpture& sculpture, uint64_t seq,
                   const codec::PaintRecord& record);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_PAINT_H_
