/// @brief Tool shapes in the two forms the thesis uses: an implicit signed distance (the influence
/// region Gamma) and explicit surface sample points (for contact). Seed 000 §2.4, §3.2.
#ifndef SCULPT_LEVELSET_TOOL_H_
#define SCULPT_LEVELSET_TOOL_H_

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"

namespace sculpt::levelset {

enum class ToolKind : uint8_t { kSphere = 0, kEllipsoid = 1, kBox = 2, kCapsule = 3 };

const char* ToolKindName(ToolKind kind);

/// A rigid tool in world coordinates.
/// - kSphere: `center`, radius `size.x`.
/// - kEllipsoid: `center`, semi-axes `size` in the body frame, `rotation` body->world.
/// - kBox: `center`, half-extents `size` in the body frame, `rotation` body->world.
/// - kCapsule: segment `center`..`end` swept by a sphere of radius `size.x` (a stroke between two
///   poses).
/// Value type.
struct ToolShape {
  ToolKind kind = ToolKind::kSphere;
  Vec3 center;
  Vec3 size{1, 1, 1};
  Quat rotation;
  Vec3 end;

  static ToolShape Sphere(Vec3 c, double r);
  static ToolShape Ellipsoid(Vec3 c, Vec3 semi_axes, Quat rot = {});
  static ToolShape Box(Vec3 c, Vec3 half_extents, Quat rot = {});
  static ToolShape Capsule(Vec3 a, Vec3 b, double r);
};

/// World-space axis-aligned bounds.
struct Aabb {
  Vec3 min, max;
  bool Overlaps(const Aabb& o) const {
    return min.x <= o.max.x && max.x >= o.min.x && min.y <= o.max.y && max.y >= o.min.y &&
           min.z <= o.max.z && max.z >= o.min.z;
  }
};

/// Checks every field: finite numbers, sizes in [min_size, max_size] (world units), a unit
/// quaternion (|q| within 1e-3 of 1). The error names the field, the value and the allowed range,
/// e.g. `InvalidArgument("tool.size.x=-1 outside [0.5, 64]")`.
Status ValidateTool(const ToolShape& tool, double min_size, double max_size);

/// Signed distance from p to the tool surface, negative inside. Exact for sphere, box and capsule;
/// for the ellipsoid a first-order estimate that has the right sign and zero set and is exact on
/// the axes (good enough for masks).
double ToolSignedDistance(const ToolShape& tool, const Vec3& p);

/// Outward unit normal of the tool surface nearest to p (the gradient of ToolSignedDistance).
Vec3 ToolNormal(const ToolShape& tool, const Vec3& p);

/// Tight world bounds of the tool.
Aabb ToolBounds(const ToolShape& tool);

/// Explicit form: about `count` points on the tool surface, deterministic, roughly uniform
/// (Fibonacci lattice on spheres/ellipsoids, per-face grids on boxes, rings plus hemispheres on
/// capsules). Never fewer than 8 points.
std::vector<Vec3> ToolSurfaceSamples(const ToolShape& tool, int count);

/// Volume of the tool (exact).
double ToolVolume(const ToolShape& tool);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_TOOL_H_
