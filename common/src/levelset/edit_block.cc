/// @file edit_block.cc
/// @brief The edit block: the tools' fields, the block's extent, extraction and write-back.
#include "edit_block.h"

#include <algorithm>
#include <cmath>

namespace sculpt::levelset::internal {

// The block reaches two voxels past its stencil margin.
constexpr int kBlockPad = kStencilMargin + 2;

double ToolScale(const ToolShape& t) {
  switch (t.kind) {
    case ToolKind::kSphere:
    case ToolKind::kCapsule:
      return t.size.x;
    default:
      return std::max({t.size.x, t.size.y, t.size.z});
  }
}

namespace {

// Block-local index range [lo, hi) of the voxels within `margin` (world units) of `tb`.
void RangeNear(const Block& b, const Aabb& tb, double margin, int lo[3], int hi[3]) {
  const Int3 o = b.box.min;
  const Int3 d = b.phi.dims();
  const double mn[3] = {tb.min.x - margin, tb.min.y - margin, tb.min.z - margin};
  const double mx[3] = {tb.max.x + margin, tb.max.y + margin, tb.max.z + margin};
  const int orig[3] = {o.x, o.y, o.z};
  const int dims[3] = {d.x, d.y, d.z};
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::clamp(static_cast<int>(std::floor(mn[a] / b.dx)) - orig[a], 0, dims[a]);
    hi[a] = std::clamp(static_cast<int>(std::ceil(mx[a] / b.dx)) - orig[a] + 1, 0, dims[a]);
  }
}

// Spheres and capsules have exact distances: no voxel beyond `margin` of their bounds is nearer
// than `margin`, so their fields need not be evaluated there.
bool ExactDistance(const ToolShape& t) {
  return t.kind == ToolKind::kSphere || t.kind == ToolKind::kCapsule;
}

// The bounds of every tool of a batch.
Aabb BatchBounds(const std::vector<EditRequest>& reqs) {
  Aabb tb = ToolBounds(reqs.front().tool);
  for (const EditRequest& r : reqs) {
    const Aabb a = ToolBounds(r.tool);
    tb.min = {std::min(tb.min.x, a.min.x), std::min(tb.min.y, a.min.y),
              std::min(tb.min.z, a.min.z)};
    tb.max = {std::max(tb.max.x, a.max.x), std::max(tb.max.y, a.max.y),
              std::max(tb.max.z, a.max.z)};
  }
  return tb;
}

}  // namespace

// Spheres and capsules, the tools strokes use, skip the generic dispatch: this loop is a hot
// spot of every edit.
void ToolFieldInto(const Block& b, const ToolShape& tool, double margin, std::vector<float>& f,
                   NearBox* near) {
  f.assign(b.phi.size(), std::numeric_limits<float>::max());
  const Int3 o = b.box.min;
  const Int3 d = b.phi.dims();
  int lo[3] = {0, 0, 0}, hi[3] = {d.x, d.y, d.z};
  if (std::isfinite(margin)) RangeNear(b, ToolBounds(tool), margin, lo, hi);
  const double near_limit = near->limit;
  const Vec3 c = tool.center;
  const double r = tool.size.x;
  const Vec3 seg = tool.end - tool.center;
  const double seg_len2 = seg.LengthSqr();
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      float* row = &f[b.phi.Index(0, j, k)];
      const double y = (o.y + j) * b.dx, z = (o.z + k) * b.dx;
      for (int i = lo[0]; i < hi[0]; ++i) {
        const Vec3 p{(o.x + i) * b.dx, y, z};
        double v;
        if (tool.kind == ToolKind::kSphere) {
          v = (p - c).Length() - r;
        } else if (tool.kind == ToolKind::kCapsule) {
          const Vec3 q = p - c;
          const double t = seg_len2 > 0 ? std::clamp(q.Dot(seg) / seg_len2, 0.0, 1.0) : 0.0;
          v = (q - seg * t).Length() - r;
        } else {
          v = ToolSignedDistance(tool, p);
        }
        row[i] = static_cast<float>(v);
      }
      // The stored (float) value, as every selection reads it.
      int i0 = hi[0], i1 = -1;
      for (int i = lo[0]; i < hi[0]; ++i) {
        if (static_cast<double>(row[i]) <= near_limit) {
          i0 = std::min(i0, i);
          i1 = i;
        }
      }
      if (i1 >= 0) near->AddRow(i0, i1, j, k);
    }
  }
}

void LoadRequestField(Block& b, const ToolShape& tool, double margin) {
  b.near = NearBox{};
  b.near.limit = margin;
  ToolFieldInto(b, tool, margin, b.tool_sdf, &b.near);
}

BlockPlan PlanBlock(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs,
                    const EditSettings& s) {
  BlockPlan p;
  const double dx = impl.dx();
  const EditKind kind = reqs.front().kind;
  for (const EditRequest& r : reqs) p.scale = std::max(p.scale, ToolScale(r.tool));
  p.compensate = (kind == EditKind::kPress || kind == EditKind::kSmooth) &&
                 s.compensation != CompensationRegion::kNone;
  p.shell_outer = std::max(3 * dx, s.shell_radii * p.scale) + 1.5 * dx;
  p.reach = (p.compensate && s.compensation == CompensationRegion::kShell ? p.shell_outer : 0) +
            2 * dx +
            (kind == EditKind::kAdd || kind == EditKind::kSubtract ? impl.background() : 0);
  // The surface moves at most to the tool's rim (2 voxels); the band around it, which the
  // band repair rebuilds, must lie inside the written interior.
  p.reach = std::max(p.reach, impl.background() + 2 * dx);
  return p;
}

internal::IndexBox BlockBox(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs,
                            double reach) {
  const Aabb tb = BatchBounds(reqs);
  const Vec3 r{reach, reach, reach};
  return internal::WorldToIndexBox(tb.min - r, tb.max + r, impl.dx(), kBlockPad);
}

Block MakeBlock(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs, double reach,
                double field_reach) {
  Block b;
  b.dx = impl.dx();
  b.bg = impl.background();
  b.eps = 1.5 * b.dx;
  b.object_before = impl.volume / (b.dx * b.dx * b.dx);
  b.box = BlockBox(impl, reqs, reach);
  b.before = internal::ExtractDense(*impl.grid, b.box);
  b.phi = b.before;
  {
    unsigned outside = 0;  // branch-free, so the loop vectorises
    for (float v : b.before.data()) outside |= static_cast<unsigned>((v < -b.bg) | (v > b.bg));
    b.before_in_band = outside == 0;
  }
  const double margin = std::max(field_reach, static_cast<double>(b.bg));
  b.near.limit = margin;
  bool equal_spheres = reqs.size() > 1;
  for (const EditRequest& q : reqs) {
    equal_spheres = equal_spheres && q.tool.kind == ToolKind::kSphere &&
                    q.tool.size.x == reqs.front().tool.size.x;
  }
  if (reqs.size() == 1) {
    const ToolShape& t = reqs.front().tool;
    ToolFieldInto(b, t, ExactDistance(t) ? margin : std::numeric_limits<double>::infinity(),
                  b.tool_sdf, &b.near);
  } else if (equal_spheres) {
    // The poses of a stroke share their tool: the union of equal spheres is the distance to
    // the nearest centre minus the radius, one square root per voxel instead of one per pose.
    b.tool_sdf.assign(b.phi.size(), std::numeric_limits<float>::max());
    const Int3 o = b.box.min;
    const Aabb tb = BatchBounds(reqs);
    int lo[3], hi[3];
    RangeNear(b, tb, margin, lo, hi);
    const double r = reqs.front().tool.size.x;
    for (int k = lo[2]; k < hi[2]; ++k) {
      for (int j = lo[1]; j < hi[1]; ++j) {
        float* row = &b.tool_sdf[b.phi.Index(0, j, k)];
        for (int i = lo[0]; i < hi[0]; ++i) {
          const Vec3 p{(o.x + i) * b.dx, (o.y + j) * b.dx, (o.z + k) * b.dx};
          double best = std::numeric_limits<double>::max();
          for (const EditRequest& q : reqs) best = std::min(best, (p - q.tool.center).LengthSqr());
          row[i] = static_cast<float>(std::sqrt(best) - r);
        }
        int i0 = hi[0], i1 = -1;
        for (int i = lo[0]; i < hi[0]; ++i) {
          if (static_cast<double>(row[i]) <= b.near.limit) {
            i0 = std::min(i0, i);
            i1 = i;
          }
        }
        if (i1 >= 0) b.near.AddRow(i0, i1, j, k);
      }
    }
  } else {
    b.tool_sdf.assign(b.phi.size(), std::numeric_limits<float>::max());
    std::vector<float> f;
    for (const EditRequest& q : reqs) {
      NearBox nb;
      nb.limit = b.near.limit;
      ToolFieldInto(b, q.tool, std::numeric_limits<double>::infinity(), f, &nb);
      b.near.Merge(nb);
      for (size_t i = 0; i < f.size(); ++i) b.tool_sdf[i] = std::min(b.tool_sdf[i], f[i]);
    }
  }
  return b;
}

void SpliceBack(Sculpture::Impl& impl, const Block& b, double base_volume, EditResult* res) {
  // Before the SDF write-back: reads the block's before/after fields only (materials.h).
  internal::CarryFractions(impl, b.before, b.phi, kStencilMargin);
  const NearBox changed = b.Changed();
  internal::WriteBackResult wb =
      internal::WriteBack(*impl.grid, b.before, b.phi, kStencilMargin, changed.lo, changed.hi);
  if (wb.changed_voxels > 0) {
    impl.bounds.expand(openvdb::CoordBBox(openvdb::Coord(b.box.min.x, b.box.min.y, b.box.min.z),
                                          openvdb::Coord(b.box.max.x, b.box.max.y, b.box.max.z)));
  }
  res->changed = wb.changed_voxels > 0;
  res->changed_voxels = wb.changed_voxels;
  res->dirty_leaves = std::move(wb.dirty_leaves);
  res->volume_change = b.InsideChange(changed) * b.dx * b.dx * b.dx;
  impl.volume = base_volume + res->volume_change;
}

double UnionDistance(const std::vector<EditRequest>& reqs, const Vec3& p) {
  double d = std::numeric_limits<double>::max();
  for (const EditRequest& r : reqs) d = std::min(d, ToolSignedDistance(r.tool, p));
  return d;
}

}  // namespace sculpt::levelset::internal
