/// @brief A small 3-vector of doubles for public headers that must not pull in OpenVDB.
#ifndef SCULPT_CORE_VEC3_H_
#define SCULPT_CORE_VEC3_H_

#include <cmath>

namespace sculpt {

/// A plain 3D vector (world or index coordinates). Value type.
struct Vec3 {
  double x = 0, y = 0, z = 0;

  constexpr Vec3() = default;
  constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}

  constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  constexpr Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
  constexpr Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
  Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
  Vec3& operator-=(const Vec3& o) { x -= o.x; y -= o.y; z -= o.z; return *this; }
  Vec3& operator*=(double s) { x *= s; y *= s; z *= s; return *this; }
  constexpr double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  constexpr bool operator==(const Vec3& o) const = default;

  constexpr double Dot(const Vec3& o) const { return x * o.x + y * o.y + z * o.z; }
  constexpr Vec3 Cross(const Vec3& o) const {
    return {y * o.z - z * o.y, z * o.x - x * o.z, x * o.y - y * o.x};
  }
  double Length() const { return std::sqrt(Dot(*this)); }
  constexpr double LengthSqr() const { return Dot(*this); }
  bool IsFinite() const { return std::isfinite(x) && std::isfinite(y) && std::isfinite(z); }
};

inline constexpr Vec3 operator*(double s, const Vec3& v) { return v * s; }

/// A unit quaternion (w, x, y, z) rotating body coordinates into world coordinates.
struct Quat {
  double w = 1, x = 0, y = 0, z = 0;

  /// Rotates v by this quaternion (assumed unit length).
  Vec3 Rotate(const Vec3& v) const {
    const Vec3 u{x, y, z};
    const Vec3 t = u.Cross(v) * 2.0;
    return v + t * w + u.Cross(t);
  }
  /// Rotates v by the inverse of this quaternion.
  Vec3 InverseRotate(const Vec3& v) const { return Quat{w, -x, -y, -z}.Rotate(v); }
  double Norm() const { return std::sqrt(w * w + x * x + y * y + z * z); }
  bool IsFinite() const {
    return std::isfinite(w) && std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
  }
};

}  // namespace sculpt

#endif  // SCULPT_CORE_VEC3_H_
