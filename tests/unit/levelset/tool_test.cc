/// @brief Unit tests for tool shapes: validation, SDF, normals, bounds, samples and volume.
#include "sculpt/levelset/tool.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace sculpt::levelset {
namespace {

constexpr double kMinSize = 0.5;
constexpr double kMaxSize = 64;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = std::numbers::pi;

Quat AxisAngle(Vec3 axis, double angle) {
  axis = axis / axis.Length();
  const double s = std::sin(angle / 2);
  return {std::cos(angle / 2), axis.x * s, axis.y * s, axis.z * s};
}

struct NamedTool {
  std::string name;
  ToolShape tool;
};

/// One representative of each kind plus the awkward cases (rotations, zero-length capsule, a
/// long thin box), all valid for [kMinSize, kMaxSize].
std::vector<NamedTool> Tools() {
  return {
      {"sphere", ToolShape::Sphere({1, 2, 3}, 2)},
      {"ellipsoid", ToolShape::Ellipsoid({-1, 0.5, 2}, {3, 2, 1})},
      {"rotated_ellipsoid",
       ToolShape::Ellipsoid({-1, 0.5, 2}, {3, 2, 1}, AxisAngle({1, 2, 0.5}, 0.7))},
      {"box", ToolShape::Box({0, 0, 0}, {4, 2, 1})},
      {"rotated_box", ToolShape::Box({5, -1, 2}, {1, 2, 3}, AxisAngle({0.3, -1, 2}, 1.1))},
      {"thin_box", ToolShape::Box({0, 1, 0}, {10, 0.5, 0.5}, AxisAngle({0, 0, 1}, 0.3))},
      {"long_box", ToolShape::Box({0, 0, 0}, {64, 0.5, 0.5})},
      {"capsule", ToolShape::Capsule({0, 0, 0}, {4, 3, -2}, 1.5)},
      {"axis_capsule", ToolShape::Capsule({1, 1, 1}, {1, 1, 9}, 1)},
      {"zero_length_capsule", ToolShape::Capsule({2, 2, 2}, {2, 2, 2}, 1.25)},
  };
}

/// A length on the order of the tool, for scaling tolerances.
double Scale(const ToolShape& tool) {
  const Aabb b = ToolBounds(tool);
  return (b.max - b.min).Length();
}

Vec3 RandomPoint(std::mt19937_64& rng, const Vec3& lo, const Vec3& hi) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double x = u(rng), y = u(rng), z = u(rng);
  return {lo.x + (hi.x - lo.x) * x, lo.y + (hi.y - lo.y) * y, lo.z + (hi.z - lo.z) * z};
}

void ExpectInvalid(const ToolShape& tool, const std::string& message) {
  const Status s = ValidateTool(tool, kMinSize, kMaxSize);
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_EQ(s.message(), message);
}

// --- Names and factories ------------------------------------------------------------------------

TEST(ToolTest, KindNameNamesEveryKind) {
  EXPECT_STREQ(ToolKindName(ToolKind::kSphere), "sphere");
  EXPECT_STREQ(ToolKindName(ToolKind::kEllipsoid), "ellipsoid");
  EXPECT_STREQ(ToolKindName(ToolKind::kBox), "box");
  EXPECT_STREQ(ToolKindName(ToolKind::kCapsule), "capsule");
  EXPECT_STREQ(ToolKindName(static_cast<ToolKind>(7)), "unknown");
}

TEST(ToolTest, FactoriesFillTheDocumentedFields) {
  const Quat q = AxisAngle({0, 1, 0}, 0.5);
  const ToolShape s = ToolShape::Sphere({1, 2, 3}, 4);
  EXPECT_EQ(s.kind, ToolKind::kSphere);
  EXPECT_EQ(s.center, (Vec3{1, 2, 3}));
  EXPECT_EQ(s.size.x, 4);
  const ToolShape e = ToolShape::Ellipsoid({1, 2, 3}, {4, 5, 6}, q);
  EXPECT_EQ(e.kind, ToolKind::kEllipsoid);
  EXPECT_EQ(e.size, (Vec3{4, 5, 6}));
  EXPECT_EQ(e.rotation.w, q.w);
  EXPECT_EQ(e.rotation.y, q.y);
  const ToolShape b = ToolShape::Box({1, 2, 3}, {4, 5, 6});
  EXPECT_EQ(b.kind, ToolKind::kBox);
  EXPECT_EQ(b.size, (Vec3{4, 5, 6}));
  EXPECT_EQ(b.rotation.w, 1);
  const ToolShape c = ToolShape::Capsule({1, 2, 3}, {7, 8, 9}, 2);
  EXPECT_EQ(c.kind, ToolKind::kCapsule);
  EXPECT_EQ(c.center, (Vec3{1, 2, 3}));
  EXPECT_EQ(c.end, (Vec3{7, 8, 9}));
  EXPECT_EQ(c.size.x, 2);
}

// --- Validation ---------------------------------------------------------------------------------

TEST(ToolTest, AcceptsValidToolsOfEveryKind) {
  for (const NamedTool& t : Tools()) {
    EXPECT_TRUE(ValidateTool(t.tool, kMinSize, kMaxSize).ok()) << t.name;
  }
}

TEST(ToolTest, AcceptsSizesAtTheRangeLimits) {
  EXPECT_TRUE(ValidateTool(ToolShape::Box({}, {0.5, 64, 0.5}), kMinSize, kMaxSize).ok());
  EXPECT_TRUE(ValidateTool(ToolShape::Sphere({}, 64), kMinSize, kMaxSize).ok());
}

TEST(ToolTest, RejectsNanCenter) {
  ExpectInvalid(ToolShape::Sphere({0, kNan, 0}, 1), "tool.center.y=nan is not finite");
}

TEST(ToolTest, RejectsInfiniteSize) {
  ExpectInvalid(ToolShape::Ellipsoid({}, {1, 1, kInf}), "tool.size.z=inf is not finite");
}

TEST(ToolTest, RejectsNanRotation) {
  ToolShape t = ToolShape::Box({}, {1, 1, 1});
  t.rotation.x = kNan;
  ExpectInvalid(t, "tool.rotation.x=nan is not finite");
}

TEST(ToolTest, RejectsInfiniteCapsuleEnd) {
  ExpectInvalid(ToolShape::Capsule({}, {-kInf, 0, 0}, 1), "tool.end.x=-inf is not finite");
}

TEST(ToolTest, RejectsNonFiniteFieldEvenWhenTheKindIgnoresIt) {
  ToolShape t = ToolShape::Sphere({}, 1);
  t.end.z = kNan;
  ExpectInvalid(t, "tool.end.z=nan is not finite");
  t = ToolShape::Sphere({}, 1);
  t.size.y = kInf;
  ExpectInvalid(t, "tool.size.y=inf is not finite");
}

TEST(ToolTest, RejectsNegativeRadius) {
  ExpectInvalid(ToolShape::Sphere({}, -1), "tool.size.x=-1 outside [0.5, 64]");
  ExpectInvalid(ToolShape::Capsule({}, {1, 0, 0}, -1), "tool.size.x=-1 outside [0.5, 64]");
}

TEST(ToolTest, RejectsZeroBoxHalfExtent) {
  ExpectInvalid(ToolShape::Box({}, {1, 0, 1}), "tool.size.y=0 outside [0.5, 64]");
}

TEST(ToolTest, RejectsTooLargeEllipsoidAxis) {
  ExpectInvalid(ToolShape::Ellipsoid({}, {1, 1, 65}), "tool.size.z=65 outside [0.5, 64]");
}

TEST(ToolTest, RejectsTooSmallRadius) {
  ExpectInvalid(ToolShape::Sphere({}, 0.25), "tool.size.x=0.25 outside [0.5, 64]");
}

TEST(ToolTest, IgnoresSizeComponentsUnusedByTheKind) {
  ToolShape s = ToolShape::Sphere({}, 2);
  s.size.y = 0;
  s.size.z = 1000;
  EXPECT_TRUE(ValidateTool(s, kMinSize, kMaxSize).ok());
  ToolShape c = ToolShape::Capsule({}, {0, 0, 100}, 2);
  c.size.y = -5;
  EXPECT_TRUE(ValidateTool(c, kMinSize, kMaxSize).ok());
}

TEST(ToolTest, RejectsNonUnitQuaternion) {
  ExpectInvalid(ToolShape::Box({}, {1, 1, 1}, Quat{0.5, 0, 0, 0}),
                "tool.rotation norm=0.5 outside [0.999, 1.001]");
  ExpectInvalid(ToolShape::Ellipsoid({}, {1, 1, 1}, Quat{0, 0, 0, 0}),
                "tool.rotation norm=0 outside [0.999, 1.001]");
  ExpectInvalid(ToolShape::Ellipsoid({}, {1, 1, 1}, Quat{1.002, 0, 0, 0}),
                "tool.rotation norm=1.002 outside [0.999, 1.001]");
}

TEST(ToolTest, AcceptsQuaternionWithinTolerance) {
  EXPECT_TRUE(
      ValidateTool(ToolShape::Box({}, {1, 1, 1}, Quat{1.0009, 0, 0, 0}), kMinSize, kMaxSize).ok());
  EXPECT_TRUE(
      ValidateTool(ToolShape::Ellipsoid({}, {1, 1, 1}, Quat{0.9991, 0, 0, 0}), kMinSize, kMaxSize)
          .ok());
}

TEST(ToolTest, DoesNotRequireUnitRotationForSphereOrCapsule) {
  ToolShape s = ToolShape::Sphere({}, 1);
  s.rotation = Quat{0, 0, 0, 0};
  EXPECT_TRUE(ValidateTool(s, kMinSize, kMaxSize).ok());
  ToolShape c = ToolShape::Capsule({}, {1, 0, 0}, 1);
  c.rotation = Quat{3, 0, 0, 0};
  EXPECT_TRUE(ValidateTool(c, kMinSize, kMaxSize).ok());
}

TEST(ToolTest, RejectsBadKind) {
  ToolShape t = ToolShape::Sphere({}, 1);
  t.kind = static_cast<ToolKind>(7);
  ExpectInvalid(t, "tool.kind=7 outside [0, 3]");
  t.kind = static_cast<ToolKind>(255);
  ExpectInvalid(t, "tool.kind=255 outside [0, 3]");
}

TEST(ToolTest, RejectsCapsuleWhoseLengthOverflows) {
  ExpectInvalid(ToolShape::Capsule({-1e308, 0, 0}, {1e308, 0, 0}, 1),
                "tool.capsule length=inf is not finite");
}

TEST(ToolTest, RejectsInvalidSizeRange) {
  const ToolShape t = ToolShape::Sphere({}, 1);
  EXPECT_EQ(ValidateTool(t, 2, 1).code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(ValidateTool(t, kNan, 64).code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(ValidateTool(t, -1, 64).code(), Status::Code::kInvalidArgument);
  EXPECT_NE(ValidateTool(t, 2, 1).message().find("[2, 1]"), std::string::npos);
  EXPECT_TRUE(ValidateTool(t, 0, kInf).ok());
}

// --- Signed distance ----------------------------------------------------------------------------

TEST(ToolTest, SphereSdfKnownValues) {
  const ToolShape s = ToolShape::Sphere({1, 2, 3}, 2);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(s, {1, 2, 3}), -2);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(s, {3, 2, 3}), 0);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(s, {1, 2, 8}), 3);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(s, {1, 1, 3}), -1);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(s, {4, 6, 3}), 3);
}

TEST(ToolTest, EllipsoidSdfIsExactOnTheAxes) {
  const Vec3 a{3, 2, 1};
  const Vec3 c{-1, 0.5, 2};
  const Quat q = AxisAngle({1, 2, 0.5}, 0.7);
  const ToolShape e = ToolShape::Ellipsoid(c, a, q);
  EXPECT_NEAR(ToolSignedDistance(e, c), -1, 1e-12) << "centre: minus the shortest semi-axis";
  const Vec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int j = 0; j < 3; ++j) {
    for (double f : {-3.0, -1.5, -1.0, -0.5, 0.25, 0.5, 1.0, 1.5, 3.0}) {
      const double t = f * a[j];
      const Vec3 p = c + q.Rotate(axes[j] * t);
      EXPECT_NEAR(ToolSignedDistance(e, p), std::fabs(t) - a[j], 1e-12)
          << "axis " << j << " t=" << t;
    }
  }
}

TEST(ToolTest, EllipsoidSdfSignAndZeroSetMatchTheImplicitSurface) {
  const Vec3 a{3, 2, 1};
  const Vec3 c{-1, 0.5, 2};
  const Quat q = AxisAngle({1, 2, 0.5}, 0.7);
  const ToolShape e = ToolShape::Ellipsoid(c, a, q);
  std::mt19937_64 rng(7);
  int inside = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p = RandomPoint(rng, c - Vec3{4, 4, 4}, c + Vec3{4, 4, 4});
    const Vec3 l = q.InverseRotate(p - c);
    const double f =
        (l.x / a.x) * (l.x / a.x) + (l.y / a.y) * (l.y / a.y) + (l.z / a.z) * (l.z / a.z) - 1.0;
    if (std::fabs(f) < 1e-9) continue;
    const double d = ToolSignedDistance(e, p);
    EXPECT_EQ(d < 0, f < 0) << "p=(" << p.x << ", " << p.y << ", " << p.z << ") d=" << d;
    inside += d < 0;
  }
  EXPECT_GT(inside, 0);
}

/// Exact distance from a point outside an axis-aligned ellipsoid at the origin to its surface.
/// The nearest point is x_i = a_i^2 y_i / (t + a_i^2) for the root t > 0 of
/// sum_i (a_i y_i / (t + a_i^2))^2 = 1, found by bisection (the sum decreases in t).
double ExactOutsideEllipsoidDistance(const Vec3& a, const Vec3& p) {
  const Vec3 y{std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)};
  const auto f = [&](double t) {
    double sum = 0;
    for (int i = 0; i < 3; ++i) {
      const double q = a[i] * y[i] / (t + a[i] * a[i]);
      sum += q * q;
    }
    return sum - 1;
  };
  const double a_max = std::max({a.x, a.y, a.z});
  double lo = 0, hi = y.Length() * a_max + a_max * a_max;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    if (f(mid) > 0) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  const double t = 0.5 * (lo + hi);
  const Vec3 a2{a.x * a.x, a.y * a.y, a.z * a.z};
  const Vec3 x{a2.x * y.x / (t + a2.x), a2.y * y.y / (t + a2.y), a2.z * y.z / (t + a2.z)};
  return (x - y).Length();
}

TEST(ToolTest, EllipsoidSdfNeverOvershootsTheTrueDistanceOutside) {
  // A mask built from the SDF must not miss voxels: outside, the estimate must be a lower bound
  // of the true distance. It is tight for moderate aspect ratios only (a 128:1 needle gets as low
  // as 2% of the true distance beside it), so tightness is checked up to 4:1.
  struct Case {
    Vec3 a;
    double min_ratio;
  };
  for (const Case& c : {Case{{4, 1, 2}, 0.5}, Case{{3, 2, 1}, 0.5}, Case{{64, 0.5, 0.5}, 0.0}}) {
    const ToolShape e = ToolShape::Ellipsoid({0, 0, 0}, c.a);
    std::mt19937_64 rng(11);
    int outside = 0;
    for (int i = 0; i < 2000; ++i) {
      const Vec3 p = RandomPoint(rng, c.a * -2.0, c.a * 2.0);
      const double d = ToolSignedDistance(e, p);
      if (d <= 0) continue;
      ++outside;
      const double exact = ExactOutsideEllipsoidDistance(c.a, p);
      EXPECT_LE(d, exact + 1e-9 * c.a.x) << "a=(" << c.a.x << ", " << c.a.y << ", " << c.a.z << ")";
      EXPECT_GE(d, c.min_ratio * exact) << "a=(" << c.a.x << ", " << c.a.y << ", " << c.a.z << ")";
    }
    EXPECT_GT(outside, 100);
  }
}

TEST(ToolTest, BoxSdfKnownValues) {
  const ToolShape b = ToolShape::Box({0, 0, 0}, {1, 2, 3});
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {0, 0, 0}), -1);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {0.5, 0, 0}), -0.5);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {0, 0, 2.5}), -0.5);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {1, 0, 0}), 0);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {1, 2, 3}), 0);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {3, 0, 0}), 2);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {0, -5, 0}), 3);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {2, 3, 4}), std::sqrt(3.0));
  EXPECT_DOUBLE_EQ(ToolSignedDistance(b, {-4, -6, 3}), 5);
}

TEST(ToolTest, RotatedBoxSdfAtCornerAndAlongBodyAxes) {
  const Vec3 c{5, -1, 2};
  const Vec3 h{1, 2, 3};
  const Quat q = AxisAngle({0, 0, 1}, kPi / 4);
  const ToolShape b = ToolShape::Box(c, h, q);
  EXPECT_NEAR(ToolSignedDistance(b, c), -1, 1e-12);
  EXPECT_NEAR(ToolSignedDistance(b, c + q.Rotate({1, 2, 3})), 0, 1e-12);
  EXPECT_NEAR(ToolSignedDistance(b, c + q.Rotate({-1, 2, -3})), 0, 1e-12);
  EXPECT_NEAR(ToolSignedDistance(b, c + q.Rotate({2, 3, 4})), std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(ToolSignedDistance(b, c + q.Rotate({0, 2.5, 0})), 0.5, 1e-12);
  // A world-axis point that an unrotated box would contain is outside the rotated one.
  // In the body frame it is (2.5, 2.5, 0) / sqrt(2): past the x face, inside the y slab.
  EXPECT_NEAR(ToolSignedDistance(b, c + Vec3{0, 2.5, 0}), 2.5 * std::sqrt(0.5) - 1, 1e-12);
}

TEST(ToolTest, RotatedBoxSdfEqualsAlignedBoxSdfInTheBodyFrame) {
  const Vec3 c{5, -1, 2};
  const Vec3 h{1, 2, 3};
  const Quat q = AxisAngle({0.3, -1, 2}, 1.1);
  const ToolShape rotated = ToolShape::Box(c, h, q);
  const ToolShape aligned = ToolShape::Box({0, 0, 0}, h);
  std::mt19937_64 rng(3);
  for (int i = 0; i < 1000; ++i) {
    const Vec3 body = RandomPoint(rng, {-5, -5, -5}, {5, 5, 5});
    EXPECT_NEAR(ToolSignedDistance(rotated, c + q.Rotate(body)), ToolSignedDistance(aligned, body),
                1e-12);
  }
}

TEST(ToolTest, CapsuleSdfKnownValues) {
  const ToolShape c = ToolShape::Capsule({0, 0, 0}, {4, 0, 0}, 1);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {2, 0, 0}), -1);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {0, 0, 0}), -1);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {2, 3, 0}), 2);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {2, 0, -1}), 0);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {5, 0, 0}), 0);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {-2, 0, 0}), 1);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {7, 4, 0}), 4);
  EXPECT_DOUBLE_EQ(ToolSignedDistance(c, {-1, -1, -1}), std::sqrt(3.0) - 1);
}

TEST(ToolTest, ZeroLengthCapsuleIsASphere) {
  const ToolShape capsule = ToolShape::Capsule({2, 2, 2}, {2, 2, 2}, 1.25);
  const ToolShape sphere = ToolShape::Sphere({2, 2, 2}, 1.25);
  std::mt19937_64 rng(5);
  for (int i = 0; i < 500; ++i) {
    const Vec3 p = RandomPoint(rng, {-1, -1, -1}, {5, 5, 5});
    EXPECT_NEAR(ToolSignedDistance(capsule, p), ToolSignedDistance(sphere, p), 1e-12);
    const Vec3 nc = ToolNormal(capsule, p);
    const Vec3 ns = ToolNormal(sphere, p);
    EXPECT_NEAR((nc - ns).Length(), 0, 1e-12);
  }
  EXPECT_DOUBLE_EQ(ToolVolume(capsule), ToolVolume(sphere));
  EXPECT_TRUE(ToolNormal(capsule, {2, 2, 2}).IsFinite());
}

TEST(ToolTest, UnknownKindHasNoInteriorAndNoSurface) {
  ToolShape t = ToolShape::Sphere({}, 1);
  t.kind = static_cast<ToolKind>(9);
  EXPECT_GT(ToolSignedDistance(t, {0, 0, 0}), 0);
  EXPECT_TRUE(ToolSurfaceSamples(t, 100).empty());
  EXPECT_EQ(ToolVolume(t), 0);
  EXPECT_FALSE(ToolBounds(t).Overlaps(Aabb{{-1e9, -1e9, -1e9}, {1e9, 1e9, 1e9}}));
  EXPECT_NEAR(ToolNormal(t, {1, 0, 0}).Length(), 1, 1e-12);
}

// --- Normals ------------------------------------------------------------------------------------

TEST(ToolTest, SphereNormalIsRadialAndUnit) {
  const Vec3 c{1, 2, 3};
  const ToolShape s = ToolShape::Sphere(c, 2);
  std::mt19937_64 rng(13);
  for (int i = 0; i < 1000; ++i) {
    const Vec3 p = RandomPoint(rng, {-4, -3, -2}, {6, 7, 8});
    const Vec3 n = ToolNormal(s, p);
    const Vec3 radial = (p - c) / (p - c).Length();
    EXPECT_NEAR(n.Length(), 1, 1e-12);
    EXPECT_NEAR((n - radial).Length(), 0, 1e-12);
  }
}

TEST(ToolTest, NormalsAreUnitAndMatchTheSdfGradient) {
  std::mt19937_64 rng(17);
  for (const NamedTool& t : Tools()) {
    const Aabb b = ToolBounds(t.tool);
    const double scale = Scale(t.tool);
    const Vec3 pad = Vec3{1, 1, 1} * (0.5 * scale);
    const double h = 1e-6 * scale;
    for (int i = 0; i < 2000; ++i) {
      const Vec3 p = RandomPoint(rng, b.min - pad, b.max + pad);
      const Vec3 n = ToolNormal(t.tool, p);
      ASSERT_TRUE(n.IsFinite()) << t.name;
      EXPECT_NEAR(n.Length(), 1, 1e-12) << t.name;
      const Vec3 g{ToolSignedDistance(t.tool, p + Vec3{h, 0, 0}) -
                       ToolSignedDistance(t.tool, p - Vec3{h, 0, 0}),
                   ToolSignedDistance(t.tool, p + Vec3{0, h, 0}) -
                       ToolSignedDistance(t.tool, p - Vec3{0, h, 0}),
                   ToolSignedDistance(t.tool, p + Vec3{0, 0, h}) -
                       ToolSignedDistance(t.tool, p - Vec3{0, 0, h})};
      EXPECT_GT(n.Dot(g / g.Length()), 0.999)
          << t.name << " p=(" << p.x << ", " << p.y << ", " << p.z << ")";
    }
  }
}

TEST(ToolTest, NormalsAtSurfaceSamplesPointOutward) {
  for (const NamedTool& t : Tools()) {
    const double eps = 1e-3 * Scale(t.tool);
    for (const Vec3& p : ToolSurfaceSamples(t.tool, 500)) {
      const Vec3 n = ToolNormal(t.tool, p);
      EXPECT_GT(ToolSignedDistance(t.tool, p + n * eps), 0) << t.name;
      // Not strictly negative: from a box edge the step along one face normal stays on the other
      // face (up to rounding).
      EXPECT_LE(ToolSignedDistance(t.tool, p - n * eps), 1e-9 * eps) << t.name;
    }
  }
}

TEST(ToolTest, EllipsoidNormalOnTheSurfaceIsTheExactSurfaceNormal) {
  const Vec3 a{3, 2, 1};
  const Quat q = AxisAngle({1, 2, 0.5}, 0.7);
  const ToolShape e = ToolShape::Ellipsoid({-1, 0.5, 2}, a, q);
  for (const Vec3& p : ToolSurfaceSamples(e, 300)) {
    const Vec3 l = q.InverseRotate(p - e.center);
    Vec3 exact = q.Rotate({l.x / (a.x * a.x), l.y / (a.y * a.y), l.z / (a.z * a.z)});
    exact = exact / exact.Length();
    EXPECT_NEAR((ToolNormal(e, p) - exact).Length(), 0, 1e-9);
  }
}

TEST(ToolTest, BoxNormalOnAFaceIsTheRotatedFaceAxis) {
  const Quat q = AxisAngle({0.3, -1, 2}, 1.1);
  const ToolShape b = ToolShape::Box({5, -1, 2}, {1, 2, 3}, q);
  const Vec3 n = ToolNormal(b, b.center + q.Rotate({0.3, -2, 1.5}));
  EXPECT_NEAR((n - q.Rotate({0, -1, 0})).Length(), 0, 1e-12);
  const Vec3 outside = ToolNormal(b, b.center + q.Rotate({0.3, 0.1, 7}));
  EXPECT_NEAR((outside - q.Rotate({0, 0, 1})).Length(), 0, 1e-12);
}

TEST(ToolTest, NormalIsAFiniteUnitVectorAtDegeneratePoints) {
  const ToolShape sphere = ToolShape::Sphere({1, 2, 3}, 2);
  EXPECT_EQ(ToolNormal(sphere, {1, 2, 3}), (Vec3{0, 0, 1}));
  const ToolShape ellipsoid = ToolShape::Ellipsoid({1, 2, 3}, {3, 2, 1}, AxisAngle({1, 1, 0}, 1));
  const ToolShape cube = ToolShape::Box({1, 2, 3}, {2, 2, 2}, AxisAngle({0, 1, 1}, 0.4));
  const ToolShape capsule = ToolShape::Capsule({0, 0, 0}, {0, 0, 4}, 1);
  const std::vector<std::pair<ToolShape, Vec3>> cases = {
      {ellipsoid, {1, 2, 3}}, {cube, {1, 2, 3}},
      {capsule, {0, 0, 2}},   {capsule, {0, 0, 0}},
      {capsule, {0, 0, 4}},   {ToolShape::Capsule({1, 1, 1}, {1, 1, 1}, 1), {1, 1, 1}}};
  for (const auto& [tool, p] : cases) {
    const Vec3 n = ToolNormal(tool, p);
    ASSERT_TRUE(n.IsFinite()) << ToolKindName(tool.kind);
    EXPECT_NEAR(n.Length(), 1, 1e-12) << ToolKindName(tool.kind);
  }
  // On the capsule axis the normal is perpendicular to the segment, a valid subgradient.
  EXPECT_NEAR(ToolNormal(capsule, {0, 0, 2}).z, 0, 1e-12);
}

// --- Surface samples ----------------------------------------------------------------------------

TEST(ToolTest, SamplesLieOnTheSurfaceAndCountIsNearTheRequest) {
  for (const NamedTool& t : Tools()) {
    const double tol = 1e-6 * Scale(t.tool);
    for (int count : {8, 50, 100, 257, 1000, 5000}) {
      const std::vector<Vec3> samples = ToolSurfaceSamples(t.tool, count);
      EXPECT_GE(samples.size(), 8u) << t.name << " count=" << count;
      if (count >= 50) {
        EXPECT_GE(static_cast<double>(samples.size()), 0.8 * count) << t.name << " " << count;
        EXPECT_LE(static_cast<double>(samples.size()), 1.2 * count) << t.name << " " << count;
      }
      for (const Vec3& p : samples) {
        ASSERT_TRUE(p.IsFinite()) << t.name;
        EXPECT_LT(std::fabs(ToolSignedDistance(t.tool, p)), tol) << t.name << " count=" << count;
      }
    }
  }
}

TEST(ToolTest, SampleCountStaysWithinTwentyPercentOfEveryRequest) {
  // Sweeps the request so a lattice that jumps by a whole face strip (thin boxes) shows up.
  for (const NamedTool& t : Tools()) {
    for (int count = 50; count <= 3000; count += 7) {
      const double n = static_cast<double>(ToolSurfaceSamples(t.tool, count).size());
      EXPECT_GE(n, 0.8 * count) << t.name << " count=" << count;
      EXPECT_LE(n, 1.2 * count) << t.name << " count=" << count;
    }
  }
}

TEST(ToolTest, SamplesNeverFewerThanEight) {
  for (const NamedTool& t : Tools()) {
    for (int count : {-5, 0, 1, 7}) {
      const std::vector<Vec3> samples = ToolSurfaceSamples(t.tool, count);
      EXPECT_GE(samples.size(), 8u) << t.name << " count=" << count;
      for (const Vec3& p : samples) {
        EXPECT_LT(std::fabs(ToolSignedDistance(t.tool, p)), 1e-6 * Scale(t.tool)) << t.name;
      }
    }
  }
}

TEST(ToolTest, SamplesAreDeterministic) {
  for (const NamedTool& t : Tools()) {
    const std::vector<Vec3> a = ToolSurfaceSamples(t.tool, 321);
    const std::vector<Vec3> b = ToolSurfaceSamples(t.tool, 321);
    EXPECT_EQ(a, b) << t.name;
  }
}

TEST(ToolTest, SamplesWithSlightlyNonUnitRotationStayOnTheSurface) {
  // Validation accepts |q| up to 1.001; the SDF, bounds and samples must agree on the same shape.
  const Quat q{1.0009, 0.02, -0.01, 0.03};
  for (const ToolShape& t :
       {ToolShape::Box({1, 2, 3}, {2, 1, 3}, q), ToolShape::Ellipsoid({1, 2, 3}, {2, 1, 3}, q)}) {
    const Aabb b = ToolBounds(t);
    for (const Vec3& p : ToolSurfaceSamples(t, 2000)) {
      EXPECT_LT(std::fabs(ToolSignedDistance(t, p)), 1e-6 * Scale(t)) << ToolKindName(t.kind);
      EXPECT_GE(p.x, b.min.x - 1e-9);
      EXPECT_LE(p.x, b.max.x + 1e-9);
    }
  }
}

TEST(ToolTest, BoxSamplesCoverEveryFaceInProportionToAreaIncludingCorners) {
  const Vec3 h{4, 2, 1};
  const ToolShape b = ToolShape::Box({0, 0, 0}, h);
  const std::vector<Vec3> samples = ToolSurfaceSamples(b, 4000);
  double on_face[3] = {0, 0, 0};
  for (const Vec3& p : samples) {
    for (int i = 0; i < 3; ++i) on_face[i] += std::fabs(std::fabs(p[i]) - h[i]) < 1e-12;
  }
  // Pairs of faces normal to x, y, z have areas 16, 32 and 64 (ratio 1:2:4).
  const double total = on_face[0] + on_face[1] + on_face[2];
  EXPECT_NEAR(on_face[0] / total, 1.0 / 7, 0.15 / 7);
  EXPECT_NEAR(on_face[1] / total, 2.0 / 7, 0.3 / 7);
  EXPECT_NEAR(on_face[2] / total, 4.0 / 7, 0.6 / 7);
  for (double sx : {-1.0, 1.0}) {
    for (double sy : {-1.0, 1.0}) {
      for (double sz : {-1.0, 1.0}) {
        const Vec3 corner{sx * h.x, sy * h.y, sz * h.z};
        EXPECT_NE(std::find(samples.begin(), samples.end(), corner), samples.end())
            << "missing corner (" << corner.x << ", " << corner.y << ", " << corner.z << ")";
      }
    }
  }
  // Edges are sampled too: a point on the x-parallel edge at y=+h.y, z=+h.z, away from corners.
  const bool has_edge_point = std::any_of(samples.begin(), samples.end(), [&](const Vec3& p) {
    return p.y == h.y && p.z == h.z && std::fabs(p.x) < h.x;
  });
  EXPECT_TRUE(has_edge_point);
}

TEST(ToolTest, CapsuleSamplesCoverTheCylinderAndBothCapsByArea) {
  const Vec3 a{0, 0, 0};
  const Vec3 b{4, 3, -2};
  const double r = 1.5;
  const ToolShape c = ToolShape::Capsule(a, b, r);
  const double length = (b - a).Length();
  const std::vector<Vec3> samples = ToolSurfaceSamples(c, 5000);
  int cap_a = 0, cap_b = 0, cylinder = 0;
  for (const Vec3& p : samples) {
    const double t = (p - a).Dot(b - a) / (b - a).LengthSqr();
    if (t < -1e-12) {
      ++cap_a;
    } else if (t > 1 + 1e-12) {
      ++cap_b;
    } else {
      ++cylinder;
    }
  }
  const double n = static_cast<double>(samples.size());
  const double cylinder_share = length / (length + 2 * r);
  EXPECT_NEAR(cylinder / n, cylinder_share, 0.15 * cylinder_share);
  EXPECT_NEAR(cap_a / n, (1 - cylinder_share) / 2, 0.15 * (1 - cylinder_share) / 2);
  EXPECT_NEAR(cap_b / n, (1 - cylinder_share) / 2, 0.15 * (1 - cylinder_share) / 2);
}

// --- Bounds -------------------------------------------------------------------------------------

TEST(ToolTest, BoundsContainEverySampleAndAreTight) {
  for (const NamedTool& t : Tools()) {
    const Aabb b = ToolBounds(t.tool);
    const double tol = 1e-9 * Scale(t.tool);
    const std::vector<Vec3> samples = ToolSurfaceSamples(t.tool, 20000);
    Vec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (const Vec3& p : samples) {
      for (int i = 0; i < 3; ++i) {
        EXPECT_GE(p[i], b.min[i] - tol) << t.name << " axis " << i;
        EXPECT_LE(p[i], b.max[i] + tol) << t.name << " axis " << i;
      }
      lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
      hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    for (int i = 0; i < 3; ++i) {
      const double extent = b.max[i] - b.min[i];
      EXPECT_LE(lo[i] - b.min[i], 0.01 * extent) << t.name << " min face, axis " << i;
      EXPECT_LE(b.max[i] - hi[i], 0.01 * extent) << t.name << " max face, axis " << i;
    }
  }
}

TEST(ToolTest, RotatedBoxBoundsAreTheRotatedCorners) {
  const Vec3 c{5, -1, 2};
  const Vec3 h{1, 2, 3};
  const Quat q = AxisAngle({0.3, -1, 2}, 1.1);
  const Aabb b = ToolBounds(ToolShape::Box(c, h, q));
  Vec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  for (int k = 0; k < 8; ++k) {
    const Vec3 p = c + q.Rotate({k & 1 ? h.x : -h.x, k & 2 ? h.y : -h.y, k & 4 ? h.z : -h.z});
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  EXPECT_NEAR((b.min - lo).Length(), 0, 1e-12);
  EXPECT_NEAR((b.max - hi).Length(), 0, 1e-12);
}

TEST(ToolTest, SimpleBoundsKnownValues) {
  const Aabb s = ToolBounds(ToolShape::Sphere({1, 2, 3}, 2));
  EXPECT_EQ(s.min, (Vec3{-1, 0, 1}));
  EXPECT_EQ(s.max, (Vec3{3, 4, 5}));
  const Aabb c = ToolBounds(ToolShape::Capsule({0, 5, 0}, {4, 3, -2}, 1));
  EXPECT_EQ(c.min, (Vec3{-1, 2, -3}));
  EXPECT_EQ(c.max, (Vec3{5, 6, 1}));
  const Aabb e = ToolBounds(ToolShape::Ellipsoid({0, 0, 0}, {3, 2, 1}));
  EXPECT_EQ(e.min, (Vec3{-3, -2, -1}));
  EXPECT_EQ(e.max, (Vec3{3, 2, 1}));
  // A quarter turn about z swaps the x and y extents.
  const Aabb r =
      ToolBounds(ToolShape::Ellipsoid({0, 0, 0}, {3, 2, 1}, AxisAngle({0, 0, 1}, kPi / 2)));
  EXPECT_NEAR(r.max.x, 2, 1e-12);
  EXPECT_NEAR(r.max.y, 3, 1e-12);
  EXPECT_NEAR(r.max.z, 1, 1e-12);
}

// --- Volume -------------------------------------------------------------------------------------

TEST(ToolTest, VolumeKnownValues) {
  EXPECT_DOUBLE_EQ(ToolVolume(ToolShape::Sphere({}, 2)), 32 * kPi / 3);
  EXPECT_DOUBLE_EQ(ToolVolume(ToolShape::Ellipsoid({}, {1, 2, 3}, AxisAngle({1, 0, 0}, 1))),
                   8 * kPi);
  EXPECT_DOUBLE_EQ(ToolVolume(ToolShape::Box({}, {1, 2, 3})), 48);
  EXPECT_DOUBLE_EQ(ToolVolume(ToolShape::Capsule({1, 1, 1}, {1, 1, 5}, 1)), 4 * kPi + 4 * kPi / 3);
}

TEST(ToolTest, VolumeMatchesMonteCarloEstimateFromSdfSign) {
  std::mt19937_64 rng(20240601);
  constexpr int kPoints = 200000;
  for (const NamedTool& t : Tools()) {
    const Aabb b = ToolBounds(t.tool);
    int inside = 0;
    for (int i = 0; i < kPoints; ++i) {
      inside += ToolSignedDistance(t.tool, RandomPoint(rng, b.min, b.max)) < 0;
    }
    const Vec3 e = b.max - b.min;
    const double estimate = e.x * e.y * e.z * inside / kPoints;
    EXPECT_NEAR(estimate, ToolVolume(t.tool), 0.02 * ToolVolume(t.tool)) << t.name;
  }
}

}  // namespace
}  // namespace sculpt::levelset
