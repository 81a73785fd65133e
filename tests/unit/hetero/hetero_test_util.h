/// @brief Fixtures shared by the hetero unit and stability tests: box cells, rotations.
#ifndef SCULPT_TESTS_UNIT_HETERO_HETERO_TEST_UTIL_H_
#define SCULPT_TESTS_UNIT_HETERO_HETERO_TEST_UTIL_H_

#include <cmath>

#include "sculpt/hetero/hyperpatch.h"

namespace sculpt::hetero::testing {

/// A box cell [0,sx]×[0,sy]×[0,sz] with evenly spaced coefficients (a trilinear map), every
/// coefficient material 0 of `n`.
inline Hyperpatch BoxPatch(double sx = 3, double sy = 3, double sz = 3, int n = 2) {
  Hyperpatch h(n);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) h.set_position(Hyperpatch::Index(i, j, k), {sx * i / 3, sy * j / 3, sz * k / 3});
  return h;
}

/// Rotation of p by `deg` degrees about axis 0, 1 or 2.
inline Vec3 Rotate(const Vec3& p, int axis, double deg) {
  const double a = deg * 3.14159265358979323846 / 180.0, c = std::cos(a), s = std::sin(a);
  if (axis == 0) return {p.x, c * p.y - s * p.z, s * p.y + c * p.z};
  if (axis == 1) return {c * p.x + s * p.z, p.y, -s * p.x + c * p.z};
  return {c * p.x - s * p.y, s * p.x + c * p.y, p.z};
}

inline Hyperpatch Rotated(const Hyperpatch& h, int axis, double deg) {
  Hyperpatch r = h;
  for (int i = 0; i < 64; ++i) r.set_position(i, Rotate(h.position(i), axis, deg));
  return r;
}

}  // namespace sculpt::hetero::testing

#endif  // SCULPT_TESTS_UNIT_HETERO_HETERO_TEST_UTIL_H_

namespace sculpt::hetero::testing {

/// Cubic Bézier arc handle factor for a quarter circle.
inline constexpr double kQuarterArc = 0.5522847498307936;

/// A ring sector cell: radii r0..r1 (u), angle a0..a1 degrees (v, cubic arcs), height z0..z1 (w).
inline Hyperpatch RingSectorPatch(double r0, double r1, double a0, double a1, double z0 = 0,
                                  double z1 = 1, int n = 2) {
  Hyperpatch h(n);
  const double t0 = a0 * 3.14159265358979323846 / 180, t1 = a1 * 3.14159265358979323846 / 180;
  const double kk = 4.0 / 3.0 * std::tan((t1 - t0) / 4);
  for (int i = 0; i < 4; ++i) {
    const double r = r0 + (r1 - r0) * i / 3;
    const Vec3 p0{r * std::cos(t0), r * std::sin(t0), 0}, p3{r * std::cos(t1), r * std::sin(t1), 0};
    const Vec3 p1 = p0 + Vec3{-std::sin(t0), std::cos(t0), 0} * (kk * r);
    const Vec3 p2 = p3 - Vec3{-std::sin(t1), std::cos(t1), 0} * (kk * r);
    const Vec3 arc[4] = {p0, p1, p2, p3};
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k)
        h.set_position(Hyperpatch::Index(i, j, k), arc[j] + Vec3{0, 0, z0 + (z1 - z0) * k / 3});
  }
  return h;
}

/// A valid cell that no frame makes monotone: the box 3×1×1 with y shifted by {0, 1, −1, 0}
/// along u, an S-shaped sheared slab ((u,v,w) -> (x(u), v + f(u), w) is injective).
inline Hyperpatch SShapedPatch() {
  Hyperpatch h = BoxPatch(3, 1, 1);
  const double f[4] = {0, 1, -1, 0};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) {
        const int idx = Hyperpatch::Index(i, j, k);
        h.set_position(idx, h.position(idx) + Vec3{0, f[i], 0});
      }
  return h;
}

}  // namespace sculpt::hetero::testing
