// Hard cases of issue 7 for heterogeneous hyperpatches (seed 001 §7.3, §10.6): each invalid cell
// refused with its reason, the split of a valid non-monotone cell, the rotation sweep, and
// fraction vectors outside the simplex refused at every entry point.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/examples.h"
#include "sculpt/hetero/grid_editor.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"
#include "unit/hetero/hetero_test_util.h"

namespace sculpt::hetero {
namespace {

using testing::BoxPatch;
using testing::RingSectorPatch;
using testing::Rotated;
using testing::SShapedPatch;

// Dense det J sampling: the oracle the digest suggests (§3.3 INFERENCE) at 24^3+ nodes.
void DetRange(const Hyperpatch& h, double* lo, double* hi) {
  *lo = 1e300;
  *hi = -1e300;
  const int n = 24;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      for (int k = 0; k <= n; ++k) {
        const double d = h.JacobianDeterminant(i / double(n), j / double(n), k / double(n));
        *lo = std::min(*lo, d);
        *hi = std::max(*hi, d);
      }
}

Hyperpatch Moved(Hyperpatch h, int i, int j, int k, const Vec3& p) {
  h.set_position(Hyperpatch::Index(i, j, k), p);
  return h;
}

TEST(HeteroHardCasesTest, ZeroTangentAtACornerIsRefused) {
  // p100 = p000: ∂P/∂u(0,0,0) = 3(p100 − p000) = 0, so det J = 0 there (§7.3.1 cause 1).
  const Hyperpatch h = Moved(BoxPatch(), 1, 0, 0, {0, 0, 0});
  EXPECT_NEAR(h.JacobianDeterminant(0, 0, 0), 0.0, 1e-12);
  EXPECT_TRUE(CheckSpansOrdered(h.positions()).ok());  // non-strict order lets it through
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSkinIntersect) << v.rejection.ToString();
  EXPECT_EQ(v.rejection.direction, 0);
  EXPECT_EQ(v.rejection.skin_a, 0);
  EXPECT_EQ(v.rejection.skin_b, 1);
}

TEST(HeteroHardCasesTest, CoincidentInteriorCoefficientsAreRefused) {
  // Coincident consecutive coefficients inside every u span (slices 1 and 2 equal): the order
  // is non-strict, so only the skins, which touch, refuse it (claim 33; touching = intersecting).
  Hyperpatch h = BoxPatch();
  for (int j = 0; j < 4; ++j)
    for (int k = 0; k < 4; ++k) h.set_position(Hyperpatch::Index(2, j, k), h.position(1, j, k));
  EXPECT_TRUE(CheckSpansOrdered(h.positions()).ok());
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSkinIntersect) << v.rejection.ToString();
  EXPECT_EQ(v.rejection.skin_a, 1);
  EXPECT_EQ(v.rejection.skin_b, 2);
}

TEST(HeteroHardCasesTest, FlattenedCellIsRefused) {
  // Zero volume: every coefficient in the plane z = 0 (coplanar tangents, cause 2).
  Hyperpatch h = BoxPatch();
  for (int i = 0; i < 64; ++i) h.set_position(i, {h.position(i).x, h.position(i).y, 0});
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kDegenerateCell) << v.rejection.ToString();
  // Thinner than round-off relative to its size: refused too.
  Hyperpatch thin = BoxPatch();
  for (int i = 0; i < 64; ++i) {
    thin.set_position(i, {thin.position(i).x, thin.position(i).y, thin.position(i).z * 1e-15});
  }
  EXPECT_FALSE(CheckCell(thin).valid);
}

TEST(HeteroHardCasesTest, FlattenedInAnotherDirectionIsRefusedByTheSkins) {
  // The k layers collapse pairwise (w-skins 0/1 and 2/3 coincide) while the mean w chord stays:
  // only requirement 2 can see it.
  Hyperpatch h = BoxPatch();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      h.set_position(Hyperpatch::Index(i, j, 1), h.position(i, j, 0));
      h.set_position(Hyperpatch::Index(i, j, 2), h.position(i, j, 3));
    }
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSkinIntersect) << v.rejection.ToString();
  EXPECT_EQ(v.rejection.direction, 2);
}

TEST(HeteroHardCasesTest, FoldOverIsRefused) {
  // An interior coefficient pushed through the opposite face (Fig. 7.1).
  const Hyperpatch h = Moved(BoxPatch(), 1, 1, 1, {12, 1, 1});
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSpanNotOrdered) << v.rejection.ToString();
  EXPECT_EQ(v.rejection.direction, 0);
  EXPECT_EQ(v.rejection.span, 1 * 4 + 1);
}

TEST(HeteroHardCasesTest, SpansOrderedButSingularIsCaughtByTheSkins) {
  // Fig. 7.5a,b: all 48 spans ordered, yet det J = 0 somewhere (an edge collapsed to zero
  // tangent along u).
  Hyperpatch h = BoxPatch();
  for (int k = 0; k < 4; ++k) h.set_position(Hyperpatch::Index(1, 0, k), h.position(0, 0, k));
  double lo, hi;
  DetRange(h, &lo, &hi);
  EXPECT_LE(lo, 1e-9);  // singular on the edge
  EXPECT_TRUE(CheckSpansOrdered(h.positions()).ok());
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSkinIntersect);
}

TEST(HeteroHardCasesTest, SkinsDisjointButFoldedIsCaughtByTheSpans) {
  // Fig. 7.5c,d: u-slices at x = 0, 4, 0.5, 3 are parallel planes (no skins touch), but the
  // slab folds: det J < 0 in the middle.
  Hyperpatch h = BoxPatch();
  const double x[4] = {0, 4, 0.5, 3};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) {
        const Vec3 p = h.position(i, j, k);
        h.set_position(Hyperpatch::Index(i, j, k), {x[i], p.y, p.z});
      }
  double lo, hi;
  DetRange(h, &lo, &hi);
  EXPECT_LT(lo, 0.0);
  EXPECT_GT(hi, 0.0);
  EXPECT_TRUE(CheckSkinsDisjoint(h.positions()).ok());
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSpanNotOrdered);
  EXPECT_EQ(v.rejection.direction, 0);
}

// A ribbon along a planar cubic that loops over itself: P0P1 and P2P3 of the centre curve
// cross. Height along u, width along the control polygon's normal (w).
Hyperpatch LoopRibbon() {
  const Vec3 c[4] = {{0, 0, 0}, {6, 6, 0}, {-3, 6, 0}, {3, 0, 0}};
  Hyperpatch h(2);
  for (int j = 0; j < 4; ++j) {
    const Vec3 t = c[std::min(j + 1, 3)] - c[std::max(j - 1, 0)];
    const Vec3 n = Vec3{-t.y, t.x, 0} / t.Length();
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k < 4; ++k)
        h.set_position(Hyperpatch::Index(i, j, k), c[j] + Vec3{0, 0, i / 3.0} + n * (0.1 * k));
  }
  return h;
}

TEST(HeteroHardCasesTest, WrapAroundCellOverlappingItselfIsRefused) {
  // §10.6-5: globally overlapping. Show the overlap (two far-apart parameters map to nearly the
  // same point), then the refusal.
  const Hyperpatch h = LoopRibbon();
  const int n = 40;
  double best = 1e300;
  std::vector<std::pair<double, Vec3>> pts;
  for (int j = 0; j <= n; ++j) pts.push_back({j / double(n), h.Evaluate(0.5, j / double(n), 0.5)});
  for (size_t a = 0; a < pts.size(); ++a)
    for (size_t b = a + 1; b < pts.size(); ++b)
      if (std::abs(pts[a].first - pts[b].first) > 0.3) {
        best = std::min(best, (pts[a].second - pts[b].second).Length());
      }
  EXPECT_LT(best, 0.3);  // the centre curve comes back over itself
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSpanNotOrdered) << v.rejection.ToString();
  EXPECT_EQ(v.rejection.direction, 1);
}

TEST(HeteroHardCasesTest, ValidNonMonotoneCellPassesAfterTheSplit) {
  // Fig. 7.4: a valid cell (det J > 0 everywhere) refused by requirement 1 in every frame ...
  const Hyperpatch h = SShapedPatch();
  double lo, hi;
  DetRange(h, &lo, &hi);
  EXPECT_GT(lo, 0.0);
  const CellVerdict v = CheckCell(h);
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.rejection.reason, Reason::kSpanNotOrdered);
  EXPECT_EQ(v.rejection.direction, 0);
  // ... is accepted once split at the middle of the failing direction, with the same geometry.
  const auto [left, right] = h.Split(0, 0.5);
  EXPECT_TRUE(CheckCell(left).valid) << CheckCell(left).rejection.ToString();
  EXPECT_TRUE(CheckCell(right).valid) << CheckCell(right).rejection.ToString();
  for (double u = 0; u <= 1.0; u += 0.125)
    for (double w = 0; w <= 1.0; w += 0.5) {
      EXPECT_NEAR((left.Evaluate(u, 0.3, w) - h.Evaluate(u / 2, 0.3, w)).Length(), 0, 1e-12);
      EXPECT_NEAR((right.Evaluate(u, 0.7, w) - h.Evaluate(0.5 + u / 2, 0.7, w)).Length(), 0, 1e-12);
    }
  // Through the model: the split cells are accepted together, glued along the cut.
  CompositeModel m(2);
  ValidityChecker checker;
  ASSERT_TRUE(AddCellChecked(&m, &checker, left, CellSource::kUser)->added);
  const auto r = AddCellChecked(&m, &checker, right, CellSource::kUser);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->added) << r->rejection.ToString();
}

TEST(HeteroHardCasesTest, VerdictDoesNotChangeUnderRotation) {
  // Digest claim 32 and §10.6-7: 0°..360° in 10° steps about each axis.
  const auto tyre = BuildMotorcycleTyre(8);
  ASSERT_TRUE(tyre.ok());
  const struct {
    const char* name;
    Hyperpatch cell;
  } cases[] = {{"box", BoxPatch(3, 2, 1)},
               {"quarter ring", RingSectorPatch(1, 2, 0, 90)},
               {"45-degree sector", RingSectorPatch(1, 2, 10, 55, 0, 0.5)},
               {"tyre side wall", tyre->CellPatch(4)},
               {"S-shaped (refused)", SShapedPatch()}};
  for (const auto& c : cases) {
    const CellVerdict ref = CheckCell(c.cell);
    for (int axis = 0; axis < 3; ++axis) {
      for (int deg = 0; deg <= 360; deg += 10) {
        const CellVerdict v = CheckCell(Rotated(c.cell, axis, deg));
        EXPECT_EQ(v.valid, ref.valid) << c.name << " axis " << axis << " " << deg << "°: "
                                      << v.rejection.ToString();
        EXPECT_EQ(v.rejection.reason, ref.rejection.reason) << c.name << " " << axis << " " << deg;
      }
    }
  }
}

TEST(HeteroHardCasesTest, FractionsOutsideTheSimplexAreRefusedEverywhere) {
  const std::vector<std::vector<double>> bad = {
      {-0.1, 1.1}, {std::nan(""), 1.0}, {0.5, 0.5 + 2e-6}, {0.3, 0.3}, {INFINITY, 0}};
  for (const auto& a : bad) {
    CompositeModel m(2);
    const auto add = m.AddCoefficient({0, 0, 0}, a);
    ASSERT_FALSE(add.ok());
    EXPECT_EQ(add.status().code(), Status::Code::kInvalidArgument);
    EXPECT_NE(add.status().message().find("coefficient.a"), std::string::npos) << add.status();
    // A model file off the wire.
    char coef[160];
    std::snprintf(coef, sizeof coef, "[0,0,0,%.17g,%.17g]", a[0], a[1]);
    std::string text = R"({"format":"sculpt-hetero-model","version":1,"materials":[{"name":"x"},{"name":"y"}],"coefficients":[)";
    text += std::string(coef) + R"(],"cells":[]})";
    EXPECT_FALSE(ModelFromJson(text).ok()) << text;
    // Material edits.
    ASSERT_TRUE(m.AddCoefficient({0, 0, 0}, std::vector<double>{1, 0}).ok());
    const Status s = SetPointMaterial(&m, 0, a);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.message().find("fractions"), std::string::npos) << s;
    EXPECT_EQ(m.fractions(0)[0], 1.0);  // unchanged
  }
  // A sum within 1e-6 is accepted.
  CompositeModel m(2);
  EXPECT_TRUE(m.AddCoefficient({0, 0, 0}, std::vector<double>{0.5, 0.5 + 5e-7}).ok());
}

TEST(HeteroHardCasesTest, RandomEditsNeverLeaveAnInvalidModel) {
  // 300 random intents on a 2x2x2 block: each either accepted with the model still valid, or
  // refused with a reason and the model unchanged.
  CompositeModel m(2);
  ValidityChecker checker;
  for (int c = 0; c < 8; ++c) {
    Hyperpatch h = BoxPatch();
    for (int i = 0; i < 64; ++i) {
      h.set_position(i, h.position(i) + Vec3{3.0 * ((c >> 2) & 1), 3.0 * ((c >> 1) & 1), 3.0 * (c & 1)});
    }
    ASSERT_TRUE(AddCellChecked(&m, &checker, h, CellSource::kUser)->added);
  }
  const auto corners = CornerPoints(m);
  std::mt19937 rng(11);
  std::uniform_int_distribution<size_t> pick(0, corners.size() - 1);
  std::uniform_int_distribution<int> off(-1, 1);
  std::uniform_real_distribution<double> d(-1.2, 1.2);
  int accepted = 0, refused = 0;
  for (int e = 0; e < 300; ++e) {
    EditIntent in{corners[pick(rng)], {off(rng), off(rng), off(rng)}, {d(rng), d(rng), d(rng)}};
    if (e % 3 == 0) in.set_flags = CornerFlags{true, false};
    const std::string before = ModelToJson(m);
    const auto out = ApplyIntent(&m, &checker, in);
    if (!out.ok() || !out->applied) {
      ++refused;
      EXPECT_EQ(ModelToJson(m), before) << "edit " << e;
      if (out.ok()) {
        EXPECT_NE(out->rejection.reason, Reason::kOk);
      }
    } else {
      ++accepted;
    }
  }
  ValidityChecker fresh;
  EXPECT_TRUE(fresh.CheckModel(m).valid);
  EXPECT_GT(accepted, 0);
  EXPECT_GT(refused, 0);
}

}  // namespace
}  // namespace sculpt::hetero
