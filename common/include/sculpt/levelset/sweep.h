/// @brief Sweeps of a closed planar outline into a sculpture (extrusion along the plane normal or
/// a full revolution about an axis in the plane) as a CSG add or subtract edit: the outline is
/// rasterised into a 2D signed distance, lifted to the swept solid's 3D distance over the swept
/// region, and united with (or cut from) the level set.
#ifndef SCULPT_LEVELSET_SWEEP_H_
#define SCULPT_LEVELSET_SWEEP_H_

#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset {

/// A plane point in the coordinates of a SweepPlane's axes.
struct PlanePoint {
  double x = 0, y = 0;
};

/// A plane in world space: `origin` and two unit, orthogonal in-plane axes; the normal is u x v.
struct SweepPlane {
  Vec3 origin;
  Vec3 u{1, 0, 0};
  Vec3 v{0, 1, 0};
  Vec3 At(const PlanePoint& p) const { return origin + u * p.x + v * p.y; }
};

/// Checks a plane: finite, |u| and |v| within 1e-6 of 1, |u.v| <= 1e-6. InvalidArgument naming
/// `field`.u / .v, the value and the allowed range.
Status ValidatePlane(const std::string& field, const SweepPlane& plane);

/// One sweep.
struct SweepRequest {
  enum class Mode { kExtrude, kRevolve };
  Mode mode = Mode::kExtrude;
  bool add = true;  // CSG union; false: difference
  SweepPlane plane;
  /// The closed outline in plane coordinates, first point not repeated, at least 3 points.
  std::vector<PlanePoint> outline;
  /// kExtrude: the solid spans [0, depth] along the normal from the plane.
  double depth = 1;
  /// kRevolve: the axis through `axis_point` along `axis_dir` (plane coordinates, unit).
  PlanePoint axis_point;
  PlanePoint axis_dir{1, 0};
};

/// Largest outline accepted (points) and largest block a sweep may touch (voxels).
inline constexpr size_t kMaxSweepOutlinePoints = 1u << 18;
inline constexpr double kMaxSweepBlockVoxels = 1u << 25;

/// Checks every field (finite, ranges, the plane, a block no larger than kMaxSweepBlockVoxels)
/// without applying. InvalidArgument naming field, value and range.
Status ValidateSweep(const Sculpture& sculpture, const SweepRequest& request);

/// Signed distance (negative inside, even-odd rule) from `p` to the closed polygon `outline`.
double PolygonSignedDistance(const std::vector<PlanePoint>& outline, const PlanePoint& p);

/// Applies the sweep: phi = min(phi, d) (add) or max(phi, -d) (subtract) over the swept solid's
/// block, d its distance clamped to the band. The tracked volume follows the changed voxels and
/// the reference volume moves with it (material added or removed on purpose). Deterministic;
/// on a bad request returns InvalidArgument and leaves the sculpture unchanged.
StatusOr<EditResult> ApplySweep(Sculpture& sculpture, const SweepRequest& request);

/// The index box a sweep reads and writes (voxel by voxel), for undo (server/src/scene/
/// edit_history.h). Meaningful for a request ValidateSweep accepts.
EditFootprint SweepFootprintOf(const Sculpture& sculpture, const SweepRequest& request);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_SWEEP_H_
