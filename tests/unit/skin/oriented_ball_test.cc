#include "sculpt/skin/oriented_ball.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace sculpt::skin {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

// Digest §7 claim 1: contact points on the circle, antipodal, perpendicular to t, P+ on the right.
TEST(OrientedBallTest, ContactPointsAreAntipodalOnTheCircle) {
  const OrientedBall b{{1.5, -2}, 0.75, 37 * kDeg};
  const Vec2 pp = b.Contact(1), pm = b.Contact(-1);
  EXPECT_NEAR((pp - b.c).Length(), b.r, 1e-15);
  EXPECT_NEAR((pm - b.c).Length(), b.r, 1e-15);
  EXPECT_NEAR((pp - b.c).Dot(b.t()), 0, 1e-15);
  EXPECT_LT(b.t().Cross(pp - b.c), 0);  // right of the travel direction
  EXPECT_NEAR((pp + pm - b.c * 2).Length(), 0, 1e-15);
  // The counter-clockwise circle tangent at P+ is +t (digest Def 2.1).
  const Vec2 ccw = (pp - b.c).RotL().Normalized();
  EXPECT_NEAR(ccw.Dot(b.t()), 1, 1e-15);
}

TEST(OrientedBallTest, AcceptsOverlappingAdmissiblePair) {
  const OrientedBall a{{0, 0}, 1, 0}, b{{1.5, 0}, 1, 0};
  EXPECT_TRUE(CheckAdmissiblePair(0, a, b).ok());
}

TEST(OrientedBallTest, RejectsNestedPairNamingBoth) {
  const Status s = CheckAdmissiblePair(4, {{0, 0}, 3, 0}, {{0.5, 0}, 1, 0});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("balls[5] lies inside balls[4]"), std::string::npos) << s;
}

TEST(OrientedBallTest, RejectsConcentricPair) {
  const Status s = CheckAdmissiblePair(0, {{2, 2}, 1, 0}, {{2, 2}, 2, 1});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("balls[0] and balls[1] are concentric"), std::string::npos) << s;
}

TEST(OrientedBallTest, RejectsCoincidentPair) {
  const Status s = CheckAdmissiblePair(2, {{2, 2}, 1, 0}, {{2, 2}, 1, 0.3});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("balls[2] and balls[3] are coincident"), std::string::npos) << s;
}

TEST(OrientedBallTest, RejectsContactPointInsideNeighbour) {
  // Orientation across the chain puts P+ of balls[0] inside balls[1].
  const Status s = CheckAdmissiblePair(0, {{0, 0}, 1, 90 * kDeg}, {{1.5, 0}, 1, 90 * kDeg});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("contact point P+ of balls[0]"), std::string::npos) << s;
  EXPECT_NE(s.message().find("lies in balls[1]"), std::string::npos) << s;
}

TEST(OrientedBallTest, RejectsNanRadius) {
  const Status s = ValidateBall("balls[3]", {{0, 0}, std::nan(""), 0});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("balls[3].r=nan is not finite"), std::string::npos) << s;
}

TEST(OrientedBallTest, RejectsInfCentreAndTheta) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_NE(ValidateBall("b", {{inf, 0}, 1, 0}).message().find("b.c.x=inf"), std::string::npos);
  EXPECT_NE(ValidateBall("b", {{0, -inf}, 1, 0}).message().find("b.c.y=-inf"), std::string::npos);
  EXPECT_NE(ValidateBall("b", {{0, 0}, 1, inf}).message().find("b.theta=inf"), std::string::npos);
}

TEST(OrientedBallTest, RejectsNonPositiveRadius) {
  EXPECT_NE(ValidateBall("b", {{0, 0}, 0, 0}).message().find("b.r=0 outside (0, "),
            std::string::npos);
  EXPECT_FALSE(ValidateBall("b", {{0, 0}, -1, 0}).ok());
}

TEST(OrientedBallTest, RejectsChainOfOneBall) {
  EXPECT_FALSE(ValidateChain({{{0, 0}, 1, 0}}).ok());
}

}  // namespace
}  // namespace sculpt::skin
