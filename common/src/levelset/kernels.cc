/// @brief Finite-difference level-set kernels: Godunov/WENO5 normal motion with TVD Runge-Kutta,
/// curvature flow, Sussman reinitialisation with the Russo-Smereka fix, Eikonal error, smoothed H.
#include "sculpt/levelset/kernels.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

namespace sculpt::levelset::internal {
namespace {

// Everything here is single-threaded with plain loops in a fixed order and double arithmetic,
// so results are bit-identical run to run and independent of how many threads the caller has.

/// Box extents and strides of a DenseField (x fastest).
struct Grid {
  int n[3];
  ptrdiff_t stride[3];

  explicit Grid(const DenseField& f) {
    const Int3 d = f.dims();
    n[0] = d.x;
    n[1] = d.y;
    n[2] = d.z;
    stride[0] = 1;
    stride[1] = static_cast<ptrdiff_t>(d.x);
    stride[2] = static_cast<ptrdiff_t>(d.x) * d.y;
  }

  /// A border voxel touches the box face of some axis that has a border at all; an axis of
  /// extent 1 (a one-voxel slab) has none, so a slab's voxels are not all border voxels.
  bool IsBorder(const int c[3]) const {
    for (int a = 0; a < 3; ++a) {
      if (n[a] > 1 && (c[a] == 0 || c[a] == n[a] - 1)) return true;
    }
    return false;
  }
};

/// A voxel to update: its linear index and local coordinates, decoded once per call.
struct Voxel {
  ptrdiff_t index;
  int c[3];
};

/// Whether every voxel's stencil of radius R lies inside the box on every axis (and no axis has
/// extent 1): the stencils may then read their samples without clamping. The edits' lists keep
/// three voxels from the block's border, so this holds for them; the clamping path stays for
/// other callers. Both paths do the same arithmetic on the same samples.
bool AllInterior(const Grid& g, const std::vector<Voxel>& voxels, int r) {
  for (int a = 0; a < 3; ++a) {
    if (g.n[a] == 1) return false;
  }
  for (const Voxel& v : voxels) {
    for (int a = 0; a < 3; ++a) {
      if (v.c[a] < r || v.c[a] + r >= g.n[a]) return false;
    }
  }
  return true;
}

/// Decodes `active` into voxels, dropping indices outside the box and those `skip` rejects.
template <typename Skip>
std::vector<Voxel> Collect(const Grid& g, size_t size, const VoxelList& active, Skip skip) {
  std::vector<Voxel> out;
  out.reserve(active.size());
  // Indices are 32-bit: 32-bit divisions cost a fraction of 64-bit ones.
  const uint32_t nx = static_cast<uint32_t>(g.n[0]);
  const uint32_t ny = static_cast<uint32_t>(g.n[1]);
  for (uint32_t idx : active) {
    if (idx >= size) continue;
    Voxel v;
    v.index = static_cast<ptrdiff_t>(idx);
    const uint32_t row = idx / nx;
    v.c[0] = static_cast<int>(idx - row * nx);
    v.c[1] = static_cast<int>(row % ny);
    v.c[2] = static_cast<int>(row / ny);
    if (skip(v)) continue;
    out.push_back(v);
  }
  return out;
}

/// Samples at offsets -R..R along one axis, with coordinates clamped into the box (the kClamp
/// zero-gradient extension; an axis of extent 1 then yields a constant, i.e. no derivative).
template <int R>
inline void Gather(const float* p, ptrdiff_t index, int c, int n, ptrdiff_t s, double* v) {
  if (c >= R && c + R < n) {
    const float* q = p + index;
    for (int o = -R; o <= R; ++o) v[o + R] = q[o * s];
  } else {
    for (int o = -R; o <= R; ++o) {
      const int cc = std::clamp(c + o, 0, n - 1);
      v[o + R] = p[index + (cc - c) * s];
    }
  }
}

/// Jiang-Peng HJ-WENO5 derivative from the five divided differences v1..v5 ordered upwind to
/// downwind (Osher & Fedkiw, Level Set Methods, ch. 3). The epsilon scales with the data so the
/// weights do not depend on dx or on the magnitude of phi.
inline double Weno5(double v1, double v2, double v3, double v4, double v5) {
  constexpr double kSixth = 1.0 / 6.0;
  constexpr double k13_12 = 13.0 / 12.0;
  const double p1 = (2.0 * v1 - 7.0 * v2 + 11.0 * v3) * kSixth;
  const double p2 = (-v2 + 5.0 * v3 + 2.0 * v4) * kSixth;
  const double p3 = (2.0 * v3 + 5.0 * v4 - v5) * kSixth;
  const double a = v1 - 2.0 * v2 + v3;
  const double b = v1 - 4.0 * v2 + 3.0 * v3;
  const double c = v2 - 2.0 * v3 + v4;
  const double d = v2 - v4;
  const double e = v3 - 2.0 * v4 + v5;
  const double f = 3.0 * v3 - 4.0 * v4 + v5;
  // Smoothness indicators relative to the largest squared difference: the weights are then
  // independent of dx and of the magnitude of phi (Osher-Fedkiw's eps = 1e-6 max v^2), and the
  // products below neither overflow for huge differences nor reach 0/0 when all v vanish.
  const double vmax = std::max({v1 * v1, v2 * v2, v3 * v3, v4 * v4, v5 * v5});
  const double inv = 1.0 / (vmax + 1e-300);
  const double q1 = (k13_12 * a * a + 0.25 * b * b) * inv + 1e-6;
  const double q2 = (k13_12 * c * c + 0.25 * d * d) * inv + 1e-6;
  const double q3 = (k13_12 * e * e + 0.25 * f * f) * inv + 1e-6;
  const double r1 = q1 * q1;
  const double r2 = q2 * q2;
  const double r3 = q3 * q3;
  // Weights alpha_k = c_k / r_k, multiplied through by r1 r2 r3 to need a single division.
  const double a1 = 0.1 * r2 * r3;
  const double a2 = 0.6 * r1 * r3;
  const double a3 = 0.3 * r1 * r2;
  return (a1 * p1 + a2 * p2 + a3 * p3) / (a1 + a2 + a3);
}

/// One axis's share of |grad phi|^2 from the one-sided derivatives dm = D-, dp = D+ by Godunov's
/// method for H = F|p| (Osher & Fedkiw, ch. 6): for F > 0 information comes from smaller phi,
/// max(max(D-, 0)^2, min(D+, 0)^2); for F < 0 from larger phi. Taking the max rather than the
/// sum of the two upwind terms (Osher-Sethian) only matters where both are upwind, at a ridge
/// between colliding fronts; there the sum would move the ridge at sqrt(2) times the speed.
inline double UpwindTerm(double dm, double dp, bool positive) {
  const double m = positive ? std::max(dm, 0.0) : std::min(dm, 0.0);
  const double q = positive ? std::min(dp, 0.0) : std::max(dp, 0.0);
  return std::max(m * m, q * q);
}

/// |grad phi|^2 at voxel v with scheme S; `positive` selects the upwind side (ignored by
/// kCentral). Axes of extent 1 contribute nothing.
template <SpatialScheme S, bool kInterior = false>
inline double GradientSq(const float* p, const Grid& g, const Voxel& v, double inv_dx,
                         bool positive) {
  double sum = 0.0;
  for (int a = 0; a < 3; ++a) {
    if (!kInterior && g.n[a] == 1) continue;
    if constexpr (S == SpatialScheme::kUpwind && kInterior) {
      const float* q = p + v.index;
      const ptrdiff_t st = g.stride[a];
      const double w0 = q[-st], w1 = q[0], w2 = q[st];
      sum += UpwindTerm((w1 - w0) * inv_dx, (w2 - w1) * inv_dx, positive);
    } else if constexpr (S == SpatialScheme::kCentral) {
      double w[3];
      Gather<1>(p, v.index, v.c[a], g.n[a], g.stride[a], w);
      const double d = 0.5 * (w[2] - w[0]) * inv_dx;
      sum += d * d;
    } else if constexpr (S == SpatialScheme::kUpwind) {
      double w[3];
      Gather<1>(p, v.index, v.c[a], g.n[a], g.stride[a], w);
      sum += UpwindTerm((w[1] - w[0]) * inv_dx, (w[2] - w[1]) * inv_dx, positive);
    } else {
      double w[7];
      Gather<3>(p, v.index, v.c[a], g.n[a], g.stride[a], w);
      double d[6];
      for (int k = 0; k < 6; ++k) d[k] = (w[k + 1] - w[k]) * inv_dx;
      // d[k] is the forward difference between offsets k-3 and k-2: D- reads d0..d4 from the
      // left, D+ reads d5..d1 from the right.
      const double dm = Weno5(d[0], d[1], d[2], d[3], d[4]);
      const double dp = Weno5(d[5], d[4], d[3], d[2], d[1]);
      sum += UpwindTerm(dm, dp, positive);
    }
  }
  return sum;
}

/// Scratch for one TVD Runge-Kutta step, reused across stages.
struct RkBuffers {
  std::vector<float> orig;
  std::vector<float> next;
};

/// One Shu-Osher TVD RK step (seed 000 §2.7, its ref. [50]) of phi_t = L(phi) on `voxels`.
/// `rhs(phi_data, voxel, n)` evaluates L at voxels[n] from the current stage. Every stage evaluates
/// L at all voxels before writing any of them (Jacobi), so the result does not depend on the order
/// of the list and duplicate entries are harmless. Voxels not in the list keep their values and
/// feed the stencils.
template <typename Rhs>
void RkStep(DenseField& phi, const std::vector<Voxel>& voxels, TemporalScheme order, double dt,
            RkBuffers& buf, Rhs rhs) {
  float* p = phi.data().data();
  const size_t m = voxels.size();
  buf.next.resize(m);
  if (order != TemporalScheme::kRk1) {
    buf.orig.resize(m);
    for (size_t n = 0; n < m; ++n) buf.orig[n] = p[voxels[n].index];
  }
  // Stage weights (a, b): new = a * orig + b * (cur + dt * L(cur)).
  double weights[3][2] = {{0.0, 1.0}, {0.0, 0.0}, {0.0, 0.0}};
  int stages = 1;
  if (order == TemporalScheme::kRk2) {
    stages = 2;
    weights[1][0] = 0.5;
    weights[1][1] = 0.5;
  } else if (order == TemporalScheme::kRk3) {
    stages = 3;
    weights[1][0] = 0.75;
    weights[1][1] = 0.25;
    weights[2][0] = 1.0 / 3.0;
    weights[2][1] = 2.0 / 3.0;
  }
  for (int s = 0; s < stages; ++s) {
    const double wa = weights[s][0];
    const double wb = weights[s][1];
    for (size_t n = 0; n < m; ++n) {
      const Voxel& v = voxels[n];
      const double cur = p[v.index];
      const double euler = cur + dt * rhs(p, v, n);
      const double value = s == 0 ? euler : wa * static_cast<double>(buf.orig[n]) + wb * euler;
      buf.next[n] = static_cast<float>(value);
    }
    for (size_t n = 0; n < m; ++n) p[voxels[n].index] = buf.next[n];
  }
}

template <SpatialScheme S>
void NormalMotionImpl(DenseField& phi, const std::vector<float>& speed,
                      const std::vector<Voxel>& voxels, double dt, double dx,
                      TemporalScheme order) {
  const Grid g(phi);
  const double inv_dx = 1.0 / dx;
  RkBuffers buf;
  // seed 000 eq. 4.4: phi_t = -F |grad phi|; F < 0 raises phi, the press of eq. 5.1 with the
  // digest's sign correction. For kCentral this is exactly the thesis's `objdef` under RK1.
  if (S == SpatialScheme::kUpwind && AllInterior(g, voxels, 1)) {
    RkStep(phi, voxels, order, dt, buf, [&](const float* p, const Voxel& v, size_t) {
      const double f = speed[static_cast<size_t>(v.index)];
      return -f * std::sqrt(GradientSq<S, true>(p, g, v, inv_dx, f > 0.0));
    });
    return;
  }
  RkStep(phi, voxels, order, dt, buf, [&](const float* p, const Voxel& v, size_t) {
    const double f = speed[static_cast<size_t>(v.index)];
    return -f * std::sqrt(GradientSq<S>(p, g, v, inv_dx, f > 0.0));
  });
}

/// Per-voxel data of a reinitialisation frozen at the call's start (phi0 of seed 000 eq. 4.9).
struct ReinitVoxel {
  double sign;      // S(phi0), eq. 4.10.
  double distance;  // Russo-Smereka distance estimate D; used only when `subcell`.
  double sgn0;      // sgn(phi0) in {-1, 0, 1}.
  bool subcell;
};

inline bool OppositeSigns(double a, double b) {
  return (a < 0.0 && b > 0.0) || (a > 0.0 && b < 0.0);
}

/// Freezes S(phi0) and, for voxels with a sign change to a 6-neighbour, the Russo-Smereka
/// distance D = dx * phi0 / Delta (Russo & Smereka, JCP 163, 2000, extended to 3D): Delta is the
/// largest of the central-difference gradient norm and the one-sided differences across the
/// interface, in undivided form, so D estimates the signed distance without trusting |grad| = 1.
template <bool kInterior>
std::vector<ReinitVoxel> FreezeReinit(const DenseField& phi, const Grid& g,
                                      const std::vector<Voxel>& voxels, double dx) {
  const float* p = phi.data().data();
  std::vector<ReinitVoxel> out(voxels.size());
  const double dx2 = dx * dx;
  const double tiny = 1e-6 * dx;
  for (size_t n = 0; n < voxels.size(); ++n) {
    const Voxel& v = voxels[n];
    const double p0 = p[v.index];
    ReinitVoxel& r = out[n];
    r.sign = p0 / std::sqrt(p0 * p0 + dx2);
    r.sgn0 = p0 > 0.0 ? 1.0 : (p0 < 0.0 ? -1.0 : 0.0);
    r.distance = 0.0;
    r.subcell = p0 == 0.0;
    double central_sq = 0.0;
    double across = 0.0;
    for (int a = 0; a < 3; ++a) {
      double w[3];
      if constexpr (kInterior) {
        const float* q = p + v.index;
        w[0] = q[-g.stride[a]];
        w[1] = q[0];
        w[2] = q[g.stride[a]];
      } else {
        if (g.n[a] == 1) continue;
        Gather<1>(p, v.index, v.c[a], g.n[a], g.stride[a], w);
      }
      const double c = 0.5 * (w[2] - w[0]);
      central_sq += c * c;
      for (int side : {0, 2}) {
        if (OppositeSigns(p0, w[side])) {
          r.subcell = true;
          across = std::max(across, std::abs(w[side] - p0));
        }
      }
    }
    if (r.subcell) {
      const double delta = std::max({std::sqrt(central_sq), across, tiny});
      r.distance = dx * p0 / delta;
    }
  }
  return out;
}

template <SpatialScheme S>
void ReinitImpl(DenseField& phi, const std::vector<Voxel>& voxels, int iterations, double dx,
                TemporalScheme order, double cfl) {
  const Grid g(phi);
  const double inv_dx = 1.0 / dx;
  const double dt = cfl * dx;
  const bool interior = AllInterior(g, voxels, 1);
  const std::vector<ReinitVoxel> frozen = interior ? FreezeReinit<true>(phi, g, voxels, dx)
                                                   : FreezeReinit<false>(phi, g, voxels, dx);
  RkBuffers buf;
  auto run = [&](auto interior) {
    auto rhs = [&](const float* p, const Voxel& v, size_t n) {
      const ReinitVoxel& r = frozen[n];
      if (r.subcell) {
        // Russo-Smereka: relax phi towards the frozen distance D so that the voxels that
        // bracket the interface hold the zero crossing where phi0 put it.
        return -(r.sgn0 * std::abs(static_cast<double>(p[v.index])) - r.distance) * inv_dx;
      }
      // seed 000 eq. 4.9: phi_t = -S(phi0)(|grad phi| - 1), upwinded by the sign of S.
      return -r.sign *
             (std::sqrt(GradientSq<S, decltype(interior)::value>(p, g, v, inv_dx, r.sign > 0.0)) -
              1.0);
    };
    for (int it = 0; it < iterations; ++it) RkStep(phi, voxels, order, dt, buf, rhs);
  };
  if (S == SpatialScheme::kUpwind && interior) {
    run(std::true_type{});
  } else {
    run(std::false_type{});
  }
}

/// The indices of `active` below `size` into `out`, in order, if each lies one voxel or more
/// inside the box on every axis (as AllInterior(g, Collect(...), 1) asks); false otherwise.
/// The lists are sorted, mostly runs along x, so a run's next voxel is decoded by a step of x
/// rather than by divisions.
bool InteriorIndices(const Grid& g, size_t size, const VoxelList& active,
                     std::vector<ptrdiff_t>& out) {
  for (int a = 0; a < 3; ++a) {
    if (g.n[a] < 3) return false;
  }
  out.clear();
  out.reserve(active.size());
  const uint32_t nx = static_cast<uint32_t>(g.n[0]);
  const uint32_t ny = static_cast<uint32_t>(g.n[1]);
  const uint32_t nz = static_cast<uint32_t>(g.n[2]);
  uint32_t last = 0;
  uint32_t x = 0;  // coordinates of `last`; x = 0 also marks "none yet" (never interior)
  for (uint32_t idx : active) {
    if (idx >= size) continue;
    if (x != 0 && idx == last + 1 && x + 2 < nx) {
      ++x;  // same row, and still at most nx - 2
    } else {
      const uint32_t row = idx / nx;
      x = idx - row * nx;
      const uint32_t y = row % ny;
      const uint32_t z = row / ny;
      if (x < 1 || x + 1 >= nx || y < 1 || y + 1 >= ny || z < 1 || z + 1 >= nz) return false;
    }
    last = idx;
    out.push_back(static_cast<ptrdiff_t>(idx));
  }
  return true;
}

/// The default reinitialisation (first-order upwind, forward Euler, every stencil inside the box)
/// with the arithmetic of ReinitImpl<kUpwind> and RkStep in the same order, so the results are the
/// same bit for bit; it differs in the work around that arithmetic: the frozen data, the Eikonal
/// measure and the first step's values come from one read of each stencil, the voxels beside the
/// interface (which relax towards their frozen distance and read no neighbour) are kept apart
/// from the rest, and the upwind side is chosen by a sign flip instead of a branch per axis.
/// With `trigger` (null: reinitialise unconditionally) it also measures as
/// MeasureEikonal(phi, voxels, dx, trigger->band) does into *stats, and leaves phi unchanged and
/// returns false unless the mean error exceeds trigger->threshold or trigger->force holds (true
/// otherwise, also when `iterations` <= 0 leaves phi as it is).
/// `voxels` are linear indices one voxel or more inside the box (InteriorIndices).
bool UpwindReinitRk1(DenseField& phi, const Grid& g, const std::vector<ptrdiff_t>& voxels,
                     int iterations, double dx, double cfl, const ReinitTrigger* trigger,
                     EikonalStats* stats) {
  float* p = phi.data().data();
  const double inv_dx = 1.0 / dx;
  const double dt = cfl * dx;
  const double dx2 = dx * dx;
  const double tiny = 1e-6 * dx;
  const ptrdiff_t sy = g.stride[1];
  const ptrdiff_t sz = g.stride[2];
  // Voxels away from the interface: index and S(phi0).
  struct Far {
    ptrdiff_t index;
    double sign;
  };
  // Voxels beside it: index, sgn(phi0) and the Russo-Smereka distance.
  struct Near {
    ptrdiff_t index;
    double sgn0;
    double distance;
  };
  std::vector<Far> far;
  std::vector<Near> near;
  far.reserve(voxels.size());
  std::vector<float> next_far, next_near;
  next_far.reserve(voxels.size());
  double sum = 0.0;
  for (const ptrdiff_t index : voxels) {
    const float* q = p + index;
    const double p0 = q[0];
    const double w[3][2] = {{q[-1], q[1]}, {q[-sy], q[sy]}, {q[-sz], q[sz]}};
    // |grad phi|^2 by UpwindTerm with the side chosen by sign(phi0): for phi0 <= 0 the terms
    // are those of the negated differences, whose squares are the same.
    const bool positive = p0 > 0.0;
    const double flip = positive ? 1.0 : -1.0;
    double grad_sq = 0.0;
    bool kink = false;
    bool subcell = p0 == 0.0;
    double central_sq = 0.0;
    double across = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double dm = (p0 - w[a][0]) * inv_dx;
      const double dp = (w[a][1] - p0) * inv_dx;
      kink = kink || (positive ? (dm > 0.0 && dp < 0.0) : (dm < 0.0 && dp > 0.0));
      const double m = std::max(flip * dm, 0.0);
      const double u = std::min(flip * dp, 0.0);
      grad_sq += std::max(m * m, u * u);
      const double c = 0.5 * (w[a][1] - w[a][0]);
      central_sq += c * c;
      for (int side = 0; side < 2; ++side) {
        if (OppositeSigns(p0, w[a][side])) {
          subcell = true;
          across = std::max(across, std::abs(w[a][side] - p0));
        }
      }
    }
    if (trigger && !kink && std::abs(p0) < trigger->band) {
      // MeasureEikonal stops summing at the first kinked axis and skips the voxel; the sum over
      // the axes before it is then unused, so summing all three is the same.
      const double err = std::abs(std::sqrt(grad_sq) - 1.0);
      sum += err;
      stats->max_abs_error = std::max(stats->max_abs_error, err);
      ++stats->samples;
    }
    if (subcell) {
      const double delta = std::max({std::sqrt(central_sq), across, tiny});
      const double distance = dx * p0 / delta;
      const double sgn0 = positive ? 1.0 : (p0 < 0.0 ? -1.0 : 0.0);
      near.push_back({index, sgn0, distance});
      next_near.push_back(
          static_cast<float>(p0 + dt * (-(sgn0 * std::abs(p0) - distance) * inv_dx)));
    } else {
      const double sign = p0 / std::sqrt(p0 * p0 + dx2);
      far.push_back({index, sign});
      // The step's side is chosen by S(phi0) > 0, which is phi0 > 0 unless S underflows to 0,
      // when the step is p0 + dt * (+-0) = p0 whatever the gradient.
      next_far.push_back(static_cast<float>(p0 + dt * (-sign * (std::sqrt(grad_sq) - 1.0))));
    }
  }
  if (trigger) {
    if (stats->samples > 0) stats->mean_abs_error = sum / static_cast<double>(stats->samples);
    if (!(stats->mean_abs_error > trigger->threshold || trigger->force)) return false;
  }
  if (iterations <= 0) return true;
  // Jacobi as in RkStep: every voxel's new value from the current field, then all written.
  auto write = [&] {
    for (size_t n = 0; n < far.size(); ++n) p[far[n].index] = next_far[n];
    for (size_t n = 0; n < near.size(); ++n) p[near[n].index] = next_near[n];
  };
  write();
  // One far voxel's step, the arithmetic of ReinitImpl<kUpwind> with the side chosen by a flip.
  auto step = [&](size_t n) {
    const float* q = p + far[n].index;
    const double c = q[0];
    const double sign = far[n].sign;
    const double flip = sign > 0.0 ? 1.0 : -1.0;
    double grad_sq = 0.0;
    for (ptrdiff_t s : {ptrdiff_t{1}, sy, sz}) {
      const double m = std::max(flip * ((c - q[-s]) * inv_dx), 0.0);
      const double u = std::min(flip * ((q[s] - c) * inv_dx), 0.0);
      grad_sq += std::max(m * m, u * u);
    }
    next_far[n] = static_cast<float>(c + dt * (-sign * (std::sqrt(grad_sq) - 1.0)));
  };
#if defined(__GNUC__) && !defined(__clang__)
  // Runs of far voxels along x (the lists are sorted): two neighbours' stencils are two
  // adjacent floats at each of the seven offsets, read and converted as pairs and stepped in
  // GCC's two-lane vectors, lane by lane the operations of `step` in its order (the selects
  // are std::max's and std::min's), so the values are the same bit for bit.
  using V2 = double __attribute__((vector_size(16)));
  using F2 = float __attribute__((vector_size(8)));
  auto load2 = [](const float* a) {
    F2 f;
    std::memcpy(&f, a, sizeof f);
    return __builtin_convertvector(f, V2);
  };
  std::vector<size_t> pairs;  // first of two far voxels adjacent along x
  std::vector<size_t> singles;
  for (size_t n = 0; n < far.size();) {
    if (n + 1 < far.size() && far[n + 1].index == far[n].index + 1) {
      pairs.push_back(n);
      n += 2;
    } else {
      singles.push_back(n);
      n += 1;
    }
  }
  const V2 zero = {0.0, 0.0};
  const V2 one = {1.0, 1.0};
  const V2 inv = {inv_dx, inv_dx};
  const V2 dtv = {dt, dt};
  auto term = [&](V2 c, V2 flip, V2 lo, V2 hi) {
    const V2 fm = flip * ((c - lo) * inv);
    const V2 fp = flip * ((hi - c) * inv);
    const V2 m = fm < zero ? zero : fm;
    const V2 u = zero < fp ? zero : fp;
    const V2 m2 = m * m;
    const V2 u2 = u * u;
    return m2 < u2 ? u2 : m2;
  };
  auto step_all = [&] {
    for (size_t n : pairs) {
      const float* q = p + far[n].index;
      const V2 c = load2(q);
      const V2 sign = {far[n].sign, far[n + 1].sign};
      const V2 flip = sign > zero ? one : -one;
      const V2 g2 = (term(c, flip, load2(q - 1), load2(q + 1)) +
                     term(c, flip, load2(q - sy), load2(q + sy))) +
                    term(c, flip, load2(q - sz), load2(q + sz));
      const V2 norm = {std::sqrt(g2[0]), std::sqrt(g2[1])};
      const F2 next = __builtin_convertvector(c + dtv * (-sign * (norm - one)), F2);
      std::memcpy(&next_far[n], &next, sizeof next);
    }
    for (size_t n : singles) step(n);
  };
#else
  auto step_all = [&] {
    for (size_t n = 0; n < far.size(); ++n) step(n);
  };
#endif
  for (int it = 1; it < iterations; ++it) {
    step_all();
    for (size_t n = 0; n < near.size(); ++n) {
      const double c = p[near[n].index];
      next_near[n] =
          static_cast<float>(c + dt * (-(near[n].sgn0 * std::abs(c) - near[n].distance) * inv_dx));
    }
    write();
  }
  return true;
}

}  // namespace
}  // namespace sculpt::levelset::internal

namespace sculpt::levelset {

using internal::Collect;
using internal::Grid;
using internal::Voxel;

void NormalMotionStep(DenseField& phi, const std::vector<float>& speed, const VoxelList& active,
                      double dt, double dx, const MotionSettings& settings) {
  // A speed field of another layout or a non-positive dx is a programmer error: leave phi alone
  // rather than read out of bounds or divide by zero.
  if (speed.size() != phi.size() || !(dx > 0.0) || dt == 0.0) return;
  const Grid g(phi);
  const bool adiabatic = settings.boundary == Boundary::kAdiabatic;
  // F = 0 voxels and adiabatic border voxels (|grad phi| := 0, eq. 5.10) cannot move; leaving
  // them out of the list keeps them bit-identical through the RK combinations.
  const std::vector<Voxel> voxels = Collect(g, phi.size(), active, [&](const Voxel& v) {
    return speed[static_cast<size_t>(v.index)] == 0.0f || (adiabatic && g.IsBorder(v.c));
  });
  switch (settings.spatial) {
    case SpatialScheme::kCentral:
      internal::NormalMotionImpl<SpatialScheme::kCentral>(phi, speed, voxels, dt, dx,
                                                          settings.temporal);
      break;
    case SpatialScheme::kUpwind:
      internal::NormalMotionImpl<SpatialScheme::kUpwind>(phi, speed, voxels, dt, dx,
                                                         settings.temporal);
      break;
    case SpatialScheme::kWeno5:
      internal::NormalMotionImpl<SpatialScheme::kWeno5>(phi, speed, voxels, dt, dx,
                                                        settings.temporal);
      break;
  }
}

double MaxStableStep(double max_abs_speed, double dx, double cfl) {
  // Only the magnitude matters; nothing moves at zero speed, so every step is stable.
  const double speed = std::abs(max_abs_speed);
  if (!(speed > 0.0)) return std::numeric_limits<double>::infinity();
  return cfl * dx / speed;
}

void CurvatureFlowStep(DenseField& phi, const std::vector<float>& weight, const VoxelList& active,
                       double dt, double dx) {
  if (weight.size() != phi.size() || !(dx > 0.0) || dt == 0.0) return;
  const Grid g(phi);
  const std::vector<Voxel> voxels = Collect(g, phi.size(), active, [&](const Voxel& v) {
    return weight[static_cast<size_t>(v.index)] == 0.0f;
  });
  float* p = phi.data().data();
  const double inv_dx = 1.0 / dx;
  const double inv_dx2 = inv_dx * inv_dx;
  std::vector<float> next(voxels.size());
  for (size_t n = 0; n < voxels.size(); ++n) {
    const Voxel& v = voxels[n];
    // Offsets to the clamped neighbours; an axis of extent 1 gets 0 both ways, so all of its
    // derivatives vanish and eq. 2.8 reduces to its 2D terms.
    ptrdiff_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = v.c[a] > 0 ? -g.stride[a] : 0;
      hi[a] = v.c[a] < g.n[a] - 1 ? g.stride[a] : 0;
    }
    const float* q = p + v.index;
    const double c = q[0];
    double d1[3], d2[3];
    for (int a = 0; a < 3; ++a) {
      const double m = q[lo[a]];
      const double pl = q[hi[a]];
      d1[a] = 0.5 * (pl - m) * inv_dx;
      d2[a] = (pl - 2.0 * c + m) * inv_dx2;
    }
    auto mixed = [&](int a, int b) {
      return 0.25 * inv_dx2 *
             (static_cast<double>(q[hi[a] + hi[b]]) - q[hi[a] + lo[b]] - q[lo[a] + hi[b]] +
              q[lo[a] + lo[b]]);
    };
    const double g2 = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2];
    if (std::sqrt(g2) < 1e-6) {
      next[n] = q[0];
      continue;
    }
    // seed 000 eq. 2.8: kappa |grad phi|^3 = numerator, so kappa |grad phi| = numerator / |g|^2.
    const double num = d1[0] * d1[0] * (d2[1] + d2[2]) + d1[1] * d1[1] * (d2[0] + d2[2]) +
                       d1[2] * d1[2] * (d2[0] + d2[1]) -
                       2.0 * (d1[0] * d1[1] * mixed(0, 1) + d1[0] * d1[2] * mixed(0, 2) +
                              d1[1] * d1[2] * mixed(1, 2));
    const double w = weight[static_cast<size_t>(v.index)];
    next[n] = static_cast<float>(c + dt * w * num / g2);
  }
  for (size_t n = 0; n < voxels.size(); ++n) p[voxels[n].index] = next[n];
}

int Reinitialize(DenseField& phi, const VoxelList& active, int iterations, double dx,
                 const MotionSettings& settings, double cfl) {
  if (iterations <= 0 || !(dx > 0.0) || !(cfl > 0.0)) return 0;
  const Grid g(phi);
  const bool adiabatic = settings.boundary == Boundary::kAdiabatic;
  // With kAdiabatic the border voxels are frozen: setting |grad phi| := 0 there as normal motion
  // does would make eq. 4.9 push them by S(phi0) every step.
  const std::vector<Voxel> voxels =
      Collect(g, phi.size(), active, [&](const Voxel& v) { return adiabatic && g.IsBorder(v.c); });
  if (settings.spatial == SpatialScheme::kUpwind && settings.temporal == TemporalScheme::kRk1 &&
      internal::AllInterior(g, voxels, 1)) {
    std::vector<ptrdiff_t> indices(voxels.size());
    for (size_t n = 0; n < voxels.size(); ++n) indices[n] = voxels[n].index;
    internal::UpwindReinitRk1(phi, g, indices, iterations, dx, cfl, nullptr, nullptr);
    return iterations;
  }
  switch (settings.spatial) {
    case SpatialScheme::kCentral:
      internal::ReinitImpl<SpatialScheme::kCentral>(phi, voxels, iterations, dx, settings.temporal,
                                                    cfl);
      break;
    case SpatialScheme::kUpwind:
      internal::ReinitImpl<SpatialScheme::kUpwind>(phi, voxels, iterations, dx, settings.temporal,
                                                   cfl);
      break;
    case SpatialScheme::kWeno5:
      internal::ReinitImpl<SpatialScheme::kWeno5>(phi, voxels, iterations, dx, settings.temporal,
                                                  cfl);
      break;
  }
  return iterations;
}

MeasuredReinit MeasureAndReinitialize(DenseField& phi, const VoxelList& active, int iterations,
                                      double dx, const MotionSettings& settings, double cfl,
                                      const ReinitTrigger& trigger) {
  MeasuredReinit out;
  if (!(dx > 0.0)) return out;
  const Grid g(phi);
  if (settings.spatial == SpatialScheme::kUpwind && settings.temporal == TemporalScheme::kRk1 &&
      settings.boundary == Boundary::kClamp && cfl > 0.0) {
    // With kClamp both passes take the same voxels (the measure drops border voxels and those
    // beyond the band, which the fused pass tells apart); the fused pass needs them interior.
    std::vector<ptrdiff_t> voxels;
    if (internal::InteriorIndices(g, phi.size(), active, voxels)) {
      out.triggered =
          internal::UpwindReinitRk1(phi, g, voxels, iterations, dx, cfl, &trigger, &out.before);
      out.passes = out.triggered && iterations > 0 ? iterations : 0;
      return out;
    }
  }
  out.before = MeasureEikonal(phi, active, dx, trigger.band);
  out.triggered = out.before.mean_abs_error > trigger.threshold || trigger.force;
  if (out.triggered) out.passes = Reinitialize(phi, active, iterations, dx, settings, cfl);
  return out;
}

EikonalStats MeasureEikonal(const DenseField& phi, const VoxelList& active, double dx,
                            double band) {
  EikonalStats stats;
  if (!(dx > 0.0)) return stats;
  const Grid g(phi);
  const float* p = phi.data().data();
  const double inv_dx = 1.0 / dx;
  const std::vector<Voxel> voxels = Collect(g, phi.size(), active, [&](const Voxel& v) {
    return g.IsBorder(v.c) || !(std::abs(p[v.index]) < band);
  });
  double sum = 0.0;
  for (const Voxel& v : voxels) {
    const double c = p[v.index];
    const bool positive = c > 0.0;
    double grad_sq = 0.0;
    bool kink = false;
    for (int a = 0; a < 3; ++a) {
      if (g.n[a] == 1) continue;
      const double dm = (c - p[v.index - g.stride[a]]) * inv_dx;
      const double dp = (p[v.index + g.stride[a]] - c) * inv_dx;
      // Both neighbours upwind (a ridge outside, a trough inside) is the skeleton of the
      // distance function, where the Eikonal equation holds only in the viscosity sense.
      if (positive ? (dm > 0.0 && dp < 0.0) : (dm < 0.0 && dp > 0.0)) {
        kink = true;
        break;
      }
      grad_sq += internal::UpwindTerm(dm, dp, positive);
    }
    if (kink) continue;
    const double err = std::abs(std::sqrt(grad_sq) - 1.0);
    sum += err;
    stats.max_abs_error = std::max(stats.max_abs_error, err);
    ++stats.samples;
  }
  if (stats.samples > 0) stats.mean_abs_error = sum / static_cast<double>(stats.samples);
  return stats;
}

double CentralGradientNorm(const DenseField& phi, int i, int j, int k, double dx,
                           Boundary boundary) {
  if (!phi.Contains(i, j, k) || !(dx > 0.0)) return 0.0;
  const Grid g(phi);
  const int c[3] = {i, j, k};
  if (boundary == Boundary::kAdiabatic && g.IsBorder(c)) return 0.0;
  const float* p = phi.data().data();
  const ptrdiff_t index = static_cast<ptrdiff_t>(phi.Index(i, j, k));
  double sum = 0.0;
  for (int a = 0; a < 3; ++a) {
    if (g.n[a] == 1) continue;
    const ptrdiff_t s = g.stride[a];
    double d;
    if (c[a] == 0) {
      d = (static_cast<double>(p[index + s]) - p[index]) / dx;
    } else if (c[a] == g.n[a] - 1) {
      d = (static_cast<double>(p[index]) - p[index - s]) / dx;
    } else {
      d = (static_cast<double>(p[index + s]) - p[index - s]) / (2.0 * dx);
    }
    sum += d * d;
  }
  return std::sqrt(sum);
}

}  // namespace sculpt::levelset
