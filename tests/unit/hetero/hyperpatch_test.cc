#include "sculpt/hetero/hyperpatch.h"

#include <gtest/gtest.h>

#include <random>

#include "sculpt/hetero/material.h"
#include "unit/hetero/hetero_test_util.h"

namespace sculpt::hetero {
namespace {

using testing::BoxPatch;

// A cell with random positions near a box and random valid fractions (3 materials).
Hyperpatch RandomPatch(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3), unit(0.0, 1.0);
  Hyperpatch h = BoxPatch(3, 3, 3, 3);
  for (int i = 0; i < 64; ++i) {
    h.set_position(i, h.position(i) + Vec3{jitter(rng), jitter(rng), jitter(rng)});
    std::vector<double> a = {unit(rng), unit(rng), unit(rng)};
    const double s = a[0] + a[1] + a[2];
    for (double& x : a) x /= s;
    h.set_fractions(i, a);
  }
  return h;
}

TEST(HyperpatchTest, BernsteinIsAPartitionOfUnity) {
  // Seed 001 §6.3 / claim 1: non-negative on [0,1], summing to 1.
  for (double t = 0; t <= 1.0; t += 0.05) {
    const auto b = Bernstein3(t);
    EXPECT_NEAR(b[0] + b[1] + b[2] + b[3], 1.0, 1e-15);
    for (double x : b) EXPECT_GE(x, 0.0);
  }
}

TEST(HyperpatchTest, InterpolatesTheEightCorners) {
  const Hyperpatch h = RandomPatch(1);
  for (int c = 0; c < 8; ++c) {
    const int i = (c & 4) ? 3 : 0, j = (c & 2) ? 3 : 0, k = (c & 1) ? 3 : 0;
    const Vec3 p = h.Evaluate(i / 3.0, j / 3.0, k / 3.0);
    EXPECT_NEAR((p - h.position(i, j, k)).Length(), 0.0, 1e-12) << "corner " << c;
  }
}

TEST(HyperpatchTest, CornerTangentsAreThreeTimesTheNeighbourDifference) {
  // Claim 4: ∂P/∂u(0,0,0) = 3(p100 − p000), likewise v and w.
  const Hyperpatch h = RandomPatch(2);
  const auto d = h.Derivatives(0, 0, 0);
  EXPECT_NEAR((d[0] - (h.position(1, 0, 0) - h.position(0, 0, 0)) * 3.0).Length(), 0, 1e-12);
  EXPECT_NEAR((d[1] - (h.position(0, 1, 0) - h.position(0, 0, 0)) * 3.0).Length(), 0, 1e-12);
  EXPECT_NEAR((d[2] - (h.position(0, 0, 1) - h.position(0, 0, 0)) * 3.0).Length(), 0, 1e-12);
}

TEST(HyperpatchTest, DerivativesMatchFiniteDifferences) {
  const Hyperpatch h = RandomPatch(3);
  const double e = 1e-6;
  for (const Vec3 q : {Vec3{0.3, 0.6, 0.2}, Vec3{0.9, 0.1, 0.5}}) {
    const auto d = h.Derivatives(q.x, q.y, q.z);
    const Vec3 fu = (h.Evaluate(q.x + e, q.y, q.z) - h.Evaluate(q.x - e, q.y, q.z)) / (2 * e);
    const Vec3 fv = (h.Evaluate(q.x, q.y + e, q.z) - h.Evaluate(q.x, q.y - e, q.z)) / (2 * e);
    const Vec3 fw = (h.Evaluate(q.x, q.y, q.z + e) - h.Evaluate(q.x, q.y, q.z - e)) / (2 * e);
    EXPECT_NEAR((d[0] - fu).Length(), 0, 1e-6);
    EXPECT_NEAR((d[1] - fv).Length(), 0, 1e-6);
    EXPECT_NEAR((d[2] - fw).Length(), 0, 1e-6);
    EXPECT_NEAR(h.JacobianDeterminant(q.x, q.y, q.z), d[0].Dot(d[1].Cross(d[2])), 1e-9);
  }
}

TEST(HyperpatchTest, BoxJacobianIsTheVolumeScale) {
  // The evenly spaced box net is the affine map (u,v,w) -> (2u, 3v, 4w): det J = 24.
  const Hyperpatch h = BoxPatch(2, 3, 4);
  EXPECT_NEAR(h.JacobianDeterminant(0.37, 0.81, 0.05), 24.0, 1e-12);
  EXPECT_NEAR((h.Evaluate(0.5, 0.25, 1.0) - Vec3{1.0, 0.75, 4.0}).Length(), 0.0, 1e-12);
}

TEST(HyperpatchTest, MaterialsStayInTheSimplex) {
  // Claim 2: A(u,v,w) ∈ V whenever every a_ijk ∈ V.
  const Hyperpatch h = RandomPatch(4);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int n = 0; n < 200; ++n) {
    const Fractions a = h.Materials(unit(rng), unit(rng), unit(rng));
    EXPECT_TRUE(ValidateFractions("a", a, 3).ok());
  }
}

TEST(HyperpatchTest, SplitReproducesTheGeometryAndMaterials) {
  const Hyperpatch h = RandomPatch(5);
  for (int axis = 0; axis < 3; ++axis) {
    const auto [lo, hi] = h.Split(axis, 0.4);
    for (const Vec3 q : {Vec3{0.2, 0.7, 0.3}, Vec3{0.9, 0.5, 0.1}}) {
      Vec3 ql = q, qh = q;
      double* cl = axis == 0 ? &ql.x : (axis == 1 ? &ql.y : &ql.z);
      double* ch = axis == 0 ? &qh.x : (axis == 1 ? &qh.y : &qh.z);
      const double t = *cl;
      *cl = t * 0.4;
      *ch = 0.4 + t * 0.6;
      EXPECT_NEAR((lo.Evaluate(q.x, q.y, q.z) - h.Evaluate(ql.x, ql.y, ql.z)).Length(), 0, 1e-12);
      EXPECT_NEAR((hi.Evaluate(q.x, q.y, q.z) - h.Evaluate(qh.x, qh.y, qh.z)).Length(), 0, 1e-12);
      const Fractions a = lo.Materials(q.x, q.y, q.z), b = h.Materials(ql.x, ql.y, ql.z);
      for (int m = 0; m < 3; ++m) EXPECT_NEAR(a[m], b[m], 1e-12);
    }
  }
}

TEST(HyperpatchTest, BoundsHoldTheCell) {
  const Hyperpatch h = RandomPatch(6);
  const Aabb b = h.Bounds();
  for (double u = 0; u <= 1; u += 0.25)
    for (double v = 0; v <= 1; v += 0.25)
      for (double w = 0; w <= 1; w += 0.25) EXPECT_TRUE(b.Contains(h.Evaluate(u, v, w), 1e-12));
}

TEST(HyperpatchTest, RejectsNanPosition) {
  std::vector<ControlPoint> pts(64, ControlPoint{{0, 0, 0}, {1.0, 0.0}});
  pts[17].p.y = std::nan("");
  const auto r = Hyperpatch::Create(pts, 2);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("hyperpatch.points[17].p"), std::string::npos)
      << r.status().message();
}

TEST(HyperpatchTest, RejectsFractionsOutsideTheSimplex) {
  std::vector<ControlPoint> pts(64, ControlPoint{{0, 0, 0}, {1.0, 0.0}});
  pts[5].a = {1.2, -0.2};
  const auto r = Hyperpatch::Create(pts, 2);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("hyperpatch.points[5].a[0]=1.2 outside [0, 1]"),
            std::string::npos)
      << r.status().message();
}

TEST(HyperpatchTest, RejectsWrongPointCount) {
  std::vector<ControlPoint> pts(63, ControlPoint{{0, 0, 0}, {1.0}});
  EXPECT_FALSE(Hyperpatch::Create(pts, 1).ok());
}

}  // namespace
}  // namespace sculpt::hetero
