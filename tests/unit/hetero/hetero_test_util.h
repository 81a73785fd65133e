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
