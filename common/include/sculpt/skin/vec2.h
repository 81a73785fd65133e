/// @brief Vec2: a plain 2D vector of doubles in sketch-plane coordinates, with the rotations the
/// ball-skin construction needs (seed 004 digest, conventions).
#ifndef SCULPT_SKIN_VEC2_H_
#define SCULPT_SKIN_VEC2_H_

#include <cmath>
#include <vector>

namespace sculpt::skin {

/// A point or vector in the sketch plane. Value type.
struct Vec2 {
  double x = 0, y = 0;

  constexpr Vec2() = default;
  constexpr Vec2(double x_, double y_) : x(x_), y(y_) {}

  constexpr Vec2 operator+(const Vec2& o) const { return {x + o.x, y + o.y}; }
  constexpr Vec2 operator-(const Vec2& o) const { return {x - o.x, y - o.y}; }
  constexpr Vec2 operator-() const { return {-x, -y}; }
  constexpr Vec2 operator*(double s) const { return {x * s, y * s}; }
  constexpr Vec2 operator/(double s) const { return {x / s, y / s}; }
  Vec2& operator+=(const Vec2& o) { x += o.x; y += o.y; return *this; }
  constexpr bool operator==(const Vec2& o) const = default;

  constexpr double Dot(const Vec2& o) const { return x * o.x + y * o.y; }
  /// The z of the 3D cross product: positive when `o` is counter-clockwise from this.
  constexpr double Cross(const Vec2& o) const { return x * o.y - y * o.x; }
  double Length() const { return std::sqrt(x * x + y * y); }
  constexpr double LengthSqr() const { return x * x + y * y; }
  bool IsFinite() const { return std::isfinite(x) && std::isfinite(y); }
  /// This divided by its length; (0, 0) stays (0, 0).
  Vec2 Normalized() const {
    const double l = Length();
    return l > 0 ? Vec2{x / l, y / l} : Vec2{};
  }
  /// Rotated by -90 degrees: the right-hand normal of a travel direction (digest §2.2, the
  /// corrected sign convention n = rotR(t)).
  constexpr Vec2 RotR() const { return {y, -x}; }
  /// Rotated by +90 degrees.
  constexpr Vec2 RotL() const { return {-y, x}; }
};

inline constexpr Vec2 operator*(double s, const Vec2& v) { return v * s; }

/// An open polyline: consecutive points joined by segments.
using Polyline2 = std::vector<Vec2>;

}  // namespace sculpt::skin

#endif  // SCULPT_SKIN_VEC2_H_
