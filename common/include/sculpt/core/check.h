/// @brief Range checks whose errors name the field, the value and the allowed range, shared by
/// every validator (kernel parameters, scene configuration).
#ifndef SCULPT_CORE_CHECK_H_
#define SCULPT_CORE_CHECK_H_

#include <cmath>
#include <sstream>
#include <string>
#include <utility>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"

namespace sculpt {

/// Shortest round-trip-ish text of a number ("0.5", "-1", "nan", "inf").
inline std::string FormatNumber(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

/// InvalidArgument "`field`=v is not finite" or "`field`=v outside [lo, hi]" with that field
/// violation, else Ok.
inline Status CheckRange(const std::string& field, double v, double lo, double hi) {
  if (!std::isfinite(v)) {
    return NotFinite(field, FormatNumber(v));
  }
  if (v < lo || v > hi) {
    // Appended rather than `"[" + ...`: g++ 12 reports a false -Wrestrict (GCC bug 105329) on
    // `const char* + std::string&&` inlined here.
    std::string range = "[";
    range += FormatNumber(lo);
    range += ", ";
    range += FormatNumber(hi);
    range += "]";
    return Outside(field, FormatNumber(v), std::move(range));
  }
  return Status::Ok();
}

/// InvalidArgument "`field`=(x, y, z) is not finite" for a point with a NaN or Inf coordinate.
inline Status CheckFinitePoint(const std::string& field, const Vec3& p) {
  if (!p.IsFinite()) {
    std::string value = "(";
    value += FormatNumber(p.x);
    value += ", ";
    value += FormatNumber(p.y);
    value += ", ";
    value += FormatNumber(p.z);
    value += ")";
    return NotFinite(field, std::move(value));
  }
  return Status::Ok();
}

}  // namespace sculpt

#endif  // SCULPT_CORE_CHECK_H_
