/// @file edit_block.h
/// @brief The block an edit runs in (internal to the levelset library): the influence box, grown
/// by the compensation shell and the stencil halo, copied out of the grid into a DenseField with
/// the tools' signed distance beside it; the edit's passes (edit_passes.h) work on it and
/// SpliceBack writes the changed voxels back.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/kernels.h"
#include "sculpture_impl.h"

namespace sculpt::levelset::internal {

// WENO5 reads three voxels to each side; the write-back skips this margin, and every mask
// below stays at least this far from the block border.
constexpr int kStencilMargin = 3;

/// The scale of a tool (radius, or the largest half-extent), in world units.
double ToolScale(const ToolShape& t);

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
  double object_before = 0;     // the object's tracked volume at extraction, in voxels

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
    ForEachChangedRow([&](size_t, int i0, int i1, int j, int k) { c.AddRow(i0, i1, j, k); });
    return c;
  }
  // Calls f(row, i0, i1, j, k) for each row (j, k) of the block whose bits differ from `before`,
  // in index order: `row` is its first index, [i0, i1] its first to last changed voxel. Rows
  // are compared whole first, so unchanged rows cost one memcmp.
  template <typename F>
  void ForEachChangedRow(F&& f) const {
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
        f(row, i0, i1, j, k);
      }
    }
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
  // Clamps the listed voxels to the band: enough when the rest of the block is within it and only
  // they moved since (a list kernel writes its list's voxels alone).
  void ClampToBand(const VoxelList& moved) {
    float* p = phi.data().data();
    for (uint32_t idx : moved) p[idx] = std::clamp(p[idx], -bg, bg);
  }
  // Change of the inside-voxel count since extraction: only voxels that changed contribute, so
  // the tracked volume stays exact without summing the block. They are added in index order.
  // One pass over the block's rows: a changed row is summed between its first and last changed
  // voxels (found as Changed() finds them), which holds every voxel the box would visit in it.
  double InsideChange() const {
    double sum = 0;
    const float* now = phi.data().data();
    const float* was = before.data().data();
    ForEachChangedRow([&](size_t row, int i0, int i1, int, int) {
      for (size_t idx = row + i0; idx <= row + i1; ++idx) {
        if (now[idx] != was[idx]) {
          sum += VolumeFraction(now[idx], dx) - VolumeFraction(was[idx], dx);
        }
      }
    });
    return sum;
  }
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
            sum += VolumeFraction(now[idx], dx) - VolumeFraction(was[idx], dx);
          }
        }
      }
    }
    return sum;
  }
};

/// The tool's signed distance (world units) at the voxels of the block within `margin` of the
/// tool's bounds; +max elsewhere, where no operator reads a finite value. Written into `f`
/// (resized to the block); `near` gets the range of the voxels at most near->limit away.
void ToolFieldInto(const Block& b, const ToolShape& tool, double margin, std::vector<float>& f,
                   NearBox* near);

/// Sets the block's tool field to one request's own tool, evaluated within `margin` (a batch's
/// operators read their own tool; the union is set aside meanwhile).
void LoadRequestField(Block& b, const ToolShape& tool, double margin);

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
                    const EditSettings& s);

/// The index box around every tool of a batch, grown by `reach` and the stencil pad.
IndexBox BlockBox(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs,
                  double reach);

// One block around every tool of a batch; tool_sdf is the union of the tools (their minimum).
// Every operator and selection compares the field with thresholds no larger than
// `field_reach` (and the CSG operators see no difference between a distance beyond the band
// and +max), so the exact-distance tools are evaluated only within max(field_reach, band) of
// their bounds.
Block MakeBlock(const Sculpture::Impl& impl, const std::vector<EditRequest>& reqs, double reach,
                double field_reach);

// Writes the block's changed voxels into the grid, grows the cached bounds, and updates the
// tracked volume from the changed voxels alone.
void SpliceBack(Sculpture::Impl& impl, const Block& b, double base_volume, EditResult* res);

/// The union of the batch's tools (their smallest signed distance) at a world point.
double UnionDistance(const std::vector<EditRequest>& reqs, const Vec3& p);

/// Whether any voxel of `gamma` still holds material (phi <= 0).
inline bool GammaHoldsMaterial(const Block& b, const VoxelList& gamma) {
  for (uint32_t idx : gamma) {
    if (b.phi.data()[idx] <= 0.f) return true;
  }
  return false;
}

}  // namespace sculpt::levelset::internal
