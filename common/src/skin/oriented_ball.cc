/// @brief Ball validation and admissibility (digest Def 2.1, Def 2.6).
#include "sculpt/skin/oriented_ball.h"

#include <algorithm>
#include <cstdio>

#include "sculpt/core/check.h"

namespace sculpt::skin {
namespace {

std::string Point(const Vec2& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.9g, %.9g)", p.x, p.y);
  return buf;
}

std::string Name(size_t i) { return "balls[" + std::to_string(i) + "]"; }

}  // namespace

Status ValidateBall(const std::string& field, const OrientedBall& b) {
  SCULPT_RETURN_IF_ERROR(CheckRange(field + ".c.x", b.c.x, -kMaxCoordinate, kMaxCoordinate));
  SCULPT_RETURN_IF_ERROR(CheckRange(field + ".c.y", b.c.y, -kMaxCoordinate, kMaxCoordinate));
  SCULPT_RETURN_IF_ERROR(CheckRange(field + ".r", b.r, 0, kMaxCoordinate));
  if (!(b.r > 0)) {
    return Outside(field + ".r", FormatNumber(b.r),
                   std::string("(0, ") + FormatNumber(kMaxCoordinate) + "]");
  }
  // An angle beyond 1e9 rad has lost every digit of its direction.
  SCULPT_RETURN_IF_ERROR(CheckRange(field + ".theta", b.theta, -1e9, 1e9));
  return Status::Ok();
}

Status CheckAdmissiblePair(size_t i, const OrientedBall& a, const OrientedBall& b) {
  const std::string na = Name(i), nb = Name(i + 1);
  const double dist = (b.c - a.c).Length();
  // Lengths are compared with a margin relative to the pair's own size (digest §7: eps = 1e-9 S),
  // so a chain far from the origin or with huge total extent is judged like a small one.
  const double eps = 1e-9 * (dist + a.r + b.r);
  if (dist <= eps) {
    if (std::abs(a.r - b.r) <= eps) {
      return InvalidArgument(na + " and " + nb + " are coincident (centre " + Point(a.c) +
                             ", radius " + FormatNumber(a.r) +
                             "): not admissible (digest Def 2.6)");
    }
    return InvalidArgument(na + " and " + nb + " are concentric (centre " + Point(a.c) +
                           ", radii " + FormatNumber(a.r) + " and " + FormatNumber(b.r) +
                           "): not admissible (digest Def 2.6)");
  }
  if (dist + std::min(a.r, b.r) <= std::max(a.r, b.r) + eps) {
    const bool a_inside = a.r < b.r;
    return InvalidArgument((a_inside ? na : nb) + " lies inside " + (a_inside ? nb : na) +
                           " (nested: centre distance " + FormatNumber(dist) + ", radii " +
                           FormatNumber(a.r) + " and " + FormatNumber(b.r) +
                           "): not admissible (digest Def 2.6)");
  }
  const OrientedBall* balls[2] = {&a, &b};
  const std::string names[2] = {na, nb};
  for (int k = 0; k < 2; ++k) {
    const OrientedBall& self = *balls[k];
    const OrientedBall& other = *balls[1 - k];
    for (int side : {1, -1}) {
      const Vec2 p = self.Contact(side);
      const double dp = (p - other.c).Length();
      if (dp <= other.r + eps) {
        return InvalidArgument(names[0] + " and " + names[1] +
                               " are not admissible (digest Def 2.6): contact point " +
                               (side > 0 ? "P+" : "P-") + " of " + names[k] + " at " + Point(p) +
                               " lies in " + names[1 - k] + " (distance " + FormatNumber(dp) +
                               " <= radius " + FormatNumber(other.r) + ")");
      }
    }
  }
  return Status::Ok();
}

Status ValidateChain(const std::vector<OrientedBall>& balls) {
  if (balls.size() < 2) {
    return Outside("balls.size", std::to_string(balls.size()),
                   "[2, inf): a skin needs at least two balls");
  }
  for (size_t i = 0; i < balls.size(); ++i) {
    SCULPT_RETURN_IF_ERROR(ValidateBall(Name(i), balls[i]));
  }
  for (size_t i = 0; i + 1 < balls.size(); ++i) {
    SCULPT_RETURN_IF_ERROR(CheckAdmissiblePair(i, balls[i], balls[i + 1]));
  }
  return Status::Ok();
}

}  // namespace sculpt::skin
