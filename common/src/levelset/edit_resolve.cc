/// @file edit_resolve.cc
/// @brief Slivers and torn bands: material thinner than a voxel is emptied and the narrow band
/// rebuilt where an edit left it broken (the holes inflate left, the ribs of a box press).
#include <algorithm>
#include <cmath>
#include <cstring>

#include "edit_block.h"
#include "edit_passes.h"
#include "sculpt/levelset/fast_march.h"
#include "sculpt/levelset/invariants.h"

namespace sculpt::levelset::internal {

// Rounds of sliver removal and band repair before the last sliver pass (Resolve).
constexpr int kBandRepairRounds = 4;

namespace {

// A box of the block, [lo, hi), with a byte per voxel (x fastest).
struct BoxMask {
  int lo[3] = {0, 0, 0};
  int hi[3] = {0, 0, 0};
  std::vector<uint8_t> m;

  bool Empty() const { return lo[0] >= hi[0] || lo[1] >= hi[1] || lo[2] >= hi[2]; }
  int Width(int a) const { return hi[a] - lo[a]; }
  size_t Local(int i, int j, int k) const {
    return (static_cast<size_t>(k - lo[2]) * Width(1) + (j - lo[1])) * Width(0) + (i - lo[0]);
  }
  // Sets the box and clears every mark.
  void Reset(const int l[3], const int h[3]) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = l[a];
      hi[a] = std::max(l[a], h[a]);
    }
    m.assign(Empty() ? 0 : static_cast<size_t>(Width(0)) * Width(1) * Width(2), 0);
  }
  // Grows every mark by `r` voxels along each axis in turn (a box filter: the marks become the
  // Chebyshev r-neighbourhood of the old ones, clipped to the box). Each axis ORs the 2r + 1
  // shifted copies of its lines, whole rows or planes at a time, which the compiler vectorises.
  void Dilate(int r) {
    if (Empty() || r <= 0) return;
    const int w[3] = {Width(0), Width(1), Width(2)};
    const size_t row = static_cast<size_t>(w[0]), plane = row * w[1];
    std::vector<uint8_t> out(m.size());
    auto or_into = [](uint8_t* dst, const uint8_t* src, size_t count) {
      for (size_t q = 0; q < count; ++q) dst[q] |= src[q];
    };
    for (int a = 0; a < 3; ++a) {
      std::copy(m.begin(), m.end(), out.begin());
      for (int d = -r; d <= r; ++d) {
        if (d == 0) continue;
        const int c0 = std::max(0, -d), c1 = std::min(w[a], w[a] - d);  // c + d within [0, w)
        if (c0 >= c1) continue;
        if (a == 2) {
          or_into(&out[c0 * plane], &m[(c0 + d) * plane], (c1 - c0) * plane);
        } else {
          for (int k = 0; k < w[2]; ++k) {
            if (a == 1) {
              uint8_t* base = &out[k * plane];
              or_into(base + c0 * row, &m[k * plane + (c0 + d) * row], (c1 - c0) * row);
            } else {
              for (int j = 0; j < w[1]; ++j) {
                const size_t line = k * plane + j * row;
                or_into(&out[line + c0], &m[line + c0 + d], c1 - c0);
              }
            }
          }
        }
      }
      m.swap(out);
    }
  }
};

// The voxels of the block's written interior within one voxel (26-neighbourhood) of a voxel
// whose bits differ from the extracted field's: the only ones whose thinness, interface or
// steepest slope the edit can have changed (the field beyond them is the one the previous edit
// left). The sliver and band passes scan these rather than the block: after a press they are
// about a third of it.
BoxMask NearChanges(const Block& b) {
  BoxMask near;
  const NearBox c = b.Changed();
  const Int3 d = b.phi.dims();
  const int dims[3] = {d.x, d.y, d.z};
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(0, c.lo[a] - 1);
    hi[a] = std::min(dims[a], c.hi[a] + 1);
  }
  near.Reset(lo, hi);
  if (near.Empty()) return near;
  const float* now = b.phi.data().data();
  const float* was = b.before.data().data();
  const size_t span = static_cast<size_t>(c.hi[0] - c.lo[0]) * sizeof(float);
  for (int k = c.lo[2]; k < c.hi[2]; ++k) {
    for (int j = c.lo[1]; j < c.hi[1]; ++j) {
      const size_t row = b.phi.Index(c.lo[0], j, k);
      if (std::memcmp(now + row, was + row, span) == 0) continue;
      uint8_t* marks = &near.m[near.Local(c.lo[0], j, k)];
      for (int i = 0; i < c.hi[0] - c.lo[0]; ++i) {
        uint32_t a, w;
        std::memcpy(&a, now + row + i, sizeof a);
        std::memcpy(&w, was + row + i, sizeof w);
        marks[i] = a != w;
      }
    }
  }
  near.Dilate(1);
  // Kept to the written interior.
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(kStencilMargin, near.lo[a]);
    hi[a] = std::min(dims[a] - kStencilMargin, near.hi[a]);
  }
  BoxMask inner;
  inner.Reset(lo, hi);
  if (inner.Empty()) return inner;
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      const uint8_t* from = &near.m[near.Local(lo[0], j, k)];
      std::copy(from, from + inner.Width(0), &inner.m[inner.Local(lo[0], j, k)]);
    }
  }
  return inner;
}

// RemoveThinMaterial on the voxels `near` marks (NearChanges of the block as it is).
size_t RemoveThinNear(Block& b, const BoxMask& near, std::vector<uint8_t>& touched) {
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
      const float a = data[idx - dirs[n]], c = data[idx + dirs[n]];
      // Only material with air on both sides can be thin (ThinMaterialThickness is infinite
      // otherwise); most voxels stop here without the call.
      if (!(a >= 0.f) || !(c >= 0.f)) continue;
      if (ThinMaterialThickness(data[idx], a, c, lengths[n]) < b.dx) {
        return true;
      }
    }
    return false;
  };
  std::vector<uint32_t> work;
  if (near.Empty()) return 0;
  for (int k = near.lo[2]; k < near.hi[2]; ++k) {
    for (int j = near.lo[1]; j < near.hi[1]; ++j) {
      const uint8_t* marks = &near.m[near.Local(near.lo[0], j, k)] - near.lo[0];
      for (int i = near.lo[0]; i < near.hi[0]; ++i) {
        if (!marks[i]) continue;
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

}  // namespace

size_t RemoveThinMaterial(Block& b, std::vector<uint8_t>& touched) {
  return RemoveThinNear(b, NearChanges(b), touched);
}

namespace {

// The steepest slope (below) over the neighbours the edit may write (the block's interior):
// next to the stencil margin, a slope to a margin voxel that an earlier edit left is no cliff a
// rebuild here can level (it would find it again every round).
float SteepestWritableSlope(const Block& b, int i, int j, int k) {
  const float v = b.phi.at(i, j, k);
  float g = 0.f;
  for (int dk = -1; dk <= 1; ++dk) {
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        if ((!di && !dj && !dk) || !b.Interior(i + di, j + dj, k + dk)) continue;
        const float length =
            static_cast<float>(b.dx * std::sqrt(static_cast<double>(di * di + dj * dj + dk * dk)));
        g = std::max(g, std::abs(b.phi.at(i + di, j + dj, k + dk) - v) / length);
      }
    }
  }
  return g;
}

// Keeps the narrow band valid where the edit left it broken. Among the voxels `near` marks (the
// edit's changes and their neighbours: the band elsewhere is as the previous edit left it), an
// interface voxel with a voxel at the band's edge among its 26 neighbours (the zero crossing
// about to leave the band, the source of the holes inflate left), or a band voxel whose
// |grad phi| is far from one, marks its surroundings (the band's half-width plus one voxel) for
// rebuilding. There the voxels that bracket the interface take their Russo-Smereka distance (the
// crossing stays where it is) and every other voxel its distance by fast marching, which visits
// the surroundings' box alone. Voxels `touched` marks (emptied slivers: changed voxels, so within
// `near`) are rebuilt too. Returns the number of voxels rebuilt.
size_t RepairBand(Block& b, const BoxMask& near, const std::vector<uint8_t>& touched) {
  if (near.Empty()) return 0;
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
  std::vector<Int3> bad;
  // |grad phi| is judged as the slope of steepest descent: the largest |phi(n) - phi(v)| /
  // |n - v| over the 26 neighbours (invariants.h explains why not a one-sided norm). Per row of
  // the mask's box, it and the interface test are computed for every voxel, one neighbour at a
  // time along the row: loops the compiler vectorises, where a voxel at a time it could not.
  const int width = near.Width(0);
  std::vector<float> slope(static_cast<size_t>(width));
  std::vector<uint8_t> flips(static_cast<size_t>(width));
  for (int k = near.lo[2]; k < near.hi[2]; ++k) {
    for (int j = near.lo[1]; j < near.hi[1]; ++j) {
      const uint8_t* marks = &near.m[near.Local(near.lo[0], j, k)] - near.lo[0];
      const uint8_t* first = std::find(marks + near.lo[0], marks + near.hi[0], uint8_t{1});
      if (first == marks + near.hi[0]) continue;
      // Only the marked voxels read their slope and crossing: the row's span from its first to
      // its last mark is computed (each voxel's value does not depend on the span).
      int last = near.hi[0] - 1;
      while (!marks[last]) --last;
      const int s0 = static_cast<int>(first - marks) - near.lo[0];
      const int s1 = last + 1 - near.lo[0];
      const size_t row = b.phi.Index(near.lo[0], j, k);
      const float* c = p + row;
      std::fill(slope.begin() + s0, slope.begin() + s1, 0.f);
      std::fill(flips.begin() + s0, flips.begin() + s1, uint8_t{0});
      for (int o = 0; o < 26; ++o) {
        const float* q = c + offsets[o];
        const float inv = inv_lengths[o];
        for (int i = s0; i < s1; ++i) slope[i] = std::max(slope[i], std::abs(q[i] - c[i]) * inv);
      }
      for (int a = 0; a < 3; ++a) {
        const float* lo_side = c - stride[a];
        const float* hi_side = c + stride[a];
        for (int i = s0; i < s1; ++i) {
          const uint8_t in = c[i] < 0.f;
          flips[i] |= static_cast<uint8_t>(((lo_side[i] < 0.f) != in) | ((hi_side[i] < 0.f) != in));
        }
      }
      for (int i = near.lo[0] + s0; i < near.lo[0] + s1; ++i) {
        if (!marks[i]) continue;
        const size_t idx = row + static_cast<size_t>(i - near.lo[0]);
        if (touched[idx]) {
          bad.push_back({i, j, k});
          continue;
        }
        const float v = p[idx];
        const bool interface = flips[i - near.lo[0]] != 0;
        if (!interface && !(std::abs(v) < band_inner)) continue;
        bool broken = false;
        if (interface) {  // a voxel at the band's edge in its 3x3x3 neighbourhood
          broken = !(std::abs(v) < bg);
          for (int o = 0; o < 26 && !broken; ++o) broken = !(std::abs(p[idx + offsets[o]]) < bg);
        }
        if (!broken && std::abs(v) < band_inner) {
          const float g = slope[i - near.lo[0]];
          bool steep = g > 1.4f;
          const bool at_margin =
              !b.Interior(i - 1, j - 1, k - 1) || !b.Interior(i + 1, j + 1, k + 1);
          if (steep && at_margin) steep = SteepestWritableSlope(b, i, j, k) > 1.4f;
          broken = g < 0.6f || steep;
        }
        if (broken) bad.push_back({i, j, k});
      }
    }
  }
  if (bad.empty()) return 0;
  // The region: bad voxels dilated by the half-width plus one voxel, within the block; the
  // rebuild below keeps to its written interior.
  const int reach = static_cast<int>(std::ceil(b.bg / b.dx)) + 1;
  const int dims[3] = {d.x, d.y, d.z};
  int lo[3] = {dims[0], dims[1], dims[2]}, hi[3] = {0, 0, 0};
  for (const Int3& c : bad) {
    const int cc[3] = {c.x, c.y, c.z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], std::max(0, cc[a] - reach));
      hi[a] = std::max(hi[a], std::min(dims[a], cc[a] + reach + 1));
    }
  }
  BoxMask region;
  region.Reset(lo, hi);
  for (const Int3& c : bad) region.m[region.Local(c.x, c.y, c.z)] = 1;
  region.Dilate(reach);
  int ilo[3], ihi[3];
  for (int a = 0; a < 3; ++a) {
    ilo[a] = std::max(kStencilMargin, lo[a]);
    ihi[a] = std::min(dims[a] - kStencilMargin, hi[a]);
  }
  std::vector<MarchState> state(n, MarchState::kKnown);
  std::vector<std::pair<uint32_t, float>> interface_values;
  size_t rebuilt = 0;
  for (int k = ilo[2]; k < ihi[2]; ++k) {
    for (int j = ilo[1]; j < ihi[1]; ++j) {
      for (int i = ilo[0]; i < ihi[0]; ++i) {
        if (!region.m[region.Local(i, j, k)]) continue;
        const size_t idx = b.phi.Index(i, j, k);
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
  // crossing on the segment where it was. Two Jacobi passes settle the corners seen here. All
  // interface distances are read from the field before any is written, so they are written
  // first and each pass reads the field with the previous pass's distances in place.
  for (const auto& [idx, v] : interface_values) data[idx] = v;
  std::vector<float> scaled(interface_values.size());
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t q = 0; q < interface_values.size(); ++q) {
      const auto& [idx, v] = interface_values[q];
      const bool inside = v < 0.f;
      float f = 1.f;
      for (int o = 0; o < 26; ++o) {
        const float w = p[idx + offsets[o]];
        if ((w < 0.f) == inside) continue;
        const float sum = (std::abs(v) + std::abs(w)) * inv_lengths[o];
        if (sum > 1.f) f = std::min(f, 1.f / sum);
      }
      scaled[q] = v * f;
    }
    for (size_t q = 0; q < interface_values.size(); ++q) {
      interface_values[q].second = scaled[q];
      data[interface_values[q].first] = scaled[q];
    }
  }
  MarchDistance(b.phi, state, b.dx, b.bg, Int3{ilo[0], ilo[1], ilo[2]},
                Int3{ihi[0], ihi[1], ihi[2]});
  return rebuilt;
}

}  // namespace

bool Resolve(Block& b, std::vector<uint8_t>& repair, bool always_repair) {
  bool changed = false;
  bool settled = false;
  for (int round = 0; round < kBandRepairRounds && !settled; ++round) {
    // Both passes read the voxels near the edit's changes; emptying slivers adds to those.
    BoxMask near = NearChanges(b);
    const size_t thin = RemoveThinNear(b, near, repair);
    if (round == 0 && !always_repair && thin == 0 &&
        std::find(repair.begin(), repair.end(), uint8_t{1}) == repair.end()) {
      settled = true;
      break;
    }
    if (thin > 0) near = NearChanges(b);
    const size_t rebuilt = RepairBand(b, near, repair);
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

}  // namespace sculpt::levelset::internal
