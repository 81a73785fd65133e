/// @file edit_islands.cc
/// @brief Pieces of material an edit cut off and pockets of air it sealed, inside the block.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "edit_block.h"
#include "edit_passes.h"

namespace sculpt::levelset::internal {

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

namespace {

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
      const double f = VolumeFraction(data[v], b.dx);
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
  // No material on the border: the block holds the whole object, whose largest piece stays,
  // unless the object holds more than twice that piece's volume elsewhere (material beyond the
  // block that no piece here touches: an add in open air beside a scattered object made a
  // speck of 6.5 units^3 that was kept as "the object").
  const bool whole_object =
      !any_border && 2 * pieces[largest].volume >= b.object_before + b.InsideChange();
  std::vector<uint8_t> remove(pieces.size(), 0);
  for (size_t i = 0; i < pieces.size(); ++i) {
    if (whole_object && i == largest) continue;
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
  // A band value of the removed surface lies within bg of it in Euclidean distance, which is up
  // to sqrt(3) times as many 6-steps (along a diagonal): its band is found up to that many.
  const int hw_removed = static_cast<int>(std::ceil(std::sqrt(3.0) * b.bg / b.dx)) + 1;
  auto distance_from = [&](int cap, auto is_source) {
    std::vector<int16_t> dist(n, static_cast<int16_t>(cap + 1));
    std::vector<uint32_t> queue;
    for (size_t idx = 0; idx < n; ++idx) {
      if (is_source(idx)) {
        dist[idx] = 0;
        queue.push_back(static_cast<uint32_t>(idx));
      }
    }
    for (size_t q = 0; q < queue.size(); ++q) {
      const uint32_t idx = queue[q];
      if (dist[idx] >= cap) continue;
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
      hw, [&](size_t idx) { return in(data[idx]) && (label[idx] < 0 || !remove[label[idx]]); });
  const std::vector<int16_t> dist_removed = distance_from(hw_removed, [&](size_t idx) {
    return in(data[idx]) && label[idx] >= 0 && remove[label[idx]];
  });
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
        if (dist_removed[idx] > hw_removed || in(data[idx]) || !(std::abs(data[idx]) < b.bg)) {
          continue;
        }
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

}  // namespace

IslandReport FindIslands(Block& b, const EditSettings& s, const VoxelList& flipped) {
  return FindPieces<false>(b, s, flipped);
}

IslandReport FindVoids(Block& b, const EditSettings& s, const VoxelList& flipped) {
  return FindPieces<true>(b, s, flipped);
}

}  // namespace sculpt::levelset::internal
