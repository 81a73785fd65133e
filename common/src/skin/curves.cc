/// @brief The mother curve, the distance function, the offset and the corrected A-spline
/// (digest §2.4, §2.6, §3.3-3.4, §8.4-8.5).
#include "sculpt/skin/curves.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace sculpt::skin {

HermiteMother HermiteMother::FromBalls(const OrientedBall& b0, const OrientedBall& b1) {
  HermiteMother m;
  const Vec2 chord = b1.c - b0.c;
  m.length = chord.Length();
  const Vec2 m0 = b0.t() * m.length, m1 = b1.t() * m.length;
  // Power form of h00 C0 + h10 m0 + h01 C1 + h11 m1 (digest §2.6, h10 = s^3 - 2s^2 + s), with
  // C1 - C0 formed once so coordinates near 1e6 do not cancel twice.
  m.a = chord * -2 + m0 + m1;
  m.b = chord * 3 - m0 * 2 - m1;
  m.c = m0;
  m.e = b0.c;
  return m;
}

double HermiteMother::Curvature(double tau) const {
  const Vec2 d1 = D1(tau), d2 = D2(tau);
  const double s = d1.Length();
  return s > 0 ? d1.Cross(d2) / (s * s * s) : 0.0;
}

int HermiteMother::Inflections(std::array<double, 2>& out) const {
  const double q2 = -6 * a.Cross(b), q1 = 6 * c.Cross(a), q0 = 2 * c.Cross(b);
  const double scale = std::max({std::abs(q2), std::abs(q1), std::abs(q0)});
  int n = 0;
  if (scale == 0) return 0;
  double roots[2];
  int nr = 0;
  if (std::abs(q2) <= 1e-14 * scale) {
    if (std::abs(q1) > 1e-14 * scale) roots[nr++] = -q0 / q1;
  } else {
    const double disc = q1 * q1 - 4 * q2 * q0;
    // A (near-)double root is a tangential inflection: the curvature keeps its sign.
    if (disc > 1e-14 * q1 * q1 && disc > 0) {
      const double q = -0.5 * (q1 + std::copysign(std::sqrt(disc), q1));
      roots[nr++] = q / q2;
      if (q != 0) roots[nr++] = q0 / q;
    }
  }
  std::sort(roots, roots + nr);
  for (int i = 0; i < nr; ++i) {
    if (roots[i] > 1e-6 && roots[i] < 1 - 1e-6) out[n++] = roots[i];
  }
  return n;
}

Vec2 Offset::P(double tau) const {
  return mother->P(tau) + mother->D1(tau).Normalized().RotR() * (side * dist->D(tau));
}

Vec2 Offset::D1(double tau) const {
  const Vec2 d1 = mother->D1(tau);
  const double speed = d1.Length();
  const Vec2 t = d1.Normalized();
  const double kappa = mother->Curvature(tau);
  // r^' = |r'|(1 + kappa d) t + d' n for the side's signed distance side*d (digest §3.3).
  return t * (speed * (1 + side * kappa * dist->D(tau))) + t.RotR() * (side * dist->D1(tau));
}

double Offset::OnePlusKappaD(double tau) const {
  return 1 + side * mother->Curvature(tau) * dist->D(tau);
}

std::optional<ASpline> ASpline::Make(Vec2 p0, Vec2 t0, double kappa0, Vec2 p2, Vec2 t2,
                                     double kappa2, double delta, std::string* why) {
  auto fail = [&](const std::string& m) -> std::optional<ASpline> {
    if (why) *why = m;
    return std::nullopt;
  };
  t0 = t0.Normalized();
  t2 = t2.Normalized();
  const Vec2 chord = p2 - p0;
  const double len = chord.Length();
  const double den = t0.Cross(t2);
  if (len == 0) return fail("the end points coincide");
  if (std::abs(den) < 1e-9) return fail("parallel end tangents: no control triangle");
  // P0 + alpha t0 = P2 - beta t2 (digest §8.4 step 1, Cramer).
  const double alpha = chord.Cross(t2) / den;
  const double beta = t0.Cross(chord) / den;
  if (!(alpha > 1e-9 * len) || !(beta > 1e-9 * len)) {
    return fail("the end tangent lines meet outside the interior case (alpha=" +
                std::to_string(alpha / len) + " L, beta=" + std::to_string(beta / len) +
                " L): the A-spline would need the exterior case or an inflection");
  }
  ASpline s;
  s.p0 = p0;
  s.p2 = p2;
  s.p1 = p0 + t0 * alpha;
  s.t0 = t0;
  s.t2 = t2;
  const double area = std::abs((s.p1 - p0).Cross(chord)) / 2;
  if (!(area > 0)) return fail("degenerate control triangle");
  // Normalised curvatures (digest §2.4, corrected (1.6)).
  s.k0 = std::max(0.0, kappa0) * alpha * alpha * alpha / (4 * area);
  s.k2 = std::max(0.0, kappa2) * beta * beta * beta / (4 * area);
  if (!std::isfinite(s.k0) || !std::isfinite(s.k2)) return fail("curvature overflow");
  if (delta <= 0) {
    const Vec2 ch = chord / len;
    const double th0 = std::acos(std::clamp(ch.Dot(t0), -1.0, 1.0));
    const double th2 = std::acos(std::clamp(ch.Dot(t2), -1.0, 1.0));
    delta = std::clamp(2 * std::cos(0.5 * (th0 + th2)), 0.05, 20.0);
  }
  s.delta = delta;
  return s;
}

double ASpline::F(double u, double v, double w) const {
  const double d3 = delta * delta * delta;
  return -v * v * v + d3 / 2 * (u * w * (u + w) - (k0 * u + k2 * w) * v * v) +
         d3 * delta / 2 * (k0 + k2) * u * v * w;
}

Vec2 ASpline::AtPhi(double phi) const {
  const double v = std::sin(phi), w = std::cos(phi);
  const double d3 = delta * delta * delta;
  const double A = d3 / 2 * w;
  const double B = d3 / 2 * (w * w - k0 * v * v) + d3 * delta / 2 * (k0 + k2) * v * w;
  const double C = -v * v * v - d3 / 2 * k2 * w * v * v;
  const double root = std::sqrt(std::max(0.0, B * B - 4 * A * C));
  const Vec2 e1 = p1 - p0, e2 = p2 - p0;
  // The positive root without cancellation: u directly when B > 0, else rho = 1/u, which stays
  // finite as phi -> pi/2 where u -> infinity (digest §8.5).
  if (B > 0) {
    const double u = 2 * C / (-B - root);
    return p0 + (e1 * v + e2 * w) / (u + v + w);
  }
  const double den = -B + root;
  const double rho = den > 0 ? 2 * A / den : 0.0;
  return p0 + (e1 * v + e2 * w) * (rho / (1 + rho * (v + w)));
}

}  // namespace sculpt::skin
