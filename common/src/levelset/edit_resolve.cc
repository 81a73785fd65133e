/// @file edit_resolve.cc
/// @brief Slivers and torn bands: material thinner than a voxel is emptied and the narrow band
/// rebuilt where an edit left it broken (the holes inflate left, the ribs of a box press).
#include <algorithm>
#include <cmath>

#include "edit_block.h"
#include "edit_passes.h"
#include "sculpt/levelset/fast_march.h"
#include "sculpt/levelset/invariants.h"

namespace sculpt::levelset::internal {

// Rounds of sliver removal and band repair before the last sliver pass (Resolve).
constexpr int kBandRepairRounds = 4;

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

namespace {

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

}  // namespace

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

}  // namespace sculpt::levelset::internal
