/// @brief Local deformation edits: copy the influence box (plus compensation shell and stencil
/// halo) into a DenseField, run the seed 000 operators there, splice the changed voxels back.
#include "sculpt/levelset/edit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "sculpt/core/check.h"
#include "sculpt/levelset/fast_march.h"
#include "sculpt/levelset/invariants.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

// WENO5 reads three voxels to each side; the write-back skips this margin, and every mask
// below stays at least this far from the block border.
constexpr int kStencilMargin = 3;
constexpr int kBlockPad = kStencilMargin + 2;
constexpr int kBandRepairRounds = 4;

std::string Num(double v) { return FormatNumber(v); }

double ToolScale(const ToolShape& t) {
  switch (t.kind) {
    case ToolKind::kSphere:
    case ToolKind::kCapsule:
      return t.size.x;
    default:
      return std::max({t.size.x, t.size.y, t.size.z});
  }
}

// A block-local index range [lo, hi) that holds every voxel whose tool distance is at most
// `limit` (world units); empty (lo >= hi) when there is none.
struct NearBox {
  int lo[3] = {std::numeric_limits<int>::max(), std::numeric_limits<int>::max(),
               std::numeric_limits<int>::max()};
  int hi[3] = {std::numeric_limits<int>::min(), std::numeric_limits<int>::min(),
               std::numeric_limits<int>::min()};
  double limit = -std::numeric_limits<double>::infinity();

  // Row (j, k) has voxels within the limit from i0 to i1 inclusive.
  void AddRow(int i0, int i1, int j, int k) {
    lo[0] = std::min(lo[0], i0);
    hi[0] = std::max(hi[0], i1 + 1);
    lo[1] = std::min(lo[1], j);
    hi[1] = std::max(hi[1], j + 1);
    lo[2] = std::min(lo[2], k);
    hi[2] = std::max(hi[2], k + 1);
  }
  void Merge(const NearBox& o) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], o.lo[a]);
      hi[a] = std::max(hi[a], o.hi[a]);
    }
  }
};

// Everything one edit needs about its block.
struct Block {
  internal::IndexBox box;
  DenseField before;
  DenseField phi;
  std::vector<float> tool_sdf;  // world units, per voxel
  NearBox near;                 // where tool_sdf <= near.limit
  double dx = 1;
  float bg = 1;
  double eps = 1.5;
  bool before_in_band = false;  // every extracted value within [-bg, bg]

  bool Interior(int i, int j, int k) const {
    const Int3 d = phi.dims();
    return i >= kStencilMargin && j >= kStencilMargin && k >= kStencilMargin &&
           i < d.x - kStencilMargin && j < d.y - kStencilMargin && k < d.z - kStencilMargin;
  }
  // Linear indices of interior voxels satisfying pred(index, tool_sdf).
  template <typename Pred>
  VoxelList Select(Pred pred) const {
    VoxelList out;
    const Int3 d = phi.dims();
    for (int k = kStencilMargin; k < d.z - kStencilMargin; ++k) {
      for (int j = kStencilMargin; j < d.y - kStencilMargin; ++j) {
        for (int i = kStencilMargin; i < d.x - kStencilMargin; ++i) {
          const size_t idx = phi.Index(i, j, k);
          if (pred(idx, tool_sdf[idx])) out.push_back(static_cast<uint32_t>(idx));
        }
      }
    }
    return out;
  }
  // Select for predicates that hold only where the tool distance is at most `limit`: scans the
  // part of the interior `near` bounds (the whole interior when `limit` is beyond near.limit),
  // in the same order, so the list is the one Select returns.
  template <typename Pred>
  VoxelList SelectNear(double limit, Pred pred) const {
    if (!(limit <= near.limit)) return Select(pred);
    VoxelList out;
    const Int3 d = phi.dims();
    const int dims[3] = {d.x, d.y, d.z};
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(kStencilMargin, near.lo[a]);
      hi[a] = std::min(dims[a] - kStencilMargin, near.hi[a]);
    }
    for (int k = lo[2]; k < hi[2]; ++k) {
      for (int j = lo[1]; j < hi[1]; ++j) {
        for (int i = lo[0]; i < hi[0]; ++i) {
          const size_t idx = phi.Index(i, j, k);
          if (pred(idx, tool_sdf[idx])) out.push_back(static_cast<uint32_t>(idx));
        }
      }
    }
    return out;
  }
  // Block-local box [lo, hi) of the voxels whose bits differ from `before` (empty: lo >= hi).
  // Every pass below that only needs the voxels the edit changed (clamps, the inside sum, the
  // islands' seeds, the write-back) visits this box instead of the block: a press changes one
  // voxel in ten of its block. Rows are compared whole, so finding it costs a fraction of a pass.
  NearBox Changed() const {
    NearBox c;
    const Int3 d = phi.dims();
    const float* now = phi.data().data();
    const float* was = before.data().data();
    const size_t row_bytes = static_cast<size_t>(d.x) * sizeof(float);
    for (int k = 0; k < d.z; ++k) {
      for (int j = 0; j < d.y; ++j) {
        const size_t row = phi.Index(0, j, k);
        if (std::memcmp(now + row, was + row, row_bytes) == 0) continue;
        auto same = [&](int i) {
          uint32_t a, w;
          std::memcpy(&a, now + row + i, sizeof a);
          std::memcpy(&w, was + row + i, sizeof w);
          return a == w;
        };
        int i0 = 0, i1 = d.x - 1;
        while (same(i0)) ++i0;
        while (same(i1)) --i1;
        c.AddRow(i0, i1, j, k);
      }
    }
    return c;
  }
  // Clamps to the band. Voxels outside Changed() hold their extracted values, which need no
  // clamp when all of them were within the band (before_in_band).
  void ClampToBand() {
    if (!before_in_band) {
      for (float& v : phi.data()) v = std::clamp(v, -bg, bg);
      return;
    }
    const NearBox c = Changed();
    float* p = phi.data().data();
    for (int k = c.lo[2]; k < c.hi[2]; ++k) {
      for (int j = c.lo[1]; j < c.hi[1]; ++j) {
        float* row = p + phi.Index(0, j, k);
        for (int i = c.lo[0]; i < c.hi[0]; ++i) row[i] = std::clamp(row[i], -bg, bg);
      }
    }
  }
  // Change of the inside-voxel count since extraction: only voxels that changed contribute, so
  // the tracked volume stays exact without summing the block. They are added in index order.
  double InsideChange() const { return InsideChange(Changed()); }
  double InsideChange(const NearBox& c) const {
    double sum = 0;
    const float* now = phi.data().data();
    const float* was = before.data().data();
    const size_t row_bytes = static_cast<size_t>(phi.dims().x) * sizeof(float);
    for (int k = c.lo[2]; k < c.hi[2]; ++k) {
      for (int j = c.lo[1]; j < c.hi[1]; ++j) {
        const size_t row = phi.Index(0, j, k);
        if (std::memcmp(now + row, was + row, row_bytes) == 0) continue;
        for (int i = c.lo[0]; i < c.hi[0]; ++i) {
          const size_t idx = row + i;
          if (now[idx] != was[idx]) {
            sum += InsideFraction(now[idx], eps) - InsideFraction(was[idx], eps);
          }
        }
      }
    }
    return sum;
  }
};

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

// The tool's signed distance (world units) at the voxels of the block within `margin` of the
// tool's bounds; +max elsewhere, where no operator reads a finite value. Written into `f`
// (resized to the block); `near` gets the range of the voxels at most near->limit away. Spheres
// and capsules, the tools strokes use, skip the generic dispatch: this loop is a hot spot of
// every edit.
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

std::vector<float> ToolField(const Block& b, const ToolShape& tool,
                             double margin = std::numeric_limits<double>::infinity()) {
  std::vector<float> f;
  NearBox unused;
  ToolFieldInto(b, tool, margin, f, &unused);
  return f;
}

// What a batch's block must hold beyond its tools: the compensation shell and the operators'
// rim. One function for ApplyEdits and FootprintOf, which must agree exactly (a replica decides
// from the footprint whether it can replay an edit).
struct BlockPlan {
  double scale = 0;  // largest tool scale of the batch
  bool compensate = false;
  double shell_outer = 0;
  double reach = 0;
};

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
            2 * dx + (kind == EditKind::kAdd || kind == EditKind::kSubtract ? impl.background() : 0);
  // The surface moves at most to the tool's rim (2 voxels); the band around it, which the
  // band repair rebuilds, must lie inside the written interior.
  p.reach = std::max(p.reach, impl.background() + 2 * dx);
  return p;
}

// The index box around every tool of a batch, grown by `reach` and the stencil pad.
internal::IndexBox BlockBox(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs,
                            double reach) {
  Aabb tb = ToolBounds(reqs.front().tool);
  for (const EditRequest& r : reqs) {
    const Aabb a = ToolBounds(r.tool);
    tb.min = {std::min(tb.min.x, a.min.x), std::min(tb.min.y, a.min.y),
              std::min(tb.min.z, a.min.z)};
    tb.max = {std::max(tb.max.x, a.max.x), std::max(tb.max.y, a.max.y),
              std::max(tb.max.z, a.max.z)};
  }
  const Vec3 r{reach, reach, reach};
  return internal::WorldToIndexBox(tb.min - r, tb.max + r, impl.dx(), kBlockPad);
}

// One block around every tool of a batch; tool_sdf is the union of the tools (their minimum).
// Every operator and selection compares the field with thresholds no larger than
// `field_reach` (and the CSG operators see no difference between a distance beyond the band
// and +max), so the exact-distance tools are evaluated only within max(field_reach, band) of
// their bounds.
Block MakeBlock(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs, double reach,
                double field_reach) {
  Block b;
  b.dx = impl.dx();
  b.bg = impl.background();
  b.eps = 1.5 * b.dx;
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
    Aabb tb = ToolBounds(reqs.front().tool);
    for (const EditRequest& q : reqs) {
      const Aabb a = ToolBounds(q.tool);
      tb.min = {std::min(tb.min.x, a.min.x), std::min(tb.min.y, a.min.y),
                std::min(tb.min.z, a.min.z)};
      tb.max = {std::max(tb.max.x, a.max.x), std::max(tb.max.y, a.max.y),
                std::max(tb.max.z, a.max.z)};
    }
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

// Writes the block's changed voxels into the grid, grows the cached bounds, and updates the
// tracked volume from the changed voxels alone.
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

bool GammaHoldsMaterial(const Block& b, const VoxelList& gamma) {
  for (uint32_t idx : gamma) {
    if (b.phi.data()[idx] <= 0.f) return true;
  }
  return false;
}

// Grows the band of the block's field out to `limit` (world units) by fast marching from the
// voxels inside it, so that an offset by up to limit - background still finds distances where
// the band had clamped them (an inflate or deflate by more than the band's half-width would
// otherwise read a flat +-background and move nothing there). Only voxels off the band within
// two voxels of the tool take part (the offset reads no others) and take their distance; the
// band itself is kept as it is.
void ExtendBand(Block& b, double limit) {
  std::vector<MarchState> state(b.phi.size(), MarchState::kKnown);
  const auto& data = b.phi.data();
  const double near_tool = 2 * b.dx;
  for (size_t idx = 0; idx < data.size(); ++idx) {
    if (std::abs(data[idx]) < b.bg) continue;
    state[idx] = b.tool_sdf[idx] < near_tool ? MarchState::kFree : MarchState::kIgnored;
  }
  MarchDistance(b.phi, state, b.dx, limit);
}

// Material one sample thick along some direction (both neighbours outside, along an axis, a
// face diagonal or a body diagonal): a sheet or fibre the grid cannot resolve, which the next
// edit or the mesher turns into holes, tunnels and open edges, and around which no band has a
// unit gradient. Such voxels are emptied (repeatedly: emptying one can thin its neighbour) on
// the block's written interior. Returns the voxels emptied; `touched` marks them for the band
// repair.
size_t RemoveThinMaterial(Block& b, std::vector<uint8_t>& touched) {
  const Int3 d = b.phi.dims();
  auto& data = b.phi.data();
  const size_t stride[3] = {1, static_cast<size_t>(d.x), static_cast<size_t>(d.x) * d.y};
  // One offset per pair of opposite neighbours: the 13 directions of the 26-neighbourhood, each
  // with its length.
  ptrdiff_t dirs[13];
  double lengths[13];
  int nd = 0;
  for (int dk = -1; dk <= 1; ++dk) {
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        const ptrdiff_t o =
            di + dj * static_cast<ptrdiff_t>(stride[1]) + dk * static_cast<ptrdiff_t>(stride[2]);
        if (o <= 0) continue;
        dirs[nd] = o;
        lengths[nd++] = b.dx * std::sqrt(static_cast<double>(di * di + dj * dj + dk * dk));
      }
    }
  }
  auto thin = [&](size_t idx) {
    if (!(data[idx] < 0.f)) return false;
    for (int n = 0; n < nd; ++n) {
      if (ThinMaterialThickness(data[idx], data[idx - dirs[n]], data[idx + dirs[n]], lengths[n]) <
          b.dx) {
        return true;
      }
    }
    return false;
  };
  std::vector<uint32_t> work;
  for (int k = kStencilMargin; k < d.z - kStencilMargin; ++k) {
    for (int j = kStencilMargin; j < d.y - kStencilMargin; ++j) {
      for (int i = kStencilMargin; i < d.x - kStencilMargin; ++i) {
        const size_t idx = b.phi.Index(i, j, k);
        if (data[idx] < 0.f && data[idx] > -b.bg && thin(idx)) {
          work.push_back(static_cast<uint32_t>(idx));
        }
      }
    }
  }
  size_t removed = 0;
  // Emptied just outside, so that the surface moves no further than the voxel's own depth (a
  // voxel the surface grazes stays where it was); the band repair then gives the neighbourhood
  // its distances.
  const float outside = static_cast<float>(1e-3 * b.dx);
  for (size_t w = 0; w < work.size(); ++w) {
    const size_t idx = work[w];
    if (!thin(idx)) continue;
    data[idx] = outside;
    touched[idx] = 1;
    ++removed;
    const int c[3] = {static_cast<int>(idx % d.x), static_cast<int>((idx / d.x) % d.y),
                      static_cast<int>(idx / stride[2])};
    for (int dk = -1; dk <= 1; ++dk) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          if (!b.Interior(c[0] + di, c[1] + dj, c[2] + dk)) continue;
          const size_t nb = b.phi.Index(c[0] + di, c[1] + dj, c[2] + dk);
          if (thin(nb)) work.push_back(static_cast<uint32_t>(nb));
        }
      }
    }
  }
  return removed;
}

// |grad phi| as the slope of steepest descent: the largest |phi(n) - phi(v)| / |n - v| over the
// 26 neighbours (invariants.h explains why not a one-sided norm).
float SteepestSlope(const float* p, size_t idx, const ptrdiff_t offsets[26],
                    const float inv_lengths[26]) {
  const float v = p[idx];
  float g = 0.f;
  for (int n = 0; n < 26; ++n) g = std::max(g, std::abs(p[idx + offsets[n]] - v) * inv_lengths[n]);
  return g;
}

// Keeps the narrow band valid where the edit left it broken: an interface voxel with a voxel at
// the band's edge among its 26 neighbours (the zero crossing about to leave the band, the source
// of the holes inflate left), or a band voxel whose |grad phi| is far from one, marks its
// surroundings (the band's half-width plus one voxel) for rebuilding. There the voxels that
// bracket the interface take their Russo-Smereka distance (the crossing stays where it is) and
// every other voxel its distance by fast marching. Voxels `touched` marks are rebuilt too.
// Returns the number of voxels rebuilt.
size_t RepairBand(Block& b, const std::vector<uint8_t>& touched) {
  const Int3 d = b.phi.dims();
  const size_t n = b.phi.size();
  auto& data = b.phi.data();
  const float* p = data.data();
  const size_t stride[3] = {1, static_cast<size_t>(d.x), static_cast<size_t>(d.x) * d.y};
  const float bg = b.bg;
  const float band_inner = static_cast<float>(b.bg - b.dx);
  ptrdiff_t offsets[26];
  float inv_lengths[26];
  int no = 0;
  for (int dk = -1; dk <= 1; ++dk) {
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        if (!di && !dj && !dk) continue;
        offsets[no] =
            di + dj * static_cast<ptrdiff_t>(stride[1]) + dk * static_cast<ptrdiff_t>(stride[2]);
        inv_lengths[no++] = static_cast<float>(
            1.0 / (b.dx * std::sqrt(static_cast<double>(di * di + dj * dj + dk * dk))));
      }
    }
  }
  std::vector<uint8_t> bad(n, 0);
  size_t nbad = 0;
  for (int k = kStencilMargin; k < d.z - kStencilMargin; ++k) {
    for (int j = kStencilMargin; j < d.y - kStencilMargin; ++j) {
      for (int i = kStencilMargin; i < d.x - kStencilMargin; ++i) {
        const size_t idx = b.phi.Index(i, j, k);
        if (touched[idx]) {
          bad[idx] = 1;
          ++nbad;
          continue;
        }
        const float v = p[idx];
        const bool inside = v < 0.f;
        bool interface = false;
        for (int a = 0; a < 3 && !interface; ++a) {
          interface = (p[idx - stride[a]] < 0.f) != inside || (p[idx + stride[a]] < 0.f) != inside;
        }
        if (!interface && !(std::abs(v) < band_inner)) continue;
        bool broken = false;
        if (interface) {
          for (int dk = -1; dk <= 1 && !broken; ++dk) {
            for (int dj = -1; dj <= 1 && !broken; ++dj) {
              for (int di = -1; di <= 1 && !broken; ++di) {
                const float w = p[b.phi.Index(i + di, j + dj, k + dk)];
                broken = !(std::abs(w) < bg);
              }
            }
          }
        }
        if (!broken && std::abs(v) < band_inner) {
          const float g = SteepestSlope(p, idx, offsets, inv_lengths);
          broken = g < 0.6f || g > 1.4f;
        }
        if (broken) {
          bad[idx] = 1;
          ++nbad;
        }
      }
    }
  }
  if (nbad == 0) return 0;
  // The region: bad voxels dilated by the half-width plus one voxel (a box filter per axis),
  // kept to the written interior.
  const int reach = static_cast<int>(std::ceil(b.bg / b.dx)) + 1;
  std::vector<uint8_t> region = bad;
  std::vector<uint8_t> tmp(n);
  const int dims[3] = {d.x, d.y, d.z};
  for (int a = 0; a < 3; ++a) {
    tmp.assign(n, 0);
    for (size_t idx = 0; idx < n; ++idx) {
      if (!region[idx]) continue;
      const int c = static_cast<int>(a == 0   ? idx % d.x
                                     : a == 1 ? (idx / d.x) % d.y
                                              : idx / stride[2]);
      const int lo = std::max(0, c - reach), hi = std::min(dims[a] - 1, c + reach);
      for (int cc = lo; cc <= hi; ++cc) tmp[idx + (cc - c) * static_cast<ptrdiff_t>(stride[a])] = 1;
    }
    region.swap(tmp);
  }
  std::vector<MarchState> state(n, MarchState::kKnown);
  std::vector<std::pair<uint32_t, float>> interface_values;
  size_t rebuilt = 0;
  for (int k = kStencilMargin; k < d.z - kStencilMargin; ++k) {
    for (int j = kStencilMargin; j < d.y - kStencilMargin; ++j) {
      for (int i = kStencilMargin; i < d.x - kStencilMargin; ++i) {
        const size_t idx = b.phi.Index(i, j, k);
        if (!region[idx]) continue;
        ++rebuilt;
        const float v = p[idx];
        const bool inside = v < 0.f;
        bool interface = false;
        for (int a = 0; a < 3 && !interface; ++a) {
          interface = (p[idx - stride[a]] < 0.f) != inside || (p[idx + stride[a]] < 0.f) != inside;
        }
        if (interface) {
          interface_values.push_back({static_cast<uint32_t>(idx),
                                      static_cast<float>(InterfaceDistance(b.phi, i, j, k, b.dx))});
        } else {
          state[idx] = MarchState::kFree;
        }
      }
    }
  }
  // Each interface voxel's distance comes from its own axis crossings, so two voxels across the
  // surface along a diagonal can claim more distance between them than the diagonal is long (a
  // cliff the next round would find again). The surface crosses the segment between them, so
  // |D(v)| + |D(n)| is at most its length: scale such pairs down together, which keeps the
  // crossing on the segment where it was. Two Jacobi passes settle the corners seen here.
  std::vector<float> next(data.size());
  for (int pass = 0; pass < 2; ++pass) {
    std::copy(data.begin(), data.end(), next.begin());
    for (auto& [idx, v] : interface_values) next[idx] = v;
    for (auto& [idx, v] : interface_values) {
      const bool inside = v < 0.f;
      float f = 1.f;
      for (int o = 0; o < 26; ++o) {
        const float w = next[idx + offsets[o]];
        if ((w < 0.f) == inside) continue;
        const float sum = (std::abs(v) + std::abs(w)) * inv_lengths[o];
        if (sum > 1.f) f = std::min(f, 1.f / sum);
      }
      v *= f;
    }
  }
  // All interface distances are read from the field before any is written.
  for (const auto& [idx, v] : interface_values) data[idx] = v;
  MarchDistance(b.phi, state, b.dx, b.bg);
  return rebuilt;
}

// Empties material thinner than a voxel and repairs the band where it is broken, so that
// nothing the edit leaves behind is a sliver or a torn band. The band repair changes distances,
// by which thinness is judged, so the two alternate until neither has anything left to do (a
// rebuilt interface voxel takes its distance from its neighbours' old values: next to a
// voxel-scale corner a second round settles the pair across the surface). Where they keep
// trading (a groove whose corners sit between samples) the rounds are bounded and a last pass
// empties what the last repair thinned, so no sliver survives either way. Unless
// `always_repair` (inflate and deflate, which rewrite the band wholesale), the band is repaired
// only where something was emptied or marked in `repair`: after a press, a smooth or a CSG
// edit the reinitialisation has already straightened it, and scanning the block for a torn
// band would cost more than the edit. Returns whether anything changed.
bool Resolve(Block& b, std::vector<uint8_t>& repair, bool always_repair) {
  bool changed = false;
  bool settled = false;
  for (int round = 0; round < kBandRepairRounds && !settled; ++round) {
    const size_t thin = RemoveThinMaterial(b, repair);
    if (round == 0 && !always_repair && thin == 0 &&
        std::find(repair.begin(), repair.end(), uint8_t{1}) == repair.end()) {
      settled = true;
      break;
    }
    const size_t rebuilt = RepairBand(b, repair);
    std::fill(repair.begin(), repair.end(), 0);
    settled = thin == 0 && rebuilt == 0;
    changed = changed || !settled;
  }
  if (!settled) {
    changed = RemoveThinMaterial(b, repair) > 0 || changed;
    std::fill(repair.begin(), repair.end(), 0);
  }
  b.ClampToBand();
  return changed;
}

struct IslandReport {
  int found = 0;    // pieces of at least one voxel (smaller ones are below the grid's resolution)
  int removed = 0;  // pieces removed (material) or pockets filled (air)
  double inside_change = 0;  // change of the block's inside-voxel sum by the removals
  VoxelList zone;            // voxels reset by a removal or a fill (to be reinitialised)
  VoxelList flipped;         // voxels of the pieces removed (now of the other phase)
};

// The voxels of the block's interior whose phase (material, phi < 0, or air) differs from the
// extracted field's, in index order. Only the changed box is scanned, with the coordinates
// from the loops (no division per voxel).
VoxelList PhaseChanges(const Block& b) {
  VoxelList out;
  const Int3 d = b.phi.dims();
  const float* now = b.phi.data().data();
  const float* was = b.before.data().data();
  const NearBox changed = b.Changed();
  const int lo[3] = {std::max(kStencilMargin, changed.lo[0]),
                     std::max(kStencilMargin, changed.lo[1]),
                     std::max(kStencilMargin, changed.lo[2])};
  const int hi[3] = {std::min(d.x - kStencilMargin, changed.hi[0]),
                     std::min(d.y - kStencilMargin, changed.hi[1]),
                     std::min(d.z - kStencilMargin, changed.hi[2])};
  const size_t row_bytes = static_cast<size_t>(d.x) * sizeof(float);
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      const size_t row = b.phi.Index(0, j, k);
      // Most rows of the box did not change at all (a press changes one voxel in ten).
      if (std::memcmp(now + row, was + row, row_bytes) == 0) continue;
      // Most changed rows keep every sign (the compensation shell moves values by a fraction
      // of a voxel): a branch-free test, which vectorises, skips them.
      unsigned flips = 0;
      for (int i = lo[0]; i < hi[0]; ++i) {
        flips |=
            static_cast<unsigned>(now[row + i] < 0.f) ^ static_cast<unsigned>(was[row + i] < 0.f);
      }
      if (flips == 0) continue;
      for (int i = lo[0]; i < hi[0]; ++i) {
        if ((now[row + i] < 0.f) != (was[row + i] < 0.f)) {
          out.push_back(static_cast<uint32_t>(row + i));
        }
      }
    }
  }
  return out;
}

// Pieces of one phase that this edit cut off inside the block: pieces of material
// (`kAir` false), which are removed, or pockets of air sealed inside the material (`kAir`
// true), which are filled. A piece that lies wholly inside the block's interior is cut off
// from anything reaching outside it: any path to the rest of its phase would cross the border.
// Both phases are connected through the 6 face neighbours only. The mesh (volumeToMesh) puts
// two samples of material that touch across an edge or a corner of their cell, with air on the
// other diagonal, on separate sheets, so a speck joined to the clay only diagonally is a piece
// of its own to a viewer (the demo kept such specks when the search followed 26 neighbours);
// and air joined only diagonally may be sealed there just as well. Searching 6-pieces finds
// every piece the mesh can show, each whole or as the 6-pieces it is made of.
template <bool kAir>
IslandReport FindPieces(Block& b, const EditSettings& s, const VoxelList& flipped) {
  IslandReport rep;
  const Int3 d = b.phi.dims();
  const size_t n = b.phi.size();
  auto& data = b.phi.data();
  // The phase searched: material is phi < 0, air everything else (a zero sample is air).
  auto in = [](float v) { return kAir ? !(v < 0.f) : v < 0.f; };
  const int64_t sx = 1, sy = d.x, sz = static_cast<int64_t>(d.x) * d.y;
  const int64_t offsets[6] = {-sx, sx, -sy, sy, -sz, sz};
  constexpr int no = 6;
  // Block indices fit 32 bits (VoxelList): 32-bit divisions cost a fraction of 64-bit ones.
  const uint32_t ux = static_cast<uint32_t>(d.x), uy = static_cast<uint32_t>(d.y);
  auto coords = [&](size_t idx, int& i, int& j, int& k) {
    const uint32_t u = static_cast<uint32_t>(idx);
    const uint32_t row = u / ux;
    i = static_cast<int>(u - row * ux);
    j = static_cast<int>(row % uy);
    k = static_cast<int>(row / uy);
  };
  // A piece of the phase can only be new if it holds a voxel the edit brought into the phase
  // (material the compensation shell grew into the air, air a press opened) or touches one the
  // edit took out of it (material a press emptied, air a bulge filled): the search starts from
  // those, and each search walks best-first towards the nearest border. On the main body or
  // the open air it reaches the stencil margin in a few dozen steps, and only a piece that is
  // really cut off is explored whole. A piece reaching the margin is not known to be cut off
  // (and its margin voxels are not written back).
  enum : uint8_t { kUnknown = 0, kConnected = 1, kQueued = 2, kIsland = 3 };
  std::vector<uint8_t> state(n, kUnknown);
  // Material on the border: the block does not hold the whole object (for air, which always
  // reaches beyond the object, there is no such case). The first such voxel decides, usually
  // within the first rows.
  bool any_border = kAir;
  for (int k = 0; k < d.z && !any_border; ++k) {
    for (int j = 0; j < d.y && !any_border; ++j) {
      const bool row_interior = j >= kStencilMargin && k >= kStencilMargin &&
                                j < d.y - kStencilMargin && k < d.z - kStencilMargin;
      const float* row = &data[b.phi.Index(0, j, k)];
      for (int i = 0; i < d.x; ++i) {
        if (row_interior && i >= kStencilMargin && i < d.x - kStencilMargin) continue;
        if (row[i] < 0.f) {
          any_border = true;
          break;
        }
      }
    }
  }
  std::vector<uint32_t> seeds;
  for (uint32_t idx : flipped) {
    if (in(data[idx])) {
      seeds.push_back(idx);  // brought into the phase
      continue;
    }
    // Taken out of the phase: its neighbours in the phase are seeds.
    for (int o = 0; o < no; ++o) {
      const size_t nidx = static_cast<size_t>(static_cast<int64_t>(idx) + offsets[o]);
      if (in(data[nidx])) seeds.push_back(static_cast<uint32_t>(nidx));
    }
  }
  if (seeds.empty()) return rep;
  auto border_distance = [&](size_t idx) {
    int i, j, k;
    coords(idx, i, j, k);
    return std::min({i, j, k, d.x - 1 - i, d.y - 1 - j, d.z - 1 - k});
  };
  struct Piece {
    double volume = 0;  // voxels of the phase (inside fractions for material, outside for air)
    std::vector<uint32_t> voxels;
  };
  std::vector<Piece> pieces;
  std::vector<uint32_t> visited;
  using Entry = std::pair<int, uint32_t>;  // (border distance, index), smallest first
  std::vector<Entry> heap;
  auto cmp = [](const Entry& a, const Entry& c) { return a > c; };
  for (uint32_t seed : seeds) {
    if (state[seed] != kUnknown) continue;
    // Most seeds lie beside one an earlier search found connected (the voxels of one dent):
    // they are settled without a search.
    bool beside_connected = false;
    for (int o = 0; o < no && !beside_connected; ++o) {
      const size_t nidx = static_cast<size_t>(static_cast<int64_t>(seed) + offsets[o]);
      beside_connected = state[nidx] == kConnected;
    }
    if (beside_connected) {
      state[seed] = kConnected;
      continue;
    }
    visited.clear();
    heap.clear();
    state[seed] = kQueued;
    visited.push_back(seed);
    heap.push_back({border_distance(seed), seed});
    bool connected = false;
    while (!heap.empty()) {
      std::pop_heap(heap.begin(), heap.end(), cmp);
      const uint32_t idx = heap.back().second;
      heap.pop_back();
      int i, j, k;
      coords(idx, i, j, k);
      if (!b.Interior(i, j, k)) {
        connected = true;
        break;
      }
      for (int o = 0; o < no; ++o) {
        const size_t nidx = static_cast<size_t>(static_cast<int64_t>(idx) + offsets[o]);
        if (!in(data[nidx])) continue;
        if (state[nidx] == kConnected) {
          connected = true;
          break;
        }
        if (state[nidx] == kUnknown) {
          state[nidx] = kQueued;
          visited.push_back(static_cast<uint32_t>(nidx));
          heap.push_back({border_distance(nidx), static_cast<uint32_t>(nidx)});
          std::push_heap(heap.begin(), heap.end(), cmp);
        }
      }
      if (connected) break;
    }
    if (connected) {
      for (uint32_t v : visited) state[v] = kConnected;
      continue;
    }
    Piece p;
    for (uint32_t v : visited) {
      state[v] = kIsland;
      const double f = InsideFraction(data[v], b.eps);
      p.volume += kAir ? 1.0 - f : f;
    }
    p.voxels = visited;
    pieces.push_back(std::move(p));
  }
  if (pieces.empty()) return rep;
  std::vector<int32_t> label(n, -1);
  for (size_t i = 0; i < pieces.size(); ++i) {
    for (uint32_t v : pieces[i].voxels) label[v] = static_cast<int32_t>(i);
  }
  size_t largest = 0;
  for (size_t i = 0; i < pieces.size(); ++i) {
    if (pieces[i].volume > pieces[largest].volume) largest = i;
  }
  std::vector<uint8_t> remove(pieces.size(), 0);
  for (size_t i = 0; i < pieces.size(); ++i) {
    if (!any_border && i == largest) continue;  // the whole object is in the block
    // Specks and pockets below one voxel are below the grid's resolution (sub-voxel debris a
    // press leaves on a ridge, a sample the bulge of the compensation shell sealed): handled
    // under kRemoveSmall like any small piece, not reported.
    if (pieces[i].volume >= 1.0) ++rep.found;
    const double vol = pieces[i].volume * b.dx * b.dx * b.dx;
    if (s.islands == IslandPolicy::kRemoveSmall && vol < s.min_island_volume) {
      remove[i] = 1;
      ++rep.removed;
    }
  }
  if (rep.removed == 0) return rep;
  // Distances (in 6-steps, capped) to the phase that stays and to the removed pieces: the band
  // of a removed piece is reset only where it is nearer to it than to what stays.
  const int hw = static_cast<int>(std::ceil(b.bg / b.dx)) + 1;
  auto distance_from = [&](auto is_source) {
    std::vector<int16_t> dist(n, static_cast<int16_t>(hw + 1));
    std::vector<uint32_t> queue;
    for (size_t idx = 0; idx < n; ++idx) {
      if (is_source(idx)) {
        dist[idx] = 0;
        queue.push_back(static_cast<uint32_t>(idx));
      }
    }
    for (size_t q = 0; q < queue.size(); ++q) {
      const uint32_t idx = queue[q];
      if (dist[idx] >= hw) continue;
      int i, j, k;
      coords(idx, i, j, k);
      const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
      for (const auto& o : nb) {
        const int ii = i + o[0], jj = j + o[1], kk = k + o[2];
        if (!b.phi.Contains(ii, jj, kk)) continue;
        const size_t nidx = b.phi.Index(ii, jj, kk);
        if (dist[nidx] > dist[idx] + 1) {
          dist[nidx] = static_cast<int16_t>(dist[idx] + 1);
          queue.push_back(static_cast<uint32_t>(nidx));
        }
      }
    }
    return dist;
  };
  const std::vector<int16_t> dist = distance_from(
      [&](size_t idx) { return in(data[idx]) && (label[idx] < 0 || !remove[label[idx]]); });
  const std::vector<int16_t> dist_removed = distance_from(
      [&](size_t idx) { return in(data[idx]) && label[idx] >= 0 && remove[label[idx]]; });
  const double inside_before = b.InsideChange();
  // A removed piece takes the other phase's sign: positive distances where material goes,
  // negative where a pocket is filled.
  const float sign = kAir ? -1.f : 1.f;
  for (size_t i = 0; i < pieces.size(); ++i) {
    if (!remove[i]) continue;
    rep.flipped.insert(rep.flipped.end(), pieces[i].voxels.begin(), pieces[i].voxels.end());
    for (uint32_t idx : pieces[i].voxels) {
      // Near what stays, start from the (over-estimated) step distance and let the
      // reinitialisation settle it.
      if (dist[idx] <= hw) {
        data[idx] = sign * std::min(b.bg, static_cast<float>(dist[idx] * b.dx));
        int i, j, k;
        coords(idx, i, j, k);
        if (b.Interior(i, j, k)) rep.zone.push_back(idx);
      } else {
        data[idx] = sign * b.bg;
      }
    }
  }
  // Reset the other side of the removed surfaces, and collect what needs reinitialising.
  for (int k = kStencilMargin; k < d.z - kStencilMargin; ++k) {
    for (int j = kStencilMargin; j < d.y - kStencilMargin; ++j) {
      for (int i = kStencilMargin; i < d.x - kStencilMargin; ++i) {
        const size_t idx = b.phi.Index(i, j, k);
        if (dist_removed[idx] > hw || in(data[idx]) || !(std::abs(data[idx]) < b.bg)) continue;
        if (dist[idx] > hw) {
          data[idx] = sign * b.bg;
        } else {
          rep.zone.push_back(static_cast<uint32_t>(idx));
        }
      }
    }
  }
  rep.inside_change = b.InsideChange() - inside_before;
  return rep;
}

// Weight of the compensation shell: zero inside the tool and a gap of 1.5 voxels around it (so
// the restored volume does not grow back into the tool), one across the shell, zero again at its
// outer edge, with 2-voxel smooth ramps so the bulge has no step.
float ShellWeight(double s, double gap, double outer, double dx) {
  auto smooth = [](double t) {
    t = std::clamp(t, 0.0, 1.0);
    return t * t * (3 - 2 * t);
  };
  if (s <= gap || s >= outer) return 0.f;
  return static_cast<float>(smooth((s - gap) / (2 * dx)) * smooth((outer - s) / (2 * dx)));
}

struct CompensationOutcome {
  int iterations = 0;
  int substeps = 0;
  bool failed = false;
};

// Shell compensation inside the block. `base_volume` is the tracked volume before the edit, so
// Vol = base_volume + (change of the block's inside count) dx^3, exactly as the tracked volume.
// The shell and its weights depend on the tools' field alone, which the passes of one edit share.
struct ShellCache {
  bool ready = false;
  VoxelList shell;
  std::vector<float> w;
};

CompensationOutcome CompensateShell(Block& b, double target, double base_volume,
                                    double shell_outer, const EditSettings& s, ShellCache& cache) {
  CompensationOutcome out;
  const double dx3 = b.dx * b.dx * b.dx;
  // Every shell voxel moves (offsetting only the band would leave a growing step at its
  // edge), but only band voxels can change their inside fraction by a sub-band offset, so the
  // volume and area sums run over those alone. Weights are kept beside the lists (w[n] for
  // shell[n], band_w[m] for shell_band[m]), not in a block-sized field.
  if (!cache.ready) {
    cache.shell = b.SelectNear(shell_outer,
                               [&](size_t, float t) { return t > 1.5 * b.dx && t < shell_outer; });
    cache.w.resize(cache.shell.size());
    for (size_t n = 0; n < cache.shell.size(); ++n) {
      cache.w[n] = ShellWeight(b.tool_sdf[cache.shell[n]], 1.5 * b.dx, shell_outer, b.dx);
    }
    cache.ready = true;
  }
  const VoxelList& shell = cache.shell;
  const std::vector<float>& w = cache.w;
  // in_band[n]: shell[n] is one of the band voxels the sums run over, which keep their order.
  std::vector<uint8_t> in_band(shell.size());
  for (size_t n = 0; n < shell.size(); ++n) {
    in_band[n] = std::abs(b.phi.data()[shell[n]]) < b.bg;
  }
  const double tol = s.compensation_tolerance_voxels * b.dx * b.dx * b.dx;
  // Only shell voxels change here, so the block's inside sum moves by their change alone. The
  // inside sum and the weighted smoothed area (seed 000 eq. 5.7 delta) of the band voxels, in
  // shell order: computed once here and then by each Newton step while it moves the voxels, so
  // an iteration is one pass over the shell.
  double sum = 0, area = 0;
  auto add_sums = [&](size_t n, float v) {
    sum += InsideFraction(v, b.eps);
    area += w[n] * SmoothedDelta(v, b.eps) * dx3;
  };
  for (size_t n = 0; n < shell.size(); ++n) {
    if (in_band[n]) add_sums(n, b.phi.data()[shell[n]]);
  }
  auto recompute_sums = [&] {
    sum = area = 0;
    for (size_t n = 0; n < shell.size(); ++n) {
      if (in_band[n]) add_sums(n, b.phi.data()[shell[n]]);
    }
  };
  const double change0 = b.InsideChange();
  const double shell_sum0 = sum;
  for (int it = 0; it < s.max_compensation_iterations; ++it) {
    const double vol = base_volume + (change0 - shell_sum0 + sum) * dx3;
    const double err = target - vol;
    if (std::abs(err) <= tol) break;
    if (area < 1e-9 * b.dx * b.dx) {
      out.failed = true;
      break;
    }
    const double d = err / area;  // Newton step along the normal, world units (digest §3.3)
    ++out.iterations;
    switch (s.compensation_method) {
      case CompensationMethod::kNewton: {
        // A normal offset of a signed distance field is phi - d (|grad phi| = 1), weighted by
        // the shell; no stencil, so an iteration costs one pass over the shell. Never move more
        // than the band can represent in one go; the next iteration continues.
        const double limit = 0.5 * b.bg;
        const float step = static_cast<float>(std::clamp(d, -limit, limit));
        sum = area = 0;
        for (size_t n = 0; n < shell.size(); ++n) {
          float& v = b.phi.data()[shell[n]];
          v = std::clamp(v - step * w[n], -b.bg, b.bg);
          if (in_band[n]) add_sums(n, v);
        }
        ++out.substeps;
        continue;  // clamped already, sums up to date
      }
      case CompensationMethod::kGradientDescentGrad: {
        // Eq. 5.8 with the digest's sign: phi += tau (Vol - c) |grad phi| chi; tau scaled so the
        // step is gradient_descent_dt Newton steps (a proportional controller).
        const double step = s.gradient_descent_dt * d;
        std::vector<float> speed(b.phi.size(), 0.f);
        for (size_t n = 0; n < shell.size(); ++n) {
          speed[shell[n]] = static_cast<float>(step * w[n]);
        }
        NormalMotionStep(b.phi, speed, shell, 1.0, b.dx, s.motion);
        ++out.substeps;
        break;
      }
      case CompensationMethod::kGradientDescentDelta: {
        // Eq. 5.6 with the digest's sign: phi += tau (Vol - c) delta_eps(phi) chi.
        const double tau = s.gradient_descent_dt * d * b.eps;
        for (size_t n = 0; n < shell.size(); ++n) {
          float& v = b.phi.data()[shell[n]];
          v = static_cast<float>(v - tau * SmoothedDelta(v, b.eps) * w[n]);
        }
        ++out.substeps;
        break;
      }
    }
    // Only shell voxels moved, and the block was within the band when this began.
    for (uint32_t idx : shell) {
      float& v = b.phi.data()[idx];
      v = std::clamp(v, -b.bg, b.bg);
    }
    recompute_sums();
  }
  return out;
}

Status ValidateToolFor(const Sculpture& sc, const ToolShape& tool, const EditSettings& s) {
  const double dx = sc.voxel_size();
  SCULPT_RETURN_IF_ERROR(
      levelset::ValidateTool(tool, s.min_tool_voxels * dx, s.max_tool_voxels * dx));
  if (tool.kind == ToolKind::kCapsule) {
    SCULPT_RETURN_IF_ERROR(CheckRange("tool.length", (tool.end - tool.center).Length(), 0,
                                      4 * s.max_tool_voxels * dx));
  }
  return Status::Ok();
}

}  // namespace

const char* EditKindName(EditKind kind) {
  switch (kind) {
    case EditKind::kPress: return "press";
    case EditKind::kAdd: return "add";
    case EditKind::kSubtract: return "subtract";
    case EditKind::kSmooth: return "smooth";
    case EditKind::kInflate: return "inflate";
    case EditKind::kDeflate: return "deflate";
  }
  return "unknown";
}

Status ValidateEditSettings(const EditSettings& s) {
  SCULPT_RETURN_IF_ERROR(CheckRange("cfl", s.cfl, 0.05, 0.9));
  SCULPT_RETURN_IF_ERROR(CheckRange("shell_radii", s.shell_radii, 0.25, 8));
  SCULPT_RETURN_IF_ERROR(
      CheckRange("compensation_tolerance_voxels", s.compensation_tolerance_voxels, 1e-6, 1e6));
  SCULPT_RETURN_IF_ERROR(CheckRange("max_compensation_iterations",
                                    s.max_compensation_iterations, 0, 1000));
  SCULPT_RETURN_IF_ERROR(CheckRange("gradient_descent_dt", s.gradient_descent_dt, 1e-4, 4));
  SCULPT_RETURN_IF_ERROR(CheckRange("reinit_eikonal_threshold", s.reinit_eikonal_threshold, 0, 10));
  SCULPT_RETURN_IF_ERROR(CheckRange("reinit_every_k", s.reinit_every_k, 0, 1e6));
  SCULPT_RETURN_IF_ERROR(CheckRange("reinit_iterations", s.reinit_iterations, 0, 100));
  SCULPT_RETURN_IF_ERROR(CheckRange("min_island_volume", s.min_island_volume, 0, 1e30));
  SCULPT_RETURN_IF_ERROR(CheckRange("min_tool_voxels", s.min_tool_voxels, 0.25, 1e3));
  SCULPT_RETURN_IF_ERROR(CheckRange("max_tool_voxels", s.max_tool_voxels, s.min_tool_voxels, 1e3));
  if (s.reinit_spatial == SpatialScheme::kCentral) {
    return Outside("reinit_spatial", "central", "{upwind, weno5}");
  }
  if (s.motion.spatial == SpatialScheme::kCentral) {
    return Outside("motion.spatial", "central",
                   "{upwind, weno5}: central differences with explicit time steps are unstable for "
                   "hyperbolic motion (seed 000 §4.3); use them only to reproduce the thesis");
  }
  return Status::Ok();
}

namespace {

// The request's own fields; `check_extent` adds the test against the object's extent, which a
// replica (holding only part of the object) cannot make and the server already made.
Status ValidateRequestFields(const Sculpture& sc, const EditRequest& r, const EditSettings& s,
                             bool check_extent);

}  // namespace

Status ValidateEditRequest(const Sculpture& sc, const EditRequest& r, const EditSettings& s) {
  return ValidateRequestFields(sc, r, s, true);
}

namespace {

Status ValidateRequestFields(const Sculpture& sc, const EditRequest& r, const EditSettings& s,
                             bool check_extent) {
  const int kind = static_cast<int>(r.kind);
  if (kind < 0 || kind > static_cast<int>(EditKind::kDeflate)) {
    return Outside("edit.kind", std::to_string(kind), "[0, 5]");
  }
  SCULPT_RETURN_IF_ERROR(ValidateToolFor(sc, r.tool, s));
  const double dx = sc.voxel_size();
  SCULPT_RETURN_IF_ERROR(CheckRange("edit.speed", r.speed, 0, s.max_speed_voxels * dx));
  SCULPT_RETURN_IF_ERROR(CheckRange("edit.dt", r.dt, 1e-6, 1e3));
  if (r.kind == EditKind::kInflate || r.kind == EditKind::kDeflate) {
    SCULPT_RETURN_IF_ERROR(CheckRange("edit.amount", r.amount, 0, s.max_amount_voxels * dx));
  }
  if (r.kind == EditKind::kSmooth) {
    SCULPT_RETURN_IF_ERROR(CheckRange("edit.amount", r.amount, 0, 100));
  }
  if (!check_extent) return Status::Ok();
  // A tool far larger than the whole object is a unit mistake, not an edit.
  const Aabb ob = sc.WorldBounds();
  const double extent = std::max({ob.max.x - ob.min.x, ob.max.y - ob.min.y, ob.max.z - ob.min.z,
                                  8 * dx});
  const double scale = ToolScale(r.tool);
  if (scale > 4 * extent) {
    return Outside("tool.size", Num(scale),
                   std::string("[") + Num(s.min_tool_voxels * dx) + ", " + Num(4 * extent) +
                       "] (4x the object's extent)");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<EditResult> ApplyEdit(Sculpture& sculpture, const EditRequest& req,
                               const EditSettings& s) {
  return ApplyEdits(sculpture, std::vector<EditRequest>{req}, s);
}

namespace {
StatusOr<EditResult> ApplyEditsImpl(Sculpture& sculpture, const std::vector<EditRequest>& reqs,
                                    const EditSettings& s, const ReplayState* replay);
}  // namespace

StatusOr<EditResult> ApplyEdits(Sculpture& sculpture, const std::vector<EditRequest>& reqs,
                                const EditSettings& s) {
  return ApplyEditsImpl(sculpture, reqs, s, nullptr);
}

StatusOr<EditResult> ReplayEdits(Sculpture& sculpture, const std::vector<EditRequest>& reqs,
                                 const EditSettings& s, const ReplayState& state) {
  return ApplyEditsImpl(sculpture, reqs, s, &state);
}

ReplayState CaptureReplayState(const Sculpture& sculpture) {
  const Sculpture::Impl& impl = sculpture.impl();
  return ReplayState{impl.volume, impl.reference_volume, impl.edits_since_reinit};
}

void RestoreReplayState(Sculpture& sculpture, const ReplayState& state) {
  Sculpture::Impl& impl = sculpture.impl();
  impl.volume = state.volume;
  impl.reference_volume = state.reference_volume;
  impl.edits_since_reinit = state.edits_since_reinit;
}

EditFootprint FootprintOf(const Sculpture& sculpture, const std::vector<EditRequest>& reqs,
                          const EditSettings& s) {
  EditFootprint f;
  if (reqs.empty()) return f;
  const Sculpture::Impl& impl = sculpture.impl();
  const BlockPlan plan = PlanBlock(impl, reqs, s);
  const internal::IndexBox box = BlockBox(impl, reqs, plan.reach);
  f.min = box.min;
  f.max = box.max;
  f.whole_object = plan.compensate && s.compensation == CompensationRegion::kGlobal;
  return f;
}

namespace {
StatusOr<EditResult> ApplyEditsImpl(Sculpture& sculpture, const std::vector<EditRequest>& reqs,
                                    const EditSettings& s, const ReplayState* replay) {
  SCULPT_RETURN_IF_ERROR(ValidateEditSettings(s));
  if (reqs.empty() || reqs.size() > kMaxEditsPerBatch) {
    return Outside("edits", std::to_string(reqs.size()),
                   std::string("[1, ") + std::to_string(kMaxEditsPerBatch) + "]");
  }
  for (size_t i = 0; i < reqs.size(); ++i) {
    SCULPT_RETURN_IF_ERROR(ValidateRequestFields(sculpture, reqs[i], s, replay == nullptr));
    if (reqs[i].kind != reqs.front().kind) {
      return Outside(std::string("edits[") + std::to_string(i) + "].kind",
                     EditKindName(reqs[i].kind),
                     std::string("{") + EditKindName(reqs.front().kind) + "} (one kind per batch)");
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  // Stage clock: each call charges the time since the previous one to `slot`.
  auto mark = t0;
  auto lap = [&mark](double& slot) {
    const auto now = std::chrono::steady_clock::now();
    slot += std::chrono::duration<double, std::milli>(now - mark).count();
    mark = now;
  };
  Sculpture::Impl& impl = sculpture.impl();
  if (replay) {
    // The scalars the server held before this edit: a replica holding part of the object, or
    // one resynchronised by leaf deltas, tracks different totals (seed 000 ch. 5 compensates
    // towards the reference volume, a global quantity).
    impl.volume = replay->volume;
    impl.reference_volume = replay->reference_volume;
    impl.edits_since_reinit = replay->edits_since_reinit;
  }
  EditResult res;
  res.volume_before = impl.volume;
  const double dx = impl.dx();
  const double dx3 = dx * dx * dx;
  const EditKind kind = reqs.front().kind;
  const BlockPlan plan = PlanBlock(impl, reqs, s);
  const double scale = plan.scale;
  const bool compensate = plan.compensate;
  const double shell_outer = plan.shell_outer;
  const double reach = plan.reach;

  // One block for the whole batch: each request's operator runs in turn inside it, then the
  // islands check, compensation and reinitialisation run once for all of them.
  // The largest threshold any selection compares the union's field with: the compensation
  // shell, the reinitialised region (within it) and the press's rim.
  const double field_reach =
      std::max(compensate && s.compensation == CompensationRegion::kShell ? shell_outer : 0.0,
               2 * dx);
  Block b = MakeBlock(impl, reqs, reach, field_reach);
  const double base_volume = impl.volume;
  // A batch's operators read each request's own field; the union is set aside meanwhile.
  std::vector<float> union_sdf;
  const NearBox union_near = b.near;
  if (reqs.size() > 1) union_sdf.swap(b.tool_sdf);
  std::vector<float> speed;  // a press's speed field, reused by the batch's requests
  lap(res.stage_ms.block);

  bool touched = false;
  for (const EditRequest& req : reqs) {
  // Operators read a request's own field only inside its tool, at its rim (2 voxels, within
  // the band's half-width of at least 3) and, for CSG, within the band: a distance beyond the
  // band clamps to the same value as +max, so nothing beyond bg of the tool needs evaluating.
  // A press reads it only inside the tool and at its rim unless it falls back to CSG, which
  // evaluates the band's width then.
  auto request_field = [&](double margin) {
    b.near = NearBox{};
    b.near.limit = margin;
    ToolFieldInto(b, req.tool, margin, b.tool_sdf, &b.near);
  };
  if (reqs.size() > 1) {
    request_field(req.kind == EditKind::kPress ? 2 * b.dx
                                               : std::max(static_cast<double>(b.bg), 2 * b.dx));
  }
  const VoxelList gamma = b.SelectNear(0.0, [](size_t, float t) { return t < 0.f; });
  switch (req.kind) {
    case EditKind::kPress: {
      // Seed 000 eq. 5.1 with the digest's sign: phi_t = v |grad phi| chi_Gamma, i.e. F = -v.
      // Runs whole steps of the stroke interval, each in CFL substeps, until no voxel of Gamma
      // holds material (the whole region is checked, not only the tool's boundary samples,
      // which left islands in the thesis: digest claim 9).
      if (req.speed <= 0 || !GammaHoldsMaterial(b, gamma)) break;
      touched = true;
      speed.assign(b.phi.size(), 0.f);
      for (uint32_t idx : gamma) speed[idx] = static_cast<float>(-req.speed);
      // The press runs until Gamma is empty, so its result does not depend on the speed; a
      // stroke slower than a quarter of a CFL substep per interval is run at that floor, which
      // bounds the work of any request.
      const double step_motion = std::max(req.speed * req.dt, 0.25 * s.cfl * dx);
      const int sub = std::max(1, static_cast<int>(std::ceil(step_motion / (s.cfl * dx) - 1e-9)));
      const double dt_sub = step_motion / (sub * req.speed);
      // The front needs at most the tool's diameter plus the band to leave Gamma.
      const double max_motion = 2 * scale + 2 * b.bg + 2 * dx;
      // (A very slow tool stalls by the test below long before this cap.)
      const int max_steps =
          static_cast<int>(std::min(1e6, std::ceil(max_motion / step_motion))) + 1;
      bool empty = false;
      for (int step = 0; step < max_steps && !empty; ++step) {
        ++res.steps;
        float max_change = 0;
        std::vector<float> prev;
        prev.reserve(gamma.size());
        for (int i = 0; i < sub; ++i) {
          prev.clear();
          for (uint32_t idx : gamma) prev.push_back(b.phi.data()[idx]);
          NormalMotionStep(b.phi, speed, gamma, dt_sub, dx, s.motion);
          ++res.substeps;
          for (size_t g = 0; g < gamma.size(); ++g) {
            max_change = std::max(max_change, std::abs(b.phi.data()[gamma[g]] - prev[g]));
          }
          if (!GammaHoldsMaterial(b, gamma)) {
            empty = true;
            break;
          }
        }
        if (!empty && max_change < 1e-6f * static_cast<float>(dx)) break;  // stalled
      }
      if (!GammaHoldsMaterial(b, gamma)) {
        // The flow stops at the border of Gamma and leaves the level sets piled up against it
        // (seed 000 §5 item 8): voxels just outside still hold their distance to the old
        // surface. Give them their distance to the new one, the tool's imprint (the thesis's
        // own CSG remedy, §6.2), so the dent sits where the tool was.
        VoxelList rim =
            b.SelectNear(2 * dx, [&](size_t, float t) { return t >= 0.f && t <= 2 * dx; });
        for (uint32_t idx : rim) {
          b.phi.data()[idx] = std::max(b.phi.data()[idx], -b.tool_sdf[idx]);
        }
        break;
      }
      // No interface reaches the material left in Gamma (a tool wholly inside the band-clamped
      // interior has zero gradient everywhere): finish with the CSG difference, which is where
      // the flow would have converged.
      res.press_fallback_csg = true;
      if (reqs.size() > 1) request_field(std::max(static_cast<double>(b.bg), 2 * b.dx));
      VoxelList all = b.Select([](size_t, float) { return true; });
      for (uint32_t idx : all) {
        b.phi.data()[idx] = std::max(b.phi.data()[idx], std::min(b.bg, -b.tool_sdf[idx]));
      }
      break;
    }
    case EditKind::kAdd:
    case EditKind::kSubtract: {
      const bool add = req.kind == EditKind::kAdd;
      VoxelList all = b.Select([](size_t, float) { return true; });
      for (uint32_t idx : all) {
        const float t = std::clamp(b.tool_sdf[idx], -b.bg, b.bg);
        float& v = b.phi.data()[idx];
        v = add ? std::min(v, t) : std::max(v, -t);
      }
      touched = true;
      break;
    }
    case EditKind::kSmooth: {
      std::vector<float> w(b.phi.size(), 0.f);
      VoxelList region = b.SelectNear(0.0, [](size_t, float t) { return t < 0.f; });
      for (uint32_t idx : region) {
        w[idx] = std::clamp(static_cast<float>(-b.tool_sdf[idx] / (2 * dx)), 0.f, 1.f);
      }
      const double dt = 0.9 * dx * dx / 6.0;
      const int n = std::max(1, static_cast<int>(std::ceil(req.amount * dx * dx / dt - 1e-9)));
      for (int i = 0; i < n && req.amount > 0; ++i) {
        CurvatureFlowStep(b.phi, w, region, dt, dx);
        ++res.substeps;
      }
      touched = touched || req.amount > 0;
      break;
    }
    case EditKind::kInflate:
    case EditKind::kDeflate: {
      if (req.amount <= 0) break;
      // A normal offset of a signed distance field by a is phi - a (|grad phi| = 1): done in one
      // pass, weighted by the tool's 2-voxel ramp, on a field whose band was first grown to
      // reach the offset surface. (Moving the front by normal speed instead needed a substep
      // per half voxel and ran the interface out of the band beyond the band's half-width.)
      ExtendBand(b, req.amount + b.bg + dx);
      const double sign = req.kind == EditKind::kInflate ? 1.0 : -1.0;
      for (uint32_t idx : gamma) {
        const double w = std::clamp(-b.tool_sdf[idx] / (2 * dx), 0.0, 1.0);
        b.phi.data()[idx] = static_cast<float>(b.phi.data()[idx] - sign * req.amount * w);
      }
      ++res.substeps;
      touched = true;
      break;
    }
  }
  }  // for each request
  if (reqs.size() > 1) {
    b.tool_sdf = std::move(union_sdf);
    b.near = union_near;
  }
  b.ClampToBand();
  lap(res.stage_ms.operators);
  const bool offset_kind = kind == EditKind::kInflate || kind == EditKind::kDeflate;
  // Slivers come from offsets that rewrite the band and from the box's sharp edges (ribs). A
  // smooth tool's press, smooth or CSG edit leaves none the reinitialisation does not
  // straighten, and scanning for them doubled a press's cost (and halved the server's edit
  // throughput), so those skip the sliver and band-repair passes.
  bool resolve = offset_kind;
  for (const EditRequest& req : reqs) resolve = resolve || req.tool.kind == ToolKind::kBox;
  const bool resolve_slivers = touched && resolve;
  // Slivers the operators left are emptied now. After an inflate or deflate the band repair
  // rebuilds around them; after the other kinds the reinitialisation below straightens them
  // with the rest of the edited band (a rebuild would cost more than the edit).
  // Voxels the band repair must rebuild (emptied slivers, removed islands); only edits that
  // resolve slivers use these.
  std::vector<uint8_t> repair, emptied;
  if (resolve_slivers) {
    repair.assign(b.phi.size(), 0);
    emptied.assign(b.phi.size(), 0);
    RemoveThinMaterial(b, offset_kind ? repair : emptied);
  }

  double reference = impl.reference_volume;
  ShellCache shell_cache;
  VoxelList reinit_extra;
  if (!offset_kind) {
    for (size_t idx = 0; idx < emptied.size(); ++idx) {
      if (emptied[idx]) reinit_extra.push_back(static_cast<uint32_t>(idx));
    }
  }
  lap(res.stage_ms.islands);

  // Shell compensation first: its weighted offset bends |grad phi| in the shell, which the
  // reinitialisation below then straightens.
  if (touched && compensate && s.compensation == CompensationRegion::kShell) {
    CompensationOutcome c = CompensateShell(b, reference, base_volume, shell_outer, s, shell_cache);
    res.compensation_iterations = c.iterations;
    res.compensation_failed = c.failed;
    res.substeps += c.substeps;
  }
  lap(res.stage_ms.compensation);

  // Local reinitialisation (seed 000 §4.4), triggered by the measured Eikonal error of the
  // edited band (the tool region plus two voxels), or every k edits, never blindly.
  if (touched) {
    ++impl.edits_since_reinit;
    // The tool region plus two voxels, and the compensation shell, whose variable-speed offset
    // bends |grad phi| away from one.
    const double extent =
        compensate && s.compensation == CompensationRegion::kShell ? shell_outer : 2 * dx;
    VoxelList region = b.SelectNear(extent, [&](size_t idx, float t) {
      return t < extent && std::abs(b.phi.data()[idx]) < b.bg;
    });
    if (!reinit_extra.empty()) {  // the selection alone is sorted and unique already
      region.insert(region.end(), reinit_extra.begin(), reinit_extra.end());
      std::sort(region.begin(), region.end());
      region.erase(std::unique(region.begin(), region.end()), region.end());
    }
    const EikonalStats e = MeasureEikonal(b.phi, region, dx, 3 * dx);
    res.eikonal_error_before_reinit = e.mean_abs_error;
    const bool due = s.reinit_every_k > 0 &&
                     impl.edits_since_reinit >= static_cast<uint64_t>(s.reinit_every_k);
    if (s.reinit_iterations > 0 &&
        (e.mean_abs_error > s.reinit_eikonal_threshold || due || !reinit_extra.empty())) {
      MotionSettings m = s.motion;
      m.spatial = s.reinit_spatial;
      m.temporal = TemporalScheme::kRk1;  // pseudo-time: only the steady state matters
      res.reinit_passes = Reinitialize(b.phi, region, s.reinit_iterations, dx, m, 0.5);
      impl.edits_since_reinit = 0;
      b.ClampToBand();
    }
  }
  lap(res.stage_ms.reinit);

  // Slivers emptied and the band rebuilt where the operators, the islands policy, the
  // compensation or the reinitialisation left it broken, before the last compensation restores
  // the volume that took.
  if (resolve_slivers) Resolve(b, repair, offset_kind);
  lap(res.stage_ms.resolve);

  // Compensation once more: the reinitialisation moved the interface slightly (by far less
  // than a voxel), so this pass is a small correction whose offset barely bends the field.
  if (touched && compensate && s.compensation == CompensationRegion::kShell) {
    CompensationOutcome c = CompensateShell(b, reference, base_volume, shell_outer, s, shell_cache);
    res.compensation_iterations += c.iterations;
    res.compensation_failed = res.compensation_failed || c.failed;
    res.substeps += c.substeps;
  }
  lap(res.stage_ms.compensation);

  // Again after the second compensation, whose offset may have flipped a sample next to a thin
  // spot or bent the band somewhere; usually there is nothing left to do. When there was, a
  // last compensation restores the volume that took (a small correction in the shell). What
  // slivers that regrows along the tool's sharp edges (it would regrow them again) are emptied
  // without a band repair, and like removed islands that clay is gone on purpose: the
  // reference volume is re-baselined by it.
  if (resolve_slivers && Resolve(b, repair, offset_kind) && compensate &&
      s.compensation == CompensationRegion::kShell) {
    CompensationOutcome c = CompensateShell(b, reference, base_volume, shell_outer, s, shell_cache);
    res.compensation_iterations += c.iterations;
    res.compensation_failed = res.compensation_failed || c.failed;
    res.substeps += c.substeps;
    const double inside_before = b.InsideChange();
    if (RemoveThinMaterial(b, repair) > 0) reference += (b.InsideChange() - inside_before) * dx3;
  }
  lap(res.stage_ms.resolve);

  // Pieces of material cut off and pockets of air sealed inside the block, after every pass
  // that moves the surface: the press and the sliver pass empty voxels and can cut pieces off,
  // and the compensation shell's bulge and the reinitialisation move samples either way, which
  // can leave a speck beside the surface or close a groove over a pocket of air. Under
  // kRemoveSmall the small ones are removed or filled and their band reinitialised; like the
  // slivers, that clay is removed or added on purpose, so the reference is re-baselined by it.
  if (touched) {
    // The band around what was removed or filled is reinitialised; returns the change of the
    // block's inside sum by the removal and that reinitialisation together.
    auto settle = [&](IslandReport& rep) {
      double change = rep.inside_change;
      if (rep.zone.empty() || s.reinit_iterations <= 0) return change;
      std::sort(rep.zone.begin(), rep.zone.end());
      rep.zone.erase(std::unique(rep.zone.begin(), rep.zone.end()), rep.zone.end());
      const double inside_before = b.InsideChange();
      MotionSettings m = s.motion;
      m.spatial = s.reinit_spatial;
      m.temporal = TemporalScheme::kRk1;  // pseudo-time: only the steady state matters
      res.reinit_passes += Reinitialize(b.phi, rep.zone, s.reinit_iterations, dx, m, 0.5);
      b.ClampToBand();
      return change + b.InsideChange() - inside_before;
    };
    // Islands first: removing one opens air, which the voids' search then sees connected.
    VoxelList flipped = PhaseChanges(b);
    IslandReport islands = FindPieces<false>(b, s, flipped);
    const double removed = -settle(islands);
    // The islands' voxels are air now: seeds of the voids' search like any opened voxel.
    flipped.insert(flipped.end(), islands.flipped.begin(), islands.flipped.end());
    IslandReport voids = FindPieces<true>(b, s, flipped);
    const double filled = settle(voids);
    res.islands_found = islands.found;
    res.islands_removed = islands.removed;
    res.island_volume_removed = removed * dx3;
    res.voids_found = voids.found;
    res.voids_filled = voids.removed;
    res.void_volume_filled = filled * dx3;
    reference += res.void_volume_filled - res.island_volume_removed;
  }
  lap(res.stage_ms.islands);

  SpliceBack(impl, b, base_volume, &res);
  lap(res.stage_ms.write_back);

  if (touched && compensate && s.compensation == CompensationRegion::kGlobal) {
    // The thesis's region: every interface voxel outside the tool (chi of Gamma's complement).
    // This walks the whole grid by design; it exists to reproduce seed 000 §6.3.
    auto& grid = *impl.grid;
    const double gap = 1.5 * dx;
    for (int it = 0; it < s.max_compensation_iterations; ++it) {
      const double err = reference - impl.volume;
      if (std::abs(err) <= s.compensation_tolerance_voxels * dx3) break;
      double area = 0;
      for (auto v = grid.tree().cbeginValueOn(); v; ++v) {
        const openvdb::Vec3d p = grid.indexToWorld(v.getCoord());
        if (UnionDistance(reqs, Vec3{p.x(), p.y(), p.z()}) > gap) {
          area += SmoothedDelta(*v, b.eps) * dx3;
        }
      }
      if (area <= 0) {
        res.compensation_failed = true;
        break;
      }
      // A uniform normal offset of an SDF is phi - d (|grad phi| = 1); the band is not rebuilt
      // (a tracker pass would move the interface again), values are kept within +-background.
      const float d = static_cast<float>(std::clamp(err / area, -0.5 * b.bg, 0.5 * b.bg));
      for (auto v = grid.tree().beginValueOn(); v; ++v) {
        const openvdb::Vec3d p = grid.indexToWorld(v.getCoord());
        if (UnionDistance(reqs, Vec3{p.x(), p.y(), p.z()}) > gap) {
          v.setValue(std::clamp(*v - d, -b.bg, b.bg));
        }
      }
      impl.volume = sculpture.ComputeVolume();
      ++res.compensation_iterations;
    }
    res.changed = true;
  }
  lap(res.stage_ms.compensation);

  if (kind == EditKind::kAdd || kind == EditKind::kSubtract || kind == EditKind::kInflate ||
      kind == EditKind::kDeflate) {
    // Material added or removed on purpose (islands included): the new volume is the one to keep.
    reference = impl.reference_volume + (impl.volume - res.volume_before);
  }
  impl.reference_volume = reference;
  res.reference_volume = reference;
  res.volume_after = impl.volume;
  res.compensation_residual = reference != 0 ? (impl.volume - reference) / reference : 0;
  res.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace

StatusOr<EditResult> ReinitializeRegion(Sculpture& sculpture, const Aabb& region, int iterations,
                                        const MotionSettings& motion) {
  if (!region.min.IsFinite() || !region.max.IsFinite()) {
    return InvalidArgument("region is not finite");
  }
  if (region.max.x < region.min.x || region.max.y < region.min.y || region.max.z < region.min.z) {
    return InvalidArgument("region is empty (max < min)");
  }
  SCULPT_RETURN_IF_ERROR(CheckRange("iterations", iterations, 1, 100));
  if (motion.spatial == SpatialScheme::kCentral) {
    return Outside("motion.spatial", "central", "{upwind, weno5}");
  }
  const auto t0 = std::chrono::steady_clock::now();
  Sculpture::Impl& impl = sculpture.impl();
  const double dx = impl.dx();
  const Vec3 c = (region.min + region.max) * 0.5;
  const ToolShape box = ToolShape::Box(c, (region.max - region.min) * 0.5 + Vec3{dx, dx, dx} * 0.5);
  EditRequest region_request;
  region_request.tool = box;
  Block b = MakeBlock(impl, {region_request}, 0, 0);
  const double base_volume = impl.volume;
  VoxelList active = b.Select([&](size_t idx, float t) {
    return t <= 0.f && std::abs(b.phi.data()[idx]) < b.bg;
  });
  EditResult res;
  res.volume_before = impl.volume;
  res.eikonal_error_before_reinit = MeasureEikonal(b.phi, active, dx, 3 * dx).mean_abs_error;
  res.reinit_passes = Reinitialize(b.phi, active, iterations, dx, motion, 0.5);
  b.ClampToBand();
  SpliceBack(impl, b, base_volume, &res);
  res.volume_after = impl.volume;
  res.reference_volume = impl.reference_volume;
  res.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace sculpt::levelset
