#include "sculpt/hetero/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace sculpt::hetero {
namespace {

TEST(MaterialTest, MixMatchesTheThesisExample) {
  // Seed 001 §4.2.1: (0.7,0.3) ⊕0.75 (0.4,0.6) = (0.625, 0.375).
  const auto r = Mix(std::vector<double>{0.7, 0.3}, std::vector<double>{0.4, 0.6}, 0.75);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_NEAR((*r)[0], 0.625, 1e-15);
  EXPECT_NEAR((*r)[1], 0.375, 1e-15);
}

TEST(MaterialTest, RejectsTheThesisInvalidDistributions) {
  // §4.2.1: (0.4, 0.8) sums to 1.2; (1.2, −0.2) has a coordinate outside [0, 1].
  const Status s1 = ValidateFractions("a", std::vector<double>{0.4, 0.8}, 2);
  ASSERT_FALSE(s1.ok());
  EXPECT_NE(s1.message().find("a.sum=1.2"), std::string::npos) << s1;
  const Status s2 = ValidateFractions("a", std::vector<double>{1.2, -0.2}, 2);
  ASSERT_FALSE(s2.ok());
  EXPECT_NE(s2.message().find("a[0]=1.2 outside [0, 1]"), std::string::npos) << s2;
}

TEST(MaterialTest, RejectsNegativeFraction) {
  const Status s = ValidateFractions("a", std::vector<double>{0.5, 0.6, -0.1}, 3);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("a[2]=-0.1 outside [0, 1]"), std::string::npos) << s;
}

TEST(MaterialTest, RejectsNanFraction) {
  const Status s = ValidateFractions("a", std::vector<double>{std::nan(""), 1.0}, 2);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("a[0]=nan is not finite"), std::string::npos) << s;
}

TEST(MaterialTest, SumToleranceIsOneInAMillion) {
  EXPECT_TRUE(ValidateFractions("a", std::vector<double>{0.5, 0.5 + 9e-7}, 2).ok());
  EXPECT_FALSE(ValidateFractions("a", std::vector<double>{0.5, 0.5 + 2e-6}, 2).ok());
}

TEST(MaterialTest, RejectsWrongMaterialCount) {
  EXPECT_FALSE(ValidateFractions("a", std::vector<double>{1.0}, 2).ok());
}

TEST(MaterialTest, RejectsAlphaOutsideUnitInterval) {
  const auto r = Mix(std::vector<double>{1, 0}, std::vector<double>{0, 1}, 1.5);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("alpha=1.5 outside [0, 1]"), std::string::npos);
}

TEST(MaterialTest, ProjectionLandsInTheSimplexAndKeepsValidInput) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> d(-2.0, 2.0);
  for (int n = 0; n < 500; ++n) {
    std::vector<double> a = {d(rng), d(rng), d(rng), d(rng)};
    const Fractions p = ProjectToSimplex(a);
    EXPECT_TRUE(ValidateFractions("p", p, 4).ok());
    // Projection is idempotent.
    const Fractions q = ProjectToSimplex(p);
    for (int m = 0; m < 4; ++m) EXPECT_NEAR(p[m], q[m], 1e-12);
  }
  const Fractions keep = ProjectToSimplex(std::vector<double>{0.2, 0.3, 0.5});
  EXPECT_NEAR(keep[0], 0.2, 1e-15);
  EXPECT_NEAR(keep[2], 0.5, 1e-15);
  // The thesis's extrapolated (−0.1, 1.1) (§7.4) projects to the simplex vertex (0, 1).
  const Fractions v = ProjectToSimplex(std::vector<double>{-0.1, 1.1});
  EXPECT_NEAR(v[0], 0.0, 1e-15);
  EXPECT_NEAR(v[1], 1.0, 1e-15);
}

}  // namespace
}  // namespace sculpt::hetero
