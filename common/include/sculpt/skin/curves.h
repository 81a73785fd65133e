/// @brief The curves a skin section is made of: the cubic Hermite mother curve, the distance
/// function d, the variable-distance offset (digest §3.3-3.4) and the corrected cubic A-spline
/// (digest §2.4). Pure functions of their data; no allocation.
#ifndef SCULPT_SKIN_CURVES_H_
#define SCULPT_SKIN_CURVES_H_

#include <array>
#include <optional>
#include <string>

#include "sculpt/skin/oriented_ball.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin {

/// The mother curve of a section: the cubic Hermite interpolant of the centres with end
/// derivatives L t0, L t1 in tau in [0, 1], L = |C1 - C0| (digest §3.4 step 1, the corrected h10
/// of §2.6). Stored in power form p(tau) = a tau^3 + b tau^2 + c tau + e. Value type.
struct HermiteMother {
  Vec2 a, b, c, e;
  double length = 0;  // L

  static HermiteMother FromBalls(const OrientedBall& b0, const OrientedBall& b1);
  Vec2 P(double tau) const { return ((a * tau + b) * tau + c) * tau + e; }
  Vec2 D1(double tau) const { return (a * (3 * tau) + b * 2) * tau + c; }
  Vec2 D2(double tau) const { return a * (6 * tau) + b * 2; }
  /// Signed curvature (1.3), positive for left turns; 0 where p' vanishes.
  double Curvature(double tau) const;
  /// Parameters in (1e-6, 1 - 1e-6) where the curvature changes sign: the roots of
  /// cross(p', p'') = -6 cross(a,b) tau^2 + 6 cross(c,a) tau + 2 cross(c,b) (digest §8.4).
  /// Double roots (no sign change) are skipped. Returns how many (0..2) were written.
  int Inflections(std::array<double, 2>& out) const;
};

/// The distance function d(tau) = r0 + (r1 - r0)(3 tau^2 - 2 tau^3): cubic Hermite with zero end
/// slopes (digest §3.4 step 2, conditions (2.9)-(2.10)). Value type.
struct DistanceFn {
  double r0 = 1, r1 = 1;
  double D(double tau) const { return r0 + (r1 - r0) * tau * tau * (3 - 2 * tau); }
  double D1(double tau) const { return (r1 - r0) * 6 * tau * (1 - tau); }
};

/// The variable-distance offset c(tau) = p(tau) + side d(tau) n(tau), n = rotR(p'/|p'|)
/// (digest Def 2.9 with the corrected normal). side = +1 is the right side.
struct Offset {
  const HermiteMother* mother = nullptr;
  const DistanceFn* dist = nullptr;
  int side = 1;

  Vec2 P(double tau) const;
  /// c' = |p'|(1 + side kappa d) t + side d' n (digest §3.3, the derivative in any parameter).
  Vec2 D1(double tau) const;
  /// 1 + side kappa d: negative means the offset runs backwards there (Thm 2.3 indicator).
  double OnePlusKappaD(double tau) const;
};

/// One cubic A-spline section (digest §2.4, the corrected (1.6)): the arc of
/// f(u,v,w) = -v^3 + (delta^3/2)[u w (u+w) - (k0 u + k2 w) v^2] + (delta^4/2)(k0+k2) u v w = 0
/// in barycentric coordinates of the control triangle (P0, P1, P2), from P0 to P2, tangent to
/// P0P1 at P0 and to P1P2 at P2, with curvatures kappa0, kappa2 bending into the triangle.
/// Value type.
struct ASpline {
  Vec2 p0, p1, p2;
  Vec2 t0, t2;             // unit tangents at P0, P2 (travel direction)
  double k0 = 0, k2 = 0;   // normalised curvatures (the tilde kappas of the digest)
  double delta = 1;

  /// Builds the section through P0 with tangent t0 and curvature kappa0 >= 0 to P2 with tangent t2
  /// and curvature kappa2 >= 0. delta <= 0 picks the default 2 cos(mean chord-tangent angle)
  /// clamped to [0.05, 20] (circle reproduction, digest §2.4 (c)). Returns nullopt with `why` set
  /// when there is no interior-case control triangle: parallel tangents, or the tangent lines meet
  /// behind P0 or before P2 (digest §6 item 3).
  static std::optional<ASpline> Make(Vec2 p0, Vec2 t0, double kappa0, Vec2 p2, Vec2 t2,
                                     double kappa2, double delta, std::string* why);
  /// f at barycentric (u, v, w).
  double F(double u, double v, double w) const;
  /// The point on the arc at pencil angle phi in [0, pi/2] through P0: phi = 0 is P2, pi/2 is P0
  /// (digest §8.5, the stable root of the quadratic in u or in 1/u).
  Vec2 AtPhi(double phi) const;
  /// Signed turn of the arc: +1 left (counter-clockwise), -1 right.
  double TurnSign() const { return t0.Cross(t2) >= 0 ? 1.0 : -1.0; }
};

}  // namespace sculpt::skin

#endif  // SCULPT_SKIN_CURVES_H_
