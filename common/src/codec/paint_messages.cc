/// @brief Decoding of PaintEdit off the wire and of the PaintEdit a PaintRecord embeds.
#include "sculpt/codec/paint_messages.h"

#include <span>
#include <string>

#include "sculpt/core/check.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

constexpr size_t kMaxNameBytes = 64;

Vec3 V(const v1::Vec3f& v) { return {v.x(), v.y(), v.z()}; }

levelset::ToolKind PaintTool(v1::ToolKind k) {
  switch (k) {
    case v1::TOOL_KIND_ELLIPSOID: return levelset::ToolKind::kEllipsoid;
    case v1::TOOL_KIND_BOX: return levelset::ToolKind::kBox;
    default: return levelset::ToolKind::kSphere;
  }
}

}  // namespace

levelset::ToolShape Paint::Tool() const {
  switch (tool) {
    case levelset::ToolKind::kEllipsoid: return levelset::ToolShape::Ellipsoid(position, tool_size);
    case levelset::ToolKind::kBox: return levelset::ToolShape::Box(position, tool_size);
    default: return levelset::ToolShape::Sphere(position, tool_size.x);
  }
}

StatusOr<Paint> DecodePaintEdit(const v1::PaintEdit& e, const StrokeLimits& limits,
                                int materials) {
  if (e.object().empty() || e.object().size() > kMaxNameBytes) {
    return Outside("PaintEdit.object", e.object(), "names of 1..64 bytes");
  }
  if (materials <= 0) {
    return Outside("PaintEdit.object", e.object(),
                   "scenes that declare materials (this one declares none)",
                   Status::Code::kFailedPrecondition);
  }
  if (e.tool() != v1::TOOL_KIND_SPHERE && e.tool() != v1::TOOL_KIND_ELLIPSOID &&
      e.tool() != v1::TOOL_KIND_BOX) {
    return Outside("PaintEdit.tool", std::to_string(e.tool()),
                   "{1 (SPHERE), 2 (ELLIPSOID), 3 (BOX)}");
  }
  const double dx = limits.voxel_size;
  const double lo = 0.5 * dx;
  const double hi = levelset::kMaxPaintToolVoxels * dx;
  SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.tool_size.x", e.tool_size().x(), lo, hi));
  if (e.tool() != v1::TOOL_KIND_SPHERE) {
    SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.tool_size.y", e.tool_size().y(), lo, hi));
    SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.tool_size.z", e.tool_size().z(), lo, hi));
  }
  const Vec3 p = V(e.position());
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("PaintEdit.position", p));
  const double m = limits.bounds_margin;
  const double pc[3] = {p.x, p.y, p.z};
  const double bl[3] = {limits.bounds.min.x, limits.bounds.min.y, limits.bounds.min.z};
  const double bh[3] = {limits.bounds.max.x, limits.bounds.max.y, limits.bounds.max.z};
  const char* axis[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    SCULPT_RETURN_IF_ERROR(
        CheckRange(std::string("PaintEdit.position.") + axis[a], pc[a], bl[a] - m, bh[a] + m));
  }
  Paint out;
  out.client_seq = e.client_seq();
  out.object = e.object();
  out.tool = PaintTool(e.tool());
  out.tool_size = V(e.tool_size());
  if (out.tool == levelset::ToolKind::kSphere) out.tool_size.y = out.tool_size.z = 0;
  out.position = p;
  if (e.fractions_size() > 0) {
    // A fill: the vector itself goes into the sculpture, so it must lie in the simplex (seed 001
    // (4.2)): negative, NaN or a sum off 1 by more than 1e-6 is refused by name.
    SCULPT_RETURN_IF_ERROR(levelset::ValidateFractionVector(
        "PaintEdit.fractions", std::span<const double>(e.fractions().data(), e.fractions_size()),
        materials));
    out.fractions.assign(e.fractions().begin(), e.fractions().end());
    return out;
  }
  if (e.material() >= static_cast<uint32_t>(materials)) {
    return Outside("PaintEdit.material", std::to_string(e.material()),
                   std::string("[0, ") + std::to_string(materials - 1) + "]");
  }
  SCULPT_RETURN_IF_ERROR(CheckRange("PaintEdit.weight", e.weight(), 0.0, 1.0));
  out.material = e.material();
  out.weight = e.weight();
  return out;
}

Paint PaintFromRecord(const v1::PaintEdit& e) {
  Paint out;
  out.client_seq = e.client_seq();
  out.object = e.object();
  out.tool = PaintTool(e.tool());
  out.tool_size = V(e.tool_size());
  out.position = V(e.position());
  out.material = e.material();
  out.weight = e.weight();
  out.fractions.assign(e.fractions().begin(), e.fractions().end());
  return out;
}

v1::PaintEdit EncodePaintEdit(const Paint& p) {
  v1::PaintEdit e;
  e.set_client_seq(p.client_seq);
  e.set_object(p.object);
  switch (p.tool) {
    case levelset::ToolKind::kEllipsoid: e.set_tool(v1::TOOL_KIND_ELLIPSOID); break;
    case levelset::ToolKind::kBox: e.set_tool(v1::TOOL_KIND_BOX); break;
    default: e.set_tool(v1::TOOL_KIND_SPHERE); break;
  }
  // The sizes and position came from floats: converting back is exact.
  *e.mutable_tool_size() = ToProto(p.tool_size);
  *e.mutable_position() = ToProto(p.position);
  e.set_material(p.material);
  e.set_weight(p.weight);
  for (double f : p.fractions) e.add_fractions(f);
  return e;
}

}  // namespace sculpt::codec
