/// @brief Painting material fractions on the server (issue 7): the checks of a PaintEdit off the
/// wire, and its edit-log form (a leading 0x01 byte, then a v1::PaintRecord) that recovery
/// replays. The scene's paint path (Scene::Paint) lives in paint.cc.
#ifndef SCULPT_SERVER_SCENE_PAINT_H_
#define SCULPT_SERVER_SCENE_PAINT_H_

#include <cstdint>
#include <string>

#include "sculpt/codec/stroke.h"
#include "sculpt/core/status.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

/// Every field of a paint, against the object's limits (tool sizes finite in [0.5,
/// levelset::kMaxPaintToolVoxels] voxels, position finite and inside the object's bounds grown
/// by the margin) and the scene's `materials` count: tool kind sphere/ellipsoid/box, material in
/// [0, n-1], weight finite in [0, 1]; a set `fractions` must hold n finite entries in [0, 1]
/// summing to 1 within 1e-6. InvalidArgument "PaintEdit.<field>=<value> outside <range>";
/// FailedPrecondition when the scene declares no materials.
Status ValidatePaintEdit(const v1::PaintEdit& edit, const codec::StrokeLimits& limits,
                         int materials);

/// The kernel tool a paint describes (the floats of the message, so live and replay agree).
levelset::ToolShape ToolFromPaint(const v1::PaintEdit& edit);
/// Applies a paint (PaintMaterial) or a fill (FillMaterial, when fractions are set). The
/// kernel's errors; the sculpture is unchanged then.
StatusOr<levelset::MaterialEditResult> ApplyPaint(levelset::Sculpture& sculpture,
                                                  const v1::PaintEdit& edit);

/// The edit-log payload of a paint record (read back by DecodeLogRecord, commit.h).
std::string PaintPayload(const v1::PaintRecord& record);
/// Recovery: applies a logged paint as the live server did. A paint the kernel refuses is
/// refused identically (Ok, nothing applied), as live.
Status ReplayPaint(levelset::Sculpture& sculpture, uint64_t seq, const v1::PaintRecord& record);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_PAINT_H_
