/// @brief OrientedBall (digest Def 2.1) and the checks an ordered chain of them must pass before a
/// skin is built: finite fields in range, and admissibility (digest Def 2.6).
#ifndef SCULPT_SKIN_ORIENTED_BALL_H_
#define SCULPT_SKIN_ORIENTED_BALL_H_

#include <cmath>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin {

/// Largest accepted |coordinate| and radius: beyond this, quantised contours and the 1e-9
/// relative tolerances of the construction lose their meaning.
inline constexpr double kMaxCoordinate = 1e12;

/// A circle with a touching direction (digest Def 2.1): centre `c`, radius `r` > 0 and the
/// direction `t = (cos theta, sin theta)`. The skin touches it at the antipodal contact points
/// P+ (right of t) and P- (left of t). Value type.
struct OrientedBall {
  Vec2 c;
  double r = 1;
  double theta = 0;  // radians

  Vec2 t() const { return {std::cos(theta), std::sin(theta)}; }
  /// P+ (side = +1) = c + r rotR(t) or P- (side = -1) = c - r rotR(t) (digest Def 2.1, closed
  /// form).
  Vec2 Contact(int side) const { return c + t().RotR() * (side * r); }
};

/// Checks one ball's fields: InvalidArgument naming `field` (e.g. "balls[3]"), the member, its
/// value and the allowed range for NaN/Inf anywhere, r outside (0, 1e12], |c| beyond 1e12.
Status ValidateBall(const std::string& field, const OrientedBall& b);

/// Checks the pair (a = balls[i], b = balls[i+1]) for admissibility (digest Def 2.6): neither
/// contact point of one may lie in the other's closed disk. The InvalidArgument names both
/// balls, the offending contact point and its distance; coincident, concentric and nested pairs
/// are named as such.
Status CheckAdmissiblePair(size_t i, const OrientedBall& a, const OrientedBall& b);

/// ValidateBall on every ball, then CheckAdmissiblePair on every consecutive pair. A chain needs
/// at least 2 balls.
Status ValidateChain(const std::vector<OrientedBall>& balls);

}  // namespace sculpt::skin

#endif  // SCULPT_SKIN_ORIENTED_BALL_H_
