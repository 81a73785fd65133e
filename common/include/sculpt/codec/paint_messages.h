/// @brief A PaintEdit off the wire (issue 7) decoded into a domain paint: checked against the
/// object's limits and the scene's material count, naming field, value and range.
#ifndef SCULPT_CODEC_PAINT_MESSAGES_H_
#define SCULPT_CODEC_PAINT_MESSAGES_H_

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/codec/stroke.h"
#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/tool.h"

namespace sculpt::v1 {
class PaintEdit;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// A validated paint (PaintMaterial) or fill (FillMaterial, when `fractions` is not empty).
/// Fields a paint does not use are 0 (a sphere's size y and z; a fill's material and weight).
struct Paint {
  uint64_t client_seq = 0;
  std::string object;
  levelset::ToolKind tool = levelset::ToolKind::kSphere;  // sphere, ellipsoid or box
  Vec3 tool_size;  // world units, from the wire's floats
  Vec3 position;   // world units, from the wire's floats
  uint32_t material = 0;
  double weight = 0;
  std::vector<double> fractions;

  /// The kernel tool (the floats of the message, so the live path and replay agree).
  levelset::ToolShape Tool() const;
};

/// Checks every field of a PaintEdit against the object's limits (tool sizes finite in [0.5,
/// levelset::kMaxPaintToolVoxels] voxels, position finite and inside the object's bounds grown
/// by the margin) and the scene's `materials` count: tool kind sphere/ellipsoid/box, material in
/// [0, n-1], weight finite in [0, 1]; set `fractions` must hold n finite entries in [0, 1]
/// summing to 1 within 1e-6. InvalidArgument "PaintEdit.<field>=<value> outside <range>";
/// FailedPrecondition when the scene declares no materials.
StatusOr<Paint> DecodePaintEdit(const v1::PaintEdit& edit, const StrokeLimits& limits,
                                int materials);

/// The paint a logged PaintEdit describes, unchecked (recovery: the live server checked it
/// against the limits of its time). An unknown tool kind reads as a sphere, as it always has.
Paint PaintFromRecord(const v1::PaintEdit& edit);
/// The wire form of a paint, which the edit log's PaintRecord embeds.
v1::PaintEdit EncodePaintEdit(const Paint& paint);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_PAINT_MESSAGES_H_
