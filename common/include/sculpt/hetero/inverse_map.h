/// @brief The inverse of a composite model's map: given a world point, the cell and (u,v,w) that
/// map to it and the materials there (seed 001 §10.3 step 5) — what voxelising materials into
/// the sculpture needs at every voxel centre.
#ifndef SCULPT_HETERO_INVERSE_MAP_H_
#define SCULPT_HETERO_INVERSE_MAP_H_

#include <array>
#include <optional>
#include <span>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/hyperpatch.h"

namespace sculpt::hetero {

struct InverseMapOptions {
  int start_subdivisions = 4;     // Newton starts from the nearest node of an n×n×n subdivision
  int max_iterations = 30;
  double relative_tolerance = 1e-10;  // |P(u,v,w) − x| / model size to accept
  double parameter_slack = 1e-9;      // how far outside [0,1] a root may fall and be clamped
};

/// Where a point lies.
struct Location {
  int cell = -1;
  Vec3 uvw;
  Fractions materials;
  int iterations = 0;
};

/// A snapshot of a model prepared for point queries: cells bucketed in a uniform grid by their
/// control-point boxes (convex hull property), a subdivision of start points per cell.
/// Immutable after construction; Locate may be called from many threads at once.
class InverseMap {
 public:
  explicit InverseMap(const CompositeModel& model, InverseMapOptions opt = {});

  /// The lowest-index cell containing x and its (u,v,w) and materials, so points on internal
  /// faces take the lower-index cell's material ((5.4), §7.4.1); nullopt outside the model or
  /// for a non-finite x.
  std::optional<Location> Locate(const Vec3& x) const;
  /// As Locate, trying first Newton from `hint` (the location of a nearby point, e.g. the
  /// previous voxel of a scan): same answers, far fewer iterations. Falls back to the full
  /// search when the hint misses or lands on its cell's boundary (where a lower-index cell may
  /// own the point).
  std::optional<Location> Locate(const Vec3& x, const Location* hint) const;
  /// As Locate, writing only the materials (size materials()); false outside.
  bool MaterialsAt(const Vec3& x, std::span<double> out) const;
  /// Newton inversion within one cell; nullopt when x is not in it.
  std::optional<Location> LocateInCell(int cell, const Vec3& x) const;
  /// Newton within one cell from a given start.
  std::optional<Location> NewtonInCell(int cell, const Vec3& x, Vec3 start) const;

  int materials() const { return materials_; }
  const Aabb& bounds() const { return bounds_; }
  size_t cell_count() const { return patches_.size(); }

 private:
  InverseMapOptions opt_;
  int materials_ = 1;
  std::vector<Hyperpatch> patches_;
  std::vector<Aabb> boxes_;
  // Per cell: canonical-frame axes and the control points' interval along each (a tighter
  // convex bound than the box for thin curved cells).
  std::vector<std::array<Vec3, 3>> frames_;
  std::vector<std::array<std::pair<double, double>, 3>> extents_;
  std::vector<std::vector<Vec3>> starts_;  // P at the subdivision nodes, per cell
  Aabb bounds_;
  double tol_ = 0;
  int res_[3] = {1, 1, 1};
  Vec3 cell_size_;
  std::vector<std::vector<int>> grid_;  // ascending cell indices per bucket
};

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_INVERSE_MAP_H_
