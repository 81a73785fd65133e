/// @brief Tool shapes: validation, signed distance, normals, bounds, surface samples and volume.
#include "sculpt/levelset/tool.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace sculpt::levelset {
namespace {

constexpr int kMinSamples = 8;
// Written as literals (not 1 -/+ 1e-3) so the bounds compare and print exactly as documented.
constexpr double kMinRotationNorm = 0.999;
constexpr double kMaxRotationNorm = 1.001;
constexpr Vec3 kFallbackNormal{0, 0, 1};
// pi * (3 - sqrt(5)) = 2 * pi * (2 - phi): the azimuth step of a Fibonacci lattice.
constexpr double kGoldenAngle = 2.0 * std::numbers::pi * (2.0 - std::numbers::phi);

/// Shortest round-trip text for v, with `nan`/`inf` spelled without a sign quirk.
std::string FormatDouble(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::array<char, 64> buf{};
  const auto result = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), result.ptr);
}

std::string Range(double lo, double hi) {
  return "[" + FormatDouble(lo) + ", " + FormatDouble(hi) + "]";
}

Status CheckFinite(const std::string& field, double v) {
  if (std::isfinite(v)) return Status::Ok();
  return NotFinite(field, FormatDouble(v));
}

Status CheckFiniteVec(const std::string& field, const Vec3& v) {
  SCULPT_RETURN_IF_ERROR(CheckFinite(field + ".x", v.x));
  SCULPT_RETURN_IF_ERROR(CheckFinite(field + ".y", v.y));
  return CheckFinite(field + ".z", v.z);
}

Status CheckInRange(const std::string& field, double v, double lo, double hi) {
  // Written as a negated conjunction so that NaN (if it ever got here) is rejected too.
  if (!(v >= lo && v <= hi)) {
    return Outside(field, FormatDouble(v), Range(lo, hi));
  }
  return Status::Ok();
}

bool IsKnownKind(ToolKind kind) {
  return static_cast<int>(kind) <= static_cast<int>(ToolKind::kCapsule);
}

/// The tool rotation scaled to unit length. Validation accepts |q| within 1e-3 of 1, but
/// Quat::Rotate scales by |q|^2, so without this the SDF, bounds and samples would disagree by up
/// to 0.2% of the tool size. A zero or non-finite quaternion falls back to the identity.
Quat UnitRotation(const Quat& q) {
  const double n = q.Norm();
  if (!(n > 0) || !std::isfinite(n)) return Quat{};
  return Quat{q.w / n, q.x / n, q.y / n, q.z / n};
}

/// Unit vector along v, or `fallback` when v is zero, denormal-small or not finite.
Vec3 NormalizeOr(const Vec3& v, const Vec3& fallback) {
  const double len = v.Length();
  if (!(len > std::numeric_limits<double>::min()) || !std::isfinite(len)) return fallback;
  const Vec3 n = v / len;
  return n.IsFinite() ? n : fallback;
}

Vec3 Abs(const Vec3& v) { return {std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}; }
Vec3 Max0(const Vec3& v) { return {std::max(v.x, 0.0), std::max(v.y, 0.0), std::max(v.z, 0.0)}; }
Vec3 Mul(const Vec3& a, const Vec3& b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
Vec3 Div(const Vec3& a, const Vec3& b) { return {a.x / b.x, a.y / b.y, a.z / b.z}; }
double MaxComponent(const Vec3& v) { return std::max({v.x, v.y, v.z}); }
double MinComponent(const Vec3& v) { return std::min({v.x, v.y, v.z}); }
double SignNonZero(double v) { return v < 0 ? -1.0 : 1.0; }

Vec3 ComponentMin(const Vec3& a, const Vec3& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
Vec3 ComponentMax(const Vec3& a, const Vec3& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}

Vec3 Axis(int i) { return {i == 0 ? 1.0 : 0.0, i == 1 ? 1.0 : 0.0, i == 2 ? 1.0 : 0.0}; }

/// Semi-axes clamped away from zero. A flat ellipsoid (only reachable with min_size=0) would
/// divide by zero in the k0/k1 estimate; a thickness of 1e-9 of the largest axis keeps it finite.
/// Returns false when every axis is zero (the ellipsoid is a point).
bool EllipsoidAxes(const ToolShape& tool, Vec3* axes) {
  const Vec3 a = Abs(tool.size);
  const double largest = MaxComponent(a);
  if (!(largest > 0)) return false;
  const double floor = 1e-9 * largest;
  *axes = {std::max(a.x, floor), std::max(a.y, floor), std::max(a.z, floor)};
  return true;
}

/// Parameter in [0, 1] of the point on segment a..a+ab closest to p (0 for a degenerate segment).
double SegmentParameter(const Vec3& ap, const Vec3& ab) {
  const double len_sqr = ab.LengthSqr();
  if (!(len_sqr > 0)) return 0.0;
  return std::clamp(ap.Dot(ab) / len_sqr, 0.0, 1.0);
}

double EllipsoidDistance(const ToolShape& tool, const Vec3& p) {
  const Vec3 local = UnitRotation(tool.rotation).InverseRotate(p - tool.center);
  Vec3 a;
  if (!EllipsoidAxes(tool, &a)) return local.Length();
  const double k0 = Div(local, a).Length();
  const double k1 = Div(local, Mul(a, a)).Length();
  // At the centre k0 = k1 = 0; the limit of k0*(k0-1)/k1 depends on the direction of approach, and
  // -min(a) (the limit along the shortest axis) is the exact distance there.
  if (!(k1 > 0)) return -MinComponent(a);
  return k0 * (k0 - 1.0) / k1;
}

double BoxDistance(const ToolShape& tool, const Vec3& p) {
  const Vec3 local = UnitRotation(tool.rotation).InverseRotate(p - tool.center);
  const Vec3 q = Abs(local) - Abs(tool.size);
  return Max0(q).Length() + std::min(MaxComponent(q), 0.0);
}

double CapsuleDistance(const ToolShape& tool, const Vec3& p) {
  const Vec3 ap = p - tool.center;
  const Vec3 ab = tool.end - tool.center;
  const double t = SegmentParameter(ap, ab);
  return (ap - ab * t).Length() - std::fabs(tool.size.x);
}

/// Analytic gradient of the ellipsoid estimate d = k0*(k0-1)/k1, scaled by k1 > 0 to keep it in
/// range: k1*grad d = (2*k0-1)*v/k0 - k0*(k0-1)*w/k1^2 with v = p/a^2 and w = p/a^4.
Vec3 EllipsoidNormal(const ToolShape& tool, const Vec3& p) {
  const Quat rot = UnitRotation(tool.rotation);
  const Vec3 local = rot.InverseRotate(p - tool.center);
  Vec3 a;
  if (!EllipsoidAxes(tool, &a)) return NormalizeOr(p - tool.center, kFallbackNormal);
  const Vec3 a2 = Mul(a, a);
  const Vec3 v = Div(local, a2);
  const Vec3 w = Div(v, a2);
  const double k0 = Div(local, a).Length();
  const double k1 = v.Length();
  if (!(k0 > 0) || !(k1 > 0)) return kFallbackNormal;
  const Vec3 g = v * ((2.0 * k0 - 1.0) / k0) - w * (k0 * (k0 - 1.0) / (k1 * k1));
  // Far away the products above can overflow; the normal of the scaled ellipsoid through p (v)
  // is the same direction in that limit.
  return rot.Rotate(NormalizeOr(g, NormalizeOr(v, kFallbackNormal)));
}

Vec3 BoxNormal(const ToolShape& tool, const Vec3& p) {
  const Quat rot = UnitRotation(tool.rotation);
  const Vec3 local = rot.InverseRotate(p - tool.center);
  const Vec3 q = Abs(local) - Abs(tool.size);
  const Vec3 sign{SignNonZero(local.x), SignNonZero(local.y), SignNonZero(local.z)};
  Vec3 g;
  if (MaxComponent(q) > 0) {
    g = Mul(Max0(q), sign);  // Outside: direction from the nearest surface point.
  } else {
    // Inside or on the surface: the face with the largest q is nearest; ties (edges, the centre
    // of a cube) go to the lowest axis so the result is deterministic.
    int axis = 0;
    if (q.y > q[axis]) axis = 1;
    if (q.z > q[axis]) axis = 2;
    g = Axis(axis) * sign[axis];
  }
  return NormalizeOr(rot.Rotate(g), kFallbackNormal);
}

/// Deterministic unit vector perpendicular to the unit vector u.
Vec3 Perpendicular(const Vec3& u) {
  const Vec3 au = Abs(u);
  int least = 0;
  if (au.y < au[least]) least = 1;
  if (au.z < au[least]) least = 2;
  return NormalizeOr(u.Cross(Axis(least)), Vec3{1, 0, 0});
}

Vec3 CapsuleNormal(const ToolShape& tool, const Vec3& p) {
  const Vec3 ap = p - tool.center;
  const Vec3 ab = tool.end - tool.center;
  const double t = SegmentParameter(ap, ab);
  // On the segment itself every direction perpendicular to it is a valid subgradient.
  const Vec3 axis = NormalizeOr(ab, Vec3{0, 0, 0});
  const Vec3 fallback = axis.LengthSqr() > 0 ? Perpendicular(axis) : kFallbackNormal;
  return NormalizeOr(ap - ab * t, fallback);
}

/// Point i of an n-point Fibonacci lattice on the unit sphere (uniform in z, golden-angle twist).
Vec3 FibonacciSphere(int i, int n) {
  const double z = 1.0 - (2.0 * i + 1.0) / n;
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double phi = kGoldenAngle * i;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

/// Point i of an n-point Fibonacci lattice on the unit upper hemisphere (z in (0, 1)).
Vec3 FibonacciHemisphere(int i, int n) {
  const double z = 1.0 - (i + 0.5) / n;
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double phi = kGoldenAngle * i;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

std::vector<Vec3> EllipsoidSamples(const ToolShape& tool, int count) {
  // A sphere has no orientation: its rotation field is not validated, so it is not used.
  const bool sphere = tool.kind == ToolKind::kSphere;
  const Quat rot = sphere ? Quat{} : UnitRotation(tool.rotation);
  const Vec3 axes = Abs(sphere ? Vec3{tool.size.x, tool.size.x, tool.size.x} : tool.size);
  std::vector<Vec3> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) {
    out.push_back(tool.center + rot.Rotate(Mul(FibonacciSphere(i, count), axes)));
  }
  return out;
}

/// Points on the box boundary of an n[0] x n[1] x n[2] lattice spanning the box.
int64_t BoxBoundaryCount(const std::array<int64_t, 3>& n) {
  return n[0] * n[1] * n[2] - std::max<int64_t>(n[0] - 2, 0) * std::max<int64_t>(n[1] - 2, 0) *
                                  std::max<int64_t>(n[2] - 2, 0);
}

double LatticeCoordinate(int64_t i, int64_t n, double h) {
  // The end points are assigned directly so the faces are hit exactly, not up to rounding.
  if (i == 0) return -h;
  if (i == n - 1) return h;
  return -h + 2.0 * h * static_cast<double>(i) / static_cast<double>(n - 1);
}

std::vector<Vec3> BoxSamples(const ToolShape& tool, int count) {
  const Quat rot = UnitRotation(tool.rotation);
  const Vec3 h = Abs(tool.size);
  // Refine the coarsest axis one lattice line at a time: spacing stays near-isotropic, so each
  // face gets points in proportion to its area, and the lattice always includes the edges and
  // corners. Once refining the coarsest axis would overshoot the request (on a thin box that adds
  // a whole long face strip, up to +50%), finer axes that still fit are refined instead, and the
  // last step is the smallest overshoot if that lands closer than stopping short.
  std::array<int64_t, 3> n{2, 2, 2};
  int64_t total = BoxBoundaryCount(n);
  while (total < count) {
    std::array<int, 3> by_spacing{0, 1, 2};
    std::stable_sort(by_spacing.begin(), by_spacing.end(), [&](int a, int b) {
      return h[a] / static_cast<double>(n[a] - 1) > h[b] / static_cast<double>(n[b] - 1);
    });
    int fitting_axis = -1;
    int smallest_axis = by_spacing[0];
    int64_t smallest_total = std::numeric_limits<int64_t>::max();
    for (int axis : by_spacing) {
      std::array<int64_t, 3> next = n;
      ++next[axis];
      const int64_t next_total = BoxBoundaryCount(next);
      if (next_total <= count) {
        fitting_axis = axis;
        break;
      }
      if (next_total < smallest_total) {
        smallest_total = next_total;
        smallest_axis = axis;
      }
    }
    if (fitting_axis >= 0) {
      ++n[fitting_axis];
      total = BoxBoundaryCount(n);
      continue;
    }
    if (smallest_total - count < count - total) {
      ++n[smallest_axis];
      total = smallest_total;
    }
    break;
  }
  std::vector<Vec3> out;
  out.reserve(static_cast<size_t>(total));
  for (int64_t i = 0; i < n[0]; ++i) {
    const double x = LatticeCoordinate(i, n[0], h.x);
    const bool i_face = i == 0 || i == n[0] - 1;
    for (int64_t j = 0; j < n[1]; ++j) {
      const double y = LatticeCoordinate(j, n[1], h.y);
      const bool ij_face = i_face || j == 0 || j == n[1] - 1;
      // Off the x and y faces only the two z faces are on the boundary.
      const int64_t k_step = ij_face ? 1 : std::max<int64_t>(n[2] - 1, 1);
      for (int64_t k = 0; k < n[2]; k += k_step) {
        const double z = LatticeCoordinate(k, n[2], h.z);
        out.push_back(tool.center + rot.Rotate(Vec3{x, y, z}));
      }
    }
  }
  return out;
}

std::vector<Vec3> CapsuleSamples(const ToolShape& tool, int count) {
  const double r = std::fabs(tool.size.x);
  const Vec3 ab = tool.end - tool.center;
  const double length = ab.Length();
  // A zero-length capsule is a sphere; any axis works, +z is used for determinism.
  const Vec3 u = NormalizeOr(ab, kFallbackNormal);
  const Vec3 e1 = Perpendicular(u);
  const Vec3 e2 = u.Cross(e1);

  // Share the budget by area: cylinder 2*pi*r*L, the two hemispheres 4*pi*r^2.
  const double denom = length + 2.0 * r;
  const double cylinder_share = denom > 0 ? length / denom : 0.0;
  const double cylinder_target = count * cylinder_share;
  int ring_points = 3;
  if (r > 0) {
    const double spacing = std::sqrt(2.0 * std::numbers::pi * r * denom / count);
    ring_points =
        std::max<int>(3, static_cast<int>(std::lround(2.0 * std::numbers::pi * r / spacing)));
  }
  const int rings = static_cast<int>(std::lround(cylinder_target / ring_points));
  const int cylinder_count = rings * ring_points;
  int per_cap = std::max(1, static_cast<int>(std::lround((count - cylinder_count) / 2.0)));
  per_cap = std::max(per_cap, (kMinSamples - cylinder_count + 1) / 2);

  std::vector<Vec3> out;
  out.reserve(static_cast<size_t>(cylinder_count + 2 * per_cap));
  for (int j = 0; j < rings; ++j) {
    // With a single ring put it mid-way; otherwise the end rings sit on the cap seams.
    const double t = rings == 1 ? 0.5 : static_cast<double>(j) / (rings - 1);
    const Vec3 on_axis = tool.center + ab * t;
    for (int q = 0; q < ring_points; ++q) {
      // Alternate rings are staggered by half a step so the lattice is closer to hexagonal.
      const double angle = 2.0 * std::numbers::pi * (q + 0.5 * (j % 2)) / ring_points;
      out.push_back(on_axis + (e1 * std::cos(angle) + e2 * std::sin(angle)) * r);
    }
  }
  for (int i = 0; i < per_cap; ++i) {
    const Vec3 d = FibonacciHemisphere(i, per_cap);
    out.push_back(tool.end + (u * d.z + e1 * d.x + e2 * d.y) * r);
    out.push_back(tool.center + (-u * d.z + e1 * d.x - e2 * d.y) * r);
  }
  return out;
}

}  // namespace

const char* ToolKindName(ToolKind kind) {
  switch (kind) {
    case ToolKind::kSphere:
      return "sphere";
    case ToolKind::kEllipsoid:
      return "ellipsoid";
    case ToolKind::kBox:
      return "box";
    case ToolKind::kCapsule:
      return "capsule";
  }
  return "unknown";
}

ToolShape ToolShape::Sphere(Vec3 c, double r) {
  ToolShape t;
  t.kind = ToolKind::kSphere;
  t.center = c;
  t.size = {r, r, r};
  t.end = c;
  return t;
}

ToolShape ToolShape::Ellipsoid(Vec3 c, Vec3 semi_axes, Quat rot) {
  ToolShape t;
  t.kind = ToolKind::kEllipsoid;
  t.center = c;
  t.size = semi_axes;
  t.rotation = rot;
  t.end = c;
  return t;
}

ToolShape ToolShape::Box(Vec3 c, Vec3 half_extents, Quat rot) {
  ToolShape t;
  t.kind = ToolKind::kBox;
  t.center = c;
  t.size = half_extents;
  t.rotation = rot;
  t.end = c;
  return t;
}

ToolShape ToolShape::Capsule(Vec3 a, Vec3 b, double r) {
  ToolShape t;
  t.kind = ToolKind::kCapsule;
  t.center = a;
  t.size = {r, r, r};
  t.end = b;
  return t;
}

Status ValidateTool(const ToolShape& tool, double min_size, double max_size) {
  if (!(min_size >= 0 && min_size <= max_size)) {
    return InvalidArgument("tool size range " + Range(min_size, max_size) + " is not valid");
  }
  if (!IsKnownKind(tool.kind)) {
    return Outside(
        "tool.kind", std::to_string(static_cast<int>(tool.kind)),
        std::string("[0, ") + std::to_string(static_cast<int>(ToolKind::kCapsule)) + "]");
  }
  SCULPT_RETURN_IF_ERROR(CheckFiniteVec("tool.center", tool.center));
  SCULPT_RETURN_IF_ERROR(CheckFiniteVec("tool.size", tool.size));
  SCULPT_RETURN_IF_ERROR(CheckFinite("tool.rotation.w", tool.rotation.w));
  SCULPT_RETURN_IF_ERROR(CheckFinite("tool.rotation.x", tool.rotation.x));
  SCULPT_RETURN_IF_ERROR(CheckFinite("tool.rotation.y", tool.rotation.y));
  SCULPT_RETURN_IF_ERROR(CheckFinite("tool.rotation.z", tool.rotation.z));
  SCULPT_RETURN_IF_ERROR(CheckFiniteVec("tool.end", tool.end));

  switch (tool.kind) {
    case ToolKind::kSphere:
      return CheckInRange("tool.size.x", tool.size.x, min_size, max_size);
    case ToolKind::kCapsule:
      // Finite end points can still be so far apart that end - center overflows.
      SCULPT_RETURN_IF_ERROR(CheckFinite("tool.capsule length", (tool.end - tool.center).Length()));
      return CheckInRange("tool.size.x", tool.size.x, min_size, max_size);
    case ToolKind::kEllipsoid:
    case ToolKind::kBox: {
      SCULPT_RETURN_IF_ERROR(CheckInRange("tool.size.x", tool.size.x, min_size, max_size));
      SCULPT_RETURN_IF_ERROR(CheckInRange("tool.size.y", tool.size.y, min_size, max_size));
      SCULPT_RETURN_IF_ERROR(CheckInRange("tool.size.z", tool.size.z, min_size, max_size));
      return CheckInRange("tool.rotation norm", tool.rotation.Norm(), kMinRotationNorm,
                          kMaxRotationNorm);
    }
  }
  return Status::Ok();
}

double ToolSignedDistance(const ToolShape& tool, const Vec3& p) {
  switch (tool.kind) {
    case ToolKind::kSphere:
      return (p - tool.center).Length() - std::fabs(tool.size.x);
    case ToolKind::kEllipsoid:
      return EllipsoidDistance(tool, p);
    case ToolKind::kBox:
      return BoxDistance(tool, p);
    case ToolKind::kCapsule:
      return CapsuleDistance(tool, p);
  }
  // An unknown kind has no interior: nothing is ever inside it.
  return std::numeric_limits<double>::infinity();
}

Vec3 ToolNormal(const ToolShape& tool, const Vec3& p) {
  switch (tool.kind) {
    case ToolKind::kSphere:
      return NormalizeOr(p - tool.center, kFallbackNormal);
    case ToolKind::kEllipsoid:
      return EllipsoidNormal(tool, p);
    case ToolKind::kBox:
      return BoxNormal(tool, p);
    case ToolKind::kCapsule:
      return CapsuleNormal(tool, p);
  }
  return kFallbackNormal;
}

Aabb ToolBounds(const ToolShape& tool) {
  switch (tool.kind) {
    case ToolKind::kSphere: {
      const double r = std::fabs(tool.size.x);
      return {tool.center - Vec3{r, r, r}, tool.center + Vec3{r, r, r}};
    }
    case ToolKind::kEllipsoid:
    case ToolKind::kBox: {
      const Quat rot = UnitRotation(tool.rotation);
      const Vec3 s = Abs(tool.size);
      // Columns of the body->world matrix R, scaled by the semi-axes / half-extents.
      const Vec3 c0 = rot.Rotate(Axis(0)) * s.x;
      const Vec3 c1 = rot.Rotate(Axis(1)) * s.y;
      const Vec3 c2 = rot.Rotate(Axis(2)) * s.z;
      Vec3 extent;
      if (tool.kind == ToolKind::kEllipsoid) {
        // Support of an ellipsoid along e_i: sqrt(sum_j (R_ij a_j)^2).
        extent = {std::sqrt(c0.x * c0.x + c1.x * c1.x + c2.x * c2.x),
                  std::sqrt(c0.y * c0.y + c1.y * c1.y + c2.y * c2.y),
                  std::sqrt(c0.z * c0.z + c1.z * c1.z + c2.z * c2.z)};
      } else {
        // The farthest of the 8 rotated corners along e_i: sum_j |R_ij h_j|.
        extent = Abs(c0) + Abs(c1) + Abs(c2);
      }
      return {tool.center - extent, tool.center + extent};
    }
    case ToolKind::kCapsule: {
      const double r = std::fabs(tool.size.x);
      const Vec3 rv{r, r, r};
      return {ComponentMin(tool.center, tool.end) - rv, ComponentMax(tool.center, tool.end) + rv};
    }
  }
  // Inverted bounds: Overlaps() is false against everything.
  const double inf = std::numeric_limits<double>::infinity();
  return {Vec3{inf, inf, inf}, Vec3{-inf, -inf, -inf}};
}

std::vector<Vec3> ToolSurfaceSamples(const ToolShape& tool, int count) {
  count = std::max(count, kMinSamples);
  switch (tool.kind) {
    case ToolKind::kSphere:
    case ToolKind::kEllipsoid:
      return EllipsoidSamples(tool, count);
    case ToolKind::kBox:
      return BoxSamples(tool, count);
    case ToolKind::kCapsule:
      return CapsuleSamples(tool, count);
  }
  return {};  // An unknown kind has no surface.
}

double ToolVolume(const ToolShape& tool) {
  constexpr double kFourThirdsPi = 4.0 / 3.0 * std::numbers::pi;
  const Vec3 s = Abs(tool.size);
  switch (tool.kind) {
    case ToolKind::kSphere:
      return kFourThirdsPi * s.x * s.x * s.x;
    case ToolKind::kEllipsoid:
      return kFourThirdsPi * s.x * s.y * s.z;
    case ToolKind::kBox:
      return 8.0 * s.x * s.y * s.z;
    case ToolKind::kCapsule: {
      const double length = (tool.end - tool.center).Length();
      return std::numbers::pi * s.x * s.x * length + kFourThirdsPi * s.x * s.x * s.x;
    }
  }
  return 0.0;
}

}  // namespace sculpt::levelset
