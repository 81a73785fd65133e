/// @brief Adaptive sampling and polyline predicates for the skin (digest §8.5, §7 claims 21-22).
#include "sampling.h"

#include "contour_codec_internal.h"

#include <algorithm>
#include <array>
#include <functional>
#include <cmath>
#include <numbers>
#include <vector>

namespace sculpt::skin::internal {
namespace {

constexpr int kInitialIntervals = 8;
constexpr int kMaxDepth = 40;

double SegmentDistance(Vec2 p, Vec2 a, Vec2 b) {
  const Vec2 ab = b - a;
  const double l2 = ab.LengthSqr();
  double t = l2 > 0 ? (p - a).Dot(ab) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (p - (a + ab * t)).Length();
}

/// Subdivides [ta, tb] of a curve `f` until the chord is within tol; appends points after pa.
template <typename F>
void Refine(const F& f, double ta, Vec2 pa, double tb, Vec2 pb, double tol, int depth,
            Polyline2& out) {
  const double tm = 0.5 * (ta + tb);
  const Vec2 pm = f(tm);
  double dev = SegmentDistance(pm, pa, pb);
  if (dev <= tol) {
    dev = std::max(SegmentDistance(f(0.5 * (ta + tm)), pa, pb),
                   SegmentDistance(f(0.5 * (tm + tb)), pa, pb));
  }
  if (dev > tol && depth < kMaxDepth) {
    Refine(f, ta, pa, tm, pm, tol, depth + 1, out);
    Refine(f, tm, pm, tb, pb, tol, depth + 1, out);
  } else {
    out.push_back(pb);
  }
}

/// Places samples where the chord rule needs them: the sagitta of a chord of length l on a curve
/// of curvature k is about k l^2 / 8, so a stretch of arc needs about l sqrt(k / (8 tol))
/// intervals. That count is integrated over a coarse scan and the samples are put at equal
/// steps of it, so spacing varies smoothly along the curve (which the contour codec's
/// constant-curvature predictor relies on); Refine then checks every interval and splits
/// the few that still exceed the tolerance.
template <typename F>
void SampleCurve(const F& f, double ta, double tb, double tol, bool skip_first, Polyline2& out,
                 int scan_per_unit = 64) {
  const int kScan = std::max(8, static_cast<int>(std::ceil((tb - ta) * scan_per_unit)));
  constexpr double kTarget = 0.75;  // aim below the tolerance so Refine rarely has to split
  constexpr double kDensityFloor = 0.9;
  std::vector<Vec2> p(kScan + 1);
  for (int i = 0; i <= kScan; ++i) p[i] = f(ta + (tb - ta) * i / kScan);
  std::vector<double> kappa(kScan + 1);
  for (int i = 1; i < kScan; ++i) {
    const Vec2 a = p[i] - p[i - 1], b = p[i + 1] - p[i];
    const double den = a.Length() * b.Length() * (a + b).Length();
    kappa[i] = den > 0 ? 2 * std::abs(a.Cross(b)) / den : 0.0;
  }
  kappa[0] = kappa[1];
  kappa[kScan] = kappa[kScan - 1];
  // Density per unit length, floored at a fraction of its mean so nearly straight stretches do not
  // get spacings far beyond their neighbours' (abrupt spacing changes cost the codec most).
  std::vector<double> dens(kScan), len(kScan);
  double mean = 0, length = 0;
  for (int i = 0; i < kScan; ++i) {
    len[i] = (p[i + 1] - p[i]).Length();
    dens[i] = std::sqrt(std::max(kappa[i], kappa[i + 1]) / (8 * kTarget * tol));
    mean += dens[i] * len[i];
    length += len[i];
  }
  const double floor = length > 0 ? kDensityFloor * mean / length : 0.0;
  std::vector<double> cum(kScan + 1);
  for (int i = 0; i < kScan; ++i) cum[i + 1] = cum[i] + len[i] * std::max(dens[i], floor);
  const double total = cum[kScan];
  const int n = std::max(kInitialIntervals, static_cast<int>(std::min(std::ceil(total), 1e7)));
  if (!skip_first) out.push_back(p[0]);
  double prev_t = ta;
  Vec2 prev = p[0];
  int seg = 0;
  for (int j = 1; j <= n; ++j) {
    double t = tb;
    Vec2 pt = p[kScan];
    if (j < n) {
      const double target = total > 0 ? total * j / n : 0.0;
      while (seg < kScan - 1 && cum[seg + 1] < target) ++seg;
      const double span = cum[seg + 1] - cum[seg];
      const double w = total > 0 && span > 0 ? (target - cum[seg]) / span
                                             : static_cast<double>(j) * kScan / n - seg;
      t = ta + (tb - ta) * (seg + std::clamp(w, 0.0, 1.0)) / kScan;
      pt = f(t);
    }
    Refine(f, prev_t, prev, t, pt, tol, 0, out);
    prev_t = t;
    prev = pt;
  }
}

double Orient(Vec2 a, Vec2 b, Vec2 c) { return (b - a).Cross(c - a); }

}  // namespace

void SampleOffset(const Offset& off, double ta, double tb, double tol, bool skip_first,
                  Polyline2& out) {
  SampleCurve([&](double t) { return off.P(t); }, ta, tb, tol, skip_first, out);
}

void SampleSide(const std::function<Vec2(double)>& f, int pieces, double tol, Polyline2& out) {
  SampleCurve(f, 0.0, static_cast<double>(pieces), tol, false, out);
}

void SampleSideForCodec(const std::function<Vec2(double)>& f, int pieces, double tol,
                        const CodecCursor& cursor, Polyline2& out) {
  if (!cursor.has_point) {
    SampleSide(f, pieces, tol, out);
    return;
  }
  const double tb = static_cast<double>(pieces);
  const double step = tol;
  // The chord from the last sample to f(t) is within tol of the curve. The chords here sit at
  // the tolerance more often than SampleCurve's (an escape takes a long one that holds), so the
  // test is stricter than Refine's: seven points, 2 % under the tolerance (five let 4 % through
  // in SkinTest.PolylinesWithinChordToleranceOfExactCurves).
  const double limit = 0.98 * tol;
  // The largest deviation (stopping at the first over the limit, which the escape scales by).
  auto chord_dev = [&](double ta, Vec2 pa, double t, Vec2 pt) {
    double worst = 0;
    for (double w : {0.5, 0.25, 0.75, 0.375, 0.625, 0.125, 0.875}) {
      worst = std::max(worst, SegmentDistance(f(ta + (t - ta) * w), pa, pt));
      if (worst > limit) break;
    }
    return worst;
  };
  auto chord_ok = [&](double ta, Vec2 pa, double t, Vec2 pt) {
    return chord_dev(ta, pa, t, pt) <= limit;
  };
  CodecCursor c = cursor;
  double t_prev = 0;
  Vec2 prev = f(0);
  out.push_back(prev);
  const Vec2 end = f(tb);
  double dt = tb / 64;  // the parameter span of the last chord, a first guess for the next
  if (!c.valid) {
    // A line coded anew (Skc4Restart): the decoder has a point but no turtle; the line sends its
    // first direction and its first chord in full. That chord is the longest whose deviation is
    // within the share of the tolerance the chord rule aims at (0.59), so that the turtle the
    // decoder forms from it predicts the next chords as it does mid-line.
    // The chord is searched for, not predicted, so it is checked at 64 points (the seven of
    // chord_dev let a long first chord over a wiggle through).
    const double aim = 0.59 * tol;
    auto dense_ok = [&](double t, double bound) {
      const Vec2 pt = f(t);
      for (int i = 1; i < 64; ++i) {
        if (SegmentDistance(f(t * i / 64), prev, pt) > bound) return false;
      }
      return true;
    };
    double lo = 0, hi = std::min(tb, dt);
    while (hi < tb && dense_ok(hi, aim)) {
      lo = hi;
      hi = std::min(tb, 2 * hi);
    }
    if (hi >= tb && dense_ok(tb, aim)) {
      lo = tb;
    } else {
      for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (dense_ok(mid, aim) ? lo : hi) = mid;
      }
    }
    if (!(lo > 0)) lo = std::min(tb, dt);  // degenerate: halved below until the chord holds
    while (lo < tb && !dense_ok(lo, limit)) lo *= 0.5;
    const Vec2 p1 = lo >= tb ? end : f(lo);
    out.push_back(p1);
    if (lo >= tb) return;
    c = Skc4Trace(cursor, Polyline2{prev, p1}, step);
    if (!c.valid) {
      SampleCurve(f, lo, tb, tol, true, out);
      return;
    }
    dt = lo;
    t_prev = lo;
    prev = p1;
  }
  const size_t cap = out.size() + (size_t{1} << 22);
  while (out.size() < cap) {
    Vec2 u;
    double along[2];
    internal::Skc4Predict(c, step, &u, &along[0], &along[1]);
    auto proj = [&](Vec2 q) { return (q - c.p).Dot(u); };
    // The parameter where the curve crosses the line across u at distance a along, searched
    // forward from the last sample; tb where the curve ends before it.
    auto crossing = [&](double a, double* t_out) {
      if (proj(end) <= a) return false;
      double lo = t_prev, hi = std::min(tb, t_prev + dt);
      while (hi < tb && proj(f(hi)) < a) {
        lo = hi;
        hi = std::min(tb, hi + dt);
      }
      double glo = proj(f(lo)) - a, ghi = proj(f(hi)) - a;
      for (int i = 0; i < 60 && glo < 0 && ghi > 0; ++i) {
        // Regula falsi, halving where it stalls; 0.02 of a step along is plenty (a point off
        // its column by that is still nearest its lattice point but at cell edges, which the
        // caller's check sends to the other column or an escape).
        double tm = lo + (hi - lo) * (-glo / (ghi - glo));
        if (!(tm > lo && tm < hi) || (i & 3) == 3) tm = 0.5 * (lo + hi);
        const double g = proj(f(tm)) - a;
        if (std::abs(g) < 0.02 * step) {
          *t_out = tm;
          return true;
        }
        if (g < 0) {
          lo = tm;
          glo = g;
        } else {
          hi = tm;
          ghi = g;
        }
      }
      *t_out = 0.5 * (lo + hi);
      return true;
    };
    double t_next = -1;
    Vec2 p_next;
    for (double a : along) {
      double t = 0;
      if (a <= 0 || !crossing(a, &t) || !(t > t_prev)) continue;
      const Vec2 q = f(t);
      CodecCursor trial = c;
      int64_t escape = 1;
      if (!internal::Skc4Advance(trial, q, step, &escape) || escape != 0) continue;
      if (!chord_ok(t_prev, prev, t, q)) continue;
      t_next = t;
      p_next = q;
      break;
    }
    if (t_next < 0 && chord_ok(t_prev, prev, tb, end) && proj(end) <= along[1] + step) {
      t_next = tb;  // the side ends before the predicted chord: its end point
      p_next = end;
    }
    if (t_next < 0) {
      // An escape: a chord on the lattice's columns (half spacings) within the tolerance,
      // shortened from the predicted one by the square root of the deviation's excess (a
      // sagitta grows as the chord squared), 5 % more each time it still exceeds it.
      const double hs = along[1] - along[0];
      double best_t = -1;
      double a_try = std::min(along[0], proj(end) - 0.5 * hs);
      for (int i = 0; i < 40 && a_try >= hs; ++i) {
        const double col = std::floor(a_try / hs) * hs;
        double t = 0;
        if (!crossing(col, &t) || !(t > t_prev)) break;
        const double dev = chord_dev(t_prev, prev, t, f(t));
        if (dev <= limit) {
          best_t = t;
          break;
        }
        a_try = col * std::min(0.95, std::sqrt(limit / dev));
      }
      if (best_t > t_prev) {
        t_next = best_t;
        p_next = f(best_t);
      } else {
        // Not even one spacing: halve the parameter until the chord holds (Refine's rule).
        double t = std::min(tb, t_prev + dt);
        for (int i = 0; i < kMaxDepth && !chord_ok(t_prev, prev, t, f(t)); ++i) {
          t = 0.5 * (t_prev + t);
        }
        t_next = t;
        p_next = f(t);
      }
    }
    out.push_back(p_next);
    if (t_next >= tb) break;
    if (!internal::Skc4Advance(c, p_next, step, nullptr)) {
      // Beyond the codec's reach: the rest as SampleCurve samples it.
      SampleCurve(f, t_next, tb, tol, true, out);
      break;
    }
    dt = std::max(t_next - t_prev, 1e-9 * tb);
    t_prev = t_next;
    prev = p_next;
  }
}

void SampleASpline(const ASpline& s, double tol, bool skip_first, Polyline2& out) {
  // phi runs from pi/2 (P0) down to 0 (P2), so the samples go from P0 to P2.
  const size_t first = out.size();
  SampleCurve([&](double u) { return s.AtPhi(std::numbers::pi / 2 * (1 - u)); }, 0.0, 1.0, tol,
              skip_first, out);
  // The closed form reaches the nodes only up to rounding; pin them so neighbours share them.
  if (!skip_first && out.size() > first) out[first] = s.p0;
  if (!out.empty()) out.back() = s.p2;
}

int CountCrossings(const Polyline2& pts, bool closed) {
  const size_t n = pts.size();
  if (n < 4) return 0;
  const size_t nseg = closed ? n : n - 1;
  struct Seg {
    double minx, maxx, miny, maxy;
    size_t i;
  };
  std::vector<Seg> segs(nseg);
  for (size_t i = 0; i < nseg; ++i) {
    const Vec2 a = pts[i], b = pts[(i + 1) % n];
    segs[i] = {std::min(a.x, b.x), std::max(a.x, b.x), std::min(a.y, b.y), std::max(a.y, b.y), i};
  }
  std::sort(segs.begin(), segs.end(), [](const Seg& a, const Seg& b) { return a.minx < b.minx; });
  int crossings = 0;
  for (size_t s = 0; s < nseg; ++s) {
    const Seg& A = segs[s];
    for (size_t u = s + 1; u < nseg && segs[u].minx <= A.maxx; ++u) {
      const Seg& B = segs[u];
      if (B.miny > A.maxy || B.maxy < A.miny) continue;
      const size_t lo = std::min(A.i, B.i), hi = std::max(A.i, B.i);
      if (hi - lo <= 1 || (closed && lo == 0 && hi == nseg - 1)) continue;
      const Vec2 a = pts[A.i], b = pts[(A.i + 1) % n], c = pts[B.i], d = pts[(B.i + 1) % n];
      const double o1 = Orient(a, b, c), o2 = Orient(a, b, d);
      const double o3 = Orient(c, d, a), o4 = Orient(c, d, b);
      if (((o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0)) && ((o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0))) {
        ++crossings;
      }
    }
  }
  return crossings;
}

int Winding(const Polyline2& pts, Vec2 p) {
  int w = 0;
  const size_t n = pts.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec2 a = pts[i], b = pts[(i + 1) % n];
    if (a.y <= p.y) {
      if (b.y > p.y && Orient(a, b, p) > 0) ++w;
    } else if (b.y <= p.y && Orient(a, b, p) < 0) {
      --w;
    }
  }
  return w;
}

double DistanceToClosed(const Polyline2& pts, Vec2 p) {
  double best = INFINITY;
  const size_t n = pts.size();
  for (size_t i = 0; i < n; ++i) best = std::min(best, SegmentDistance(p, pts[i], pts[(i + 1) % n]));
  return best;
}

}  // namespace sculpt::skin::internal
