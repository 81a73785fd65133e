/// @brief Fast marching of distances and interface distances on a DenseField (fast_march.h).
#include "sculpt/levelset/fast_march.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

namespace sculpt::levelset {
namespace {

// Extents and strides of a field.
struct Dims {
  int n[3];
  ptrdiff_t stride[3];
  explicit Dims(const DenseField& f) {
    const Int3 d = f.dims();
    n[0] = d.x;
    n[1] = d.y;
    n[2] = d.z;
    stride[0] = 1;
    stride[1] = static_cast<ptrdiff_t>(d.x);
    stride[2] = static_cast<ptrdiff_t>(d.x) * d.y;
  }
};

}  // namespace

size_t MarchDistance(DenseField& phi, std::vector<MarchState>& state, double dx, double limit) {
  return MarchDistance(phi, state, dx, limit, Int3{0, 0, 0}, phi.dims());
}

namespace {

// The march of MarchDistance over the box [box_lo, box_hi) of `phi`. `kInside`: the box keeps
// one voxel from every face of the field, so no neighbour of a box voxel needs a bounds test.
// The tentative distances are kept for the box alone (free voxels lie in it), so a rebuild of a
// small part of a large block neither fills nor touches the rest of the block's size.
template <bool kInside>
size_t MarchBox(DenseField& phi, std::vector<MarchState>& state, double dx, double limit,
                const int box_lo[3], const int box_hi[3]) {
  const Dims g(phi);
  float* p = phi.data().data();
  const float flimit = static_cast<float>(limit);
  // Min-heap of (distance, index) packed in 64 bits: a non-negative float's bits order as the
  // float does, and the index breaks ties, so the order is fixed whatever the platform's heap.
  auto key = [](float t, size_t idx) {
    uint32_t bits;
    std::memcpy(&bits, &t, sizeof bits);
    return (static_cast<uint64_t>(bits) << 32) | static_cast<uint64_t>(idx);
  };
  const int w0 = box_hi[0] - box_lo[0], w1 = box_hi[1] - box_lo[1], w2 = box_hi[2] - box_lo[2];
  if (w0 <= 0 || w1 <= 0 || w2 <= 0) return 0;
  auto local = [&](int c0, int c1, int c2) {
    return (static_cast<size_t>(c2 - box_lo[2]) * static_cast<size_t>(w1) +
            static_cast<size_t>(c1 - box_lo[1])) *
               static_cast<size_t>(w0) +
           static_cast<size_t>(c0 - box_lo[0]);
  };
  std::vector<uint64_t> heap;
  // |phi| candidates of the box's free voxels, +inf until reached.
  std::vector<float> tentative(static_cast<size_t>(w0) * w1 * w2,
                               std::numeric_limits<float>::infinity());
  const auto greater = std::greater<uint64_t>();
  const double dx2 = dx * dx;
  // The Godunov update of a free voxel from its known neighbours (smallest per axis).
  auto solve = [&](size_t idx, int c0, int c1, int c2) {
    double a[3];
    int n = 0;
    const int c[3] = {c0, c1, c2};
    for (int ax = 0; ax < 3; ++ax) {
      double best = std::numeric_limits<double>::infinity();
      for (int side = -1; side <= 1; side += 2) {
        if constexpr (!kInside) {
          const int cc = c[ax] + side;
          if (cc < 0 || cc >= g.n[ax]) continue;
        }
        const size_t nb = idx + side * g.stride[ax];
        if (state[nb] != MarchState::kKnown) continue;
        best = std::min(best, static_cast<double>(std::abs(p[nb])));
      }
      if (best < std::numeric_limits<double>::infinity()) a[n++] = best;
    }
    if (n == 0) return std::numeric_limits<double>::infinity();
    // Ascending (at most three values; std::sort here trips -Warray-bounds in g++ 12).
    if (n > 1 && a[1] < a[0]) std::swap(a[0], a[1]);
    if (n > 2 && a[2] < a[1]) std::swap(a[1], a[2]);
    if (n > 1 && a[1] < a[0]) std::swap(a[0], a[1]);
    double t = a[0] + dx;
    if (n >= 2 && t > a[1]) {
      const double d = a[0] - a[1];
      t = 0.5 * (a[0] + a[1] + std::sqrt(std::max(0.0, 2.0 * dx2 - d * d)));
      if (n == 3 && t > a[2]) {
        const double sum = a[0] + a[1] + a[2];
        const double sq = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        t = (sum + std::sqrt(std::max(0.0, sum * sum - 3.0 * (sq - dx2)))) / 3.0;
      }
    }
    return t;
  };
  // Indices fit 32 bits (the heap key holds them so), whose division costs a fraction of a
  // 64-bit one.
  const uint32_t n0 = static_cast<uint32_t>(g.n[0]), n1 = static_cast<uint32_t>(g.n[1]);
  auto visit_free_neighbours = [&](size_t index, auto&& fn) {
    const uint32_t idx32 = static_cast<uint32_t>(index);
    const uint32_t row = idx32 / n0;
    const int c0 = static_cast<int>(idx32 - row * n0);
    const int c2 = static_cast<int>(row / n1);
    const int c1 = static_cast<int>(row - static_cast<uint32_t>(c2) * n1);
    const size_t idx = index;
    const int c[3] = {c0, c1, c2};
    for (int ax = 0; ax < 3; ++ax) {
      for (int side = -1; side <= 1; side += 2) {
        int cc[3] = {c[0], c[1], c[2]};
        cc[ax] += side;
        if constexpr (!kInside) {
          if (cc[ax] < 0 || cc[ax] >= g.n[ax]) continue;
        }
        const size_t nb = idx + side * g.stride[ax];
        if (state[nb] == MarchState::kFree) fn(nb, cc[0], cc[1], cc[2]);
      }
    }
  };
  auto update = [&](size_t nb, int c0, int c1, int c2) {
    const double t = solve(nb, c0, c1, c2);
    float& tent = tentative[local(c0, c1, c2)];
    if (t < tent && t < limit) {
      tent = static_cast<float>(t);
      heap.push_back(key(tent, nb));
      std::push_heap(heap.begin(), heap.end(), greater);
    }
  };
  // Seed: every free voxel next to a known one (its first tentative distance depends only on
  // the known voxels, so the order of seeding does not change the result).
  size_t free_count = 0;
  for (int c2 = box_lo[2]; c2 < box_hi[2]; ++c2) {
    for (int c1 = box_lo[1]; c1 < box_hi[1]; ++c1) {
      for (int c0 = box_lo[0]; c0 < box_hi[0]; ++c0) {
        const size_t idx = phi.Index(c0, c1, c2);
        if (state[idx] != MarchState::kFree) continue;
        ++free_count;
        update(idx, c0, c1, c2);
      }
    }
  }
  size_t computed = 0;
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), greater);
    const uint64_t top = heap.back();
    heap.pop_back();
    const size_t idx = static_cast<size_t>(top & 0xffffffffu);
    if (state[idx] != MarchState::kFree) continue;  // a stale entry
    state[idx] = MarchState::kKnown;
    float t;
    const uint32_t bits = static_cast<uint32_t>(top >> 32);
    std::memcpy(&t, &bits, sizeof t);  // the tentative distance the entry was pushed with
    p[idx] = p[idx] < 0.f ? -t : t;
    ++computed;
    visit_free_neighbours(idx, update);
  }
  if (computed < free_count) {
    for (int c2 = box_lo[2]; c2 < box_hi[2]; ++c2) {
      for (int c1 = box_lo[1]; c1 < box_hi[1]; ++c1) {
        for (int c0 = box_lo[0]; c0 < box_hi[0]; ++c0) {
          const size_t idx = phi.Index(c0, c1, c2);
          if (state[idx] != MarchState::kFree) continue;
          p[idx] = p[idx] < 0.f ? -flimit : flimit;
          state[idx] = MarchState::kKnown;
        }
      }
    }
  }
  return free_count;
}

}  // namespace

size_t MarchDistance(DenseField& phi, std::vector<MarchState>& state, double dx, double limit,
                     Int3 lo, Int3 hi) {
  if (state.size() != phi.size() || !(dx > 0.0) || !(limit > 0.0)) return 0;
  const Dims g(phi);
  const int box_lo[3] = {std::max(0, lo.x), std::max(0, lo.y), std::max(0, lo.z)};
  const int box_hi[3] = {std::min(g.n[0], hi.x), std::min(g.n[1], hi.y), std::min(g.n[2], hi.z)};
  bool inside = true;
  for (int a = 0; a < 3; ++a) inside = inside && box_lo[a] >= 1 && box_hi[a] <= g.n[a] - 1;
  return inside ? MarchBox<true>(phi, state, dx, limit, box_lo, box_hi)
                : MarchBox<false>(phi, state, dx, limit, box_lo, box_hi);
}

double InterfaceDistance(const DenseField& phi, int i, int j, int k, double dx) {
  const Dims g(phi);
  const float* p = phi.data().data();
  const ptrdiff_t index = static_cast<ptrdiff_t>(phi.Index(i, j, k));
  const int c[3] = {i, j, k};
  const double p0 = p[index];
  const bool inside = p0 < 0.0;
  // Where the crossing lies along each axis, by linear interpolation on the edge to the nearer
  // neighbour of the other sign (what volumeToMesh places its vertices by); the surface is taken
  // as the plane through those intercepts, whose distance is 1 / sqrt(sum 1 / t_a^2).
  double inv_sq = 0.0;
  bool crossing = false;
  for (int a = 0; a < 3; ++a) {
    double t = std::numeric_limits<double>::infinity();
    for (int side = -1; side <= 1; side += 2) {
      const int cc = c[a] + side;
      if (cc < 0 || cc >= g.n[a]) continue;
      const double w = p[index + side * g.stride[a]];
      if ((w < 0.0) == inside) continue;
      t = std::min(t, dx * std::abs(p0) / std::max(std::abs(w - p0), 1e-12 * dx));
    }
    if (std::isinf(t)) continue;
    crossing = true;
    if (t == 0.0) return 0.0;
    inv_sq += 1.0 / (t * t);
  }
  if (!crossing) return p0;
  const double d = 1.0 / std::sqrt(inv_sq);
  return inside ? -d : d;
}

}  // namespace sculpt::levelset
