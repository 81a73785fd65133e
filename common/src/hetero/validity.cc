/// @brief Validity of composite hyperpatches: spans, skins, Jacobian sign, cell overlap.
#include "sculpt/hetero/validity.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "sculpt/core/check.h"

namespace sculpt::hetero {
namespace {

using Net = std::array<Vec3, 64>;
constexpr double kPi = 3.14159265358979323846;

// Control point q (0..3) along `dir` of the line through the fixed indices (a, b).
int SpanIndex(int dir, int a, int b, int q) {
  switch (dir) {
    case 0: return Hyperpatch::Index(q, a, b);
    case 1: return Hyperpatch::Index(a, q, b);
    default: return Hyperpatch::Index(a, b, q);
  }
}
// Point (j, k) of slice skin `s` across direction `dir` (the slice fixes index `dir` to s).
int SkinIndex(int dir, int s, int j, int k) {
  switch (dir) {
    case 0: return Hyperpatch::Index(s, j, k);
    case 1: return Hyperpatch::Index(j, s, k);
    default: return Hyperpatch::Index(j, k, s);
  }
}

double NetScale(const Net& net) {
  Aabb b;
  for (const Vec3& p : net) b.Extend(p);
  return std::max(b.Diagonal(), 1e-300);
}

struct Mat3 {
  std::array<Vec3, 3> rows;
};

Mat3 Rot(int axis, double deg) {
  const double c = std::cos(deg * kPi / 180.0), s = std::sin(deg * kPi / 180.0);
  if (axis == 0) return {{Vec3{1, 0, 0}, Vec3{0, c, -s}, Vec3{0, s, c}}};
  if (axis == 1) return {{Vec3{c, 0, s}, Vec3{0, 1, 0}, Vec3{-s, 0, c}}};
  return {{Vec3{c, -s, 0}, Vec3{s, c, 0}, Vec3{0, 0, 1}}};
}

Mat3 Mul(const Mat3& a, const Mat3& b) {
  Mat3 r;
  for (int i = 0; i < 3; ++i) {
    const Vec3& ai = a.rows[static_cast<size_t>(i)];
    r.rows[static_cast<size_t>(i)] = b.rows[0] * ai.x + b.rows[1] * ai.y + b.rows[2] * ai.z;
  }
  return r;
}

// Candidate frames relative to the canonical one: Euler angles on a 15° grid in [0°, 90°)
// (monotonicity is blind to axis permutations and sign flips, so 90° is a full period).
// Ordered by how many angles are non-zero so the canonical frame and single-axis rotations,
// which pass for ordinary cells, are tried first.
const std::vector<Mat3>& CandidateFrames() {
  static const std::vector<Mat3> frames = [] {
    struct Entry {
      int nonzero;
      int order;
      Mat3 m;
    };
    std::vector<Entry> e;
    int order = 0;
    for (int c = 0; c < 6; ++c) {
      for (int b = 0; b < 6; ++b) {
        for (int a = 0; a < 6; ++a) {
          const Mat3 m = Mul(Rot(0, 15.0 * a), Mul(Rot(1, 15.0 * b), Rot(2, 15.0 * c)));
          e.push_back({(a > 0) + (b > 0) + (c > 0), order++, m});
        }
      }
    }
    std::stable_sort(e.begin(), e.end(),
                     [](const Entry& x, const Entry& y) { return x.nonzero < y.nonzero; });
    std::vector<Mat3> out;
    for (const Entry& x : e) out.push_back(x.m);
    return out;
  }();
  return frames;
}

// True when the two patches' corners project onto disjoint intervals (gap > tol) along axis n:
// the patches, being in their corners' convex hull, are then apart.
bool SeparatedAlong(const Vec3& n, const std::array<Vec3, 4>& a, const std::array<Vec3, 4>& b,
                    double tol) {
  if (n.LengthSqr() == 0) return false;
  double alo = 1e300, ahi = -1e300, blo = 1e300, bhi = -1e300;
  for (const Vec3& p : a) {
    const double x = n.Dot(p);
    alo = std::min(alo, x);
    ahi = std::max(ahi, x);
  }
  for (const Vec3& p : b) {
    const double x = n.Dot(p);
    blo = std::min(blo, x);
    bhi = std::max(bhi, x);
  }
  return alo > bhi + tol || blo > ahi + tol;
}

// ---- Triangle contact (closed sets: touching counts, per the digest's caveat on §7.3.1) ----

struct Tri {
  Vec3 a, b, c;
};

bool SegmentPiercesTriangle(const Vec3& p, const Vec3& q, const Tri& t) {
  // Möller–Trumbore on the segment p + s (q - p), s in [0, 1].
  const Vec3 d = q - p, e1 = t.b - t.a, e2 = t.c - t.a;
  const Vec3 h = d.Cross(e2);
  const double det = e1.Dot(h);
  const double scale = e1.Length() * e2.Length() * d.Length();
  if (std::abs(det) <= 1e-14 * scale) return false;  // parallel: left to the distance tests
  const double inv = 1.0 / det;
  const Vec3 s = p - t.a;
  const double u = inv * s.Dot(h);
  if (u < 0 || u > 1) return false;
  const Vec3 qv = s.Cross(e1);
  const double v = inv * d.Dot(qv);
  if (v < 0 || u + v > 1) return false;
  const double r = inv * e2.Dot(qv);
  return r >= 0 && r <= 1;
}

// Squared distance between segments (Ericson, Real-Time Collision Detection §5.1.9).
double SegSegDist2(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.Dot(d1), e = d2.Dot(d2), f = d2.Dot(r);
  double s = 0, t = 0;
  constexpr double kEps = 1e-300;
  if (a <= kEps && e <= kEps) return r.Dot(r);
  if (a <= kEps) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.Dot(r);
    if (e <= kEps) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.Dot(d2), denom = a * e - b * b;
      s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  const Vec3 diff = (p1 + d1 * s) - (p2 + d2 * t);
  return diff.Dot(diff);
}

// Squared distance from p to a non-degenerate triangle (Ericson §5.1.5).
double PointTriDist2(const Vec3& p, const Tri& t) {
  const Vec3 ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
  const double d1 = ab.Dot(ap), d2 = ac.Dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.Dot(ap);
  const Vec3 bp = p - t.b;
  const double d3 = ab.Dot(bp), d4 = ac.Dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.Dot(bp);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const Vec3 x = t.a + ab * (d1 / (d1 - d3)) - p;
    return x.Dot(x);
  }
  const Vec3 cp = p - t.c;
  const double d5 = ab.Dot(cp), d6 = ac.Dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.Dot(cp);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const Vec3 x = t.a + ac * (d2 / (d2 - d6)) - p;
    return x.Dot(x);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const Vec3 x = t.b + (t.c - t.b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))) - p;
    return x.Dot(x);
  }
  const double denom = 1.0 / (va + vb + vc);
  const Vec3 x = t.a + ab * (vb * denom) + ac * (vc * denom) - p;
  return x.Dot(x);
}

bool Degenerate(const Tri& t) {
  const Vec3 n = (t.b - t.a).Cross(t.c - t.a);
  const double s = std::max({(t.b - t.a).LengthSqr(), (t.c - t.a).LengthSqr(),
                             (t.c - t.b).LengthSqr()});
  return n.LengthSqr() <= 1e-24 * s * s;
}

bool TrianglesTouch(const Tri& x, const Tri& y, double tol) {
  const Vec3 xs[3] = {x.a, x.b, x.c}, ys[3] = {y.a, y.b, y.c};
  for (int i = 0; i < 3; ++i) {
    if (SegmentPiercesTriangle(xs[i], xs[(i + 1) % 3], y)) return true;
    if (SegmentPiercesTriangle(ys[i], ys[(i + 1) % 3], x)) return true;
  }
  const double tol2 = tol * tol;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (SegSegDist2(xs[i], xs[(i + 1) % 3], ys[j], ys[(j + 1) % 3]) <= tol2) return true;
    }
  }
  // Containment of a vertex in the other (coplanar overlap with no edge crossing).
  if (!Degenerate(y)) {
    for (const Vec3& p : xs) {
      if (PointTriDist2(p, y) <= tol2) return true;
    }
  }
  if (!Degenerate(x)) {
    for (const Vec3& p : ys) {
      if (PointTriDist2(p, x) <= tol2) return true;
    }
  }
  return false;
}

bool BoxesTouch(const Aabb& a, const Aabb& b, double tol) {
  return a.min.x <= b.max.x + tol && b.min.x <= a.max.x + tol && a.min.y <= b.max.y + tol &&
         b.min.y <= a.max.y + tol && a.min.z <= b.max.z + tol && b.min.z <= a.max.z + tol;
}

struct Skin {
  Aabb box;
  std::array<Aabb, 9> patch_box;
  std::array<std::array<Vec3, 4>, 9> corners;  // p00, p10, p01, p11 of each bilinear patch
  std::array<Vec3, 9> normal;                  // unit normal from the diagonals (0 if degenerate)
  std::array<std::array<Tri, 4>, 9> tris;  // both diagonal splits of each bilinear patch
};

Skin MakeSkin(const Net& net, int dir, int s) {
  Skin skin;
  for (int j = 0; j < 3; ++j) {
    for (int k = 0; k < 3; ++k) {
      const Vec3& p00 = net[static_cast<size_t>(SkinIndex(dir, s, j, k))];
      const Vec3& p10 = net[static_cast<size_t>(SkinIndex(dir, s, j + 1, k))];
      const Vec3& p01 = net[static_cast<size_t>(SkinIndex(dir, s, j, k + 1))];
      const Vec3& p11 = net[static_cast<size_t>(SkinIndex(dir, s, j + 1, k + 1))];
      const size_t idx = static_cast<size_t>(j * 3 + k);
      Aabb b;
      for (const Vec3* p : {&p00, &p10, &p01, &p11}) b.Extend(*p);
      skin.patch_box[idx] = b;
      skin.box.Extend(b.min);
      skin.box.Extend(b.max);
      skin.tris[idx] = {Tri{p00, p10, p11}, Tri{p00, p11, p01}, Tri{p00, p10, p01},
                        Tri{p10, p11, p01}};
      skin.corners[idx] = {p00, p10, p01, p11};
      const Vec3 n = (p11 - p00).Cross(p01 - p10);
      const double len = n.Length();
      skin.normal[idx] = len > 0 ? n / len : Vec3{};
    }
  }
  return skin;
}

}  // namespace

const char* ReasonName(Reason r) {
  switch (r) {
    case Reason::kOk: return "OK";
    case Reason::kNotFinite: return "NOT_FINITE";
    case Reason::kMaterialNotInSimplex: return "MATERIAL_NOT_IN_SIMPLEX";
    case Reason::kDegenerateCell: return "DEGENERATE_CELL";
    case Reason::kSpanNotOrdered: return "SPAN_NOT_ORDERED";
    case Reason::kSkinIntersect: return "SKIN_INTERSECT";
    case Reason::kJacobianSign: return "JACOBIAN_SIGN";
    case Reason::kCellOverlap: return "CELL_OVERLAP";
    case Reason::kIrregularCorner: return "IRREGULAR_CORNER";
    case Reason::kNotContinuous: return "NOT_CONTINUOUS";
    case Reason::kBadIntent: return "BAD_INTENT";
  }
  return "UNKNOWN";
}

std::string Rejection::ToString() const {
  std::ostringstream os;
  os << ReasonName(reason);
  if (cell >= 0) os << " cell=" << cell;
  if (other_cell >= 0) os << " other_cell=" << other_cell;
  if (direction >= 0) os << " direction=" << "uvw"[direction];
  if (span >= 0) os << " span=(" << span / 4 << "," << span % 4 << ")";
  if (coord >= 0) os << " coord=" << coord;
  if (skin_a >= 0) os << " skins=(" << skin_a << "," << skin_b << ")";
  if (uvw.x >= 0) os << " uvw=(" << uvw.x << "," << uvw.y << "," << uvw.z << ")";
  if (!detail.empty()) os << ": " << detail;
  return os.str();
}

Status Rejection::ToStatus() const {
  return ok() ? Status::Ok() : FailedPrecondition(ToString());
}

bool CanonicalFrame(const Net& net, std::array<Vec3, 3>* frame) {
  Vec3 mean[3];
  for (int dir = 0; dir < 3; ++dir) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        mean[dir] += net[static_cast<size_t>(SpanIndex(dir, a, b, 3))] -
                     net[static_cast<size_t>(SpanIndex(dir, a, b, 0))];
      }
    }
  }
  const double scale = NetScale(net) * 16.0;
  const double lu = mean[0].Length();
  if (lu <= 1e-9 * scale) return false;
  const Vec3 e0 = mean[0] / lu;
  Vec3 v = mean[1] - e0 * e0.Dot(mean[1]);
  const double lv = v.Length();
  if (lv <= 1e-9 * scale) return false;
  const Vec3 e1 = v / lv;
  Vec3 e2 = e0.Cross(e1);
  // The w chords must leave the (u, v) plane, or the cell has no volume.
  if (std::abs(e2.Dot(mean[2])) <= 1e-9 * scale) return false;
  if (e2.Dot(mean[2]) < 0) e2 = -e2;
  *frame = {e0, e1, e2};
  return true;
}

Rejection CheckSpansOrdered(const Net& net, const CellCheckOptions& opt, int* frame_index) {
  Rejection r;
  std::array<Vec3, 3> frame;
  if (!CanonicalFrame(net, &frame)) {
    r.reason = Reason::kDegenerateCell;
    r.detail = "mean parametric directions are coplanar (zero volume)";
    return r;
  }
  const double tol = opt.relative_tolerance * NetScale(net);
  // 48 spans x 3 consecutive differences, in canonical coordinates.
  std::array<Vec3, 144> d;
  for (int dir = 0; dir < 3; ++dir) {
    for (int s = 0; s < 16; ++s) {
      for (int q = 0; q < 3; ++q) {
        const Vec3 w = net[static_cast<size_t>(SpanIndex(dir, s / 4, s % 4, q + 1))] -
                       net[static_cast<size_t>(SpanIndex(dir, s / 4, s % 4, q))];
        d[static_cast<size_t>((dir * 16 + s) * 3 + q)] = {frame[0].Dot(w), frame[1].Dot(w),
                                                          frame[2].Dot(w)};
      }
    }
  }
  const auto& frames = CandidateFrames();
  const size_t tries = opt.frame_search ? frames.size() : 1;
  // How far a frame is from ordering every span: per span and coordinate, the smaller of the
  // positive and negative parts of its three differences; 0 means requirement 1 holds.
  auto score = [&](const Mat3& m, bool record) {
    double total = 0;
    for (int span = 0; span < 48; ++span) {
      for (int c = 0; c < 3; ++c) {
        double pos = 0, neg = 0;
        for (int q = 0; q < 3; ++q) {
          const double x = m.rows[static_cast<size_t>(c)].Dot(d[static_cast<size_t>(span * 3 + q)]);
          pos += std::max(x - tol, 0.0);
          neg += std::max(-x - tol, 0.0);
        }
        const double v = std::min(pos, neg);
        if (v > 0 && record && r.direction < 0) {
          r.direction = span / 16;
          r.span = span % 16;
          r.coord = c;
        }
        total += v;
      }
    }
    return total;
  };
  std::vector<std::pair<double, size_t>> ranked;
  for (size_t f = 0; f < tries; ++f) {
    const double v = score(frames[f], f == 0);
    if (v == 0) {
      if (frame_index) *frame_index = static_cast<int>(f);
      return Rejection{};
    }
    ranked.emplace_back(v, f);
  }
  if (opt.frame_search) {
    // The grid is coarse: refine the three best frames by small rotations about each axis,
    // halving the step from 7.5° to under 0.1° (deterministic, so still rotation invariant).
    std::partial_sort(ranked.begin(), ranked.begin() + std::min<size_t>(3, ranked.size()),
                      ranked.end());
    for (size_t t = 0; t < std::min<size_t>(3, ranked.size()); ++t) {
      Mat3 m = frames[ranked[t].second];
      double best = ranked[t].first;
      for (double step = 7.5; step > 0.05 && best > 0; step *= 0.5) {
        bool improved = true;
        while (improved && best > 0) {
          improved = false;
          for (int axis = 0; axis < 3 && best > 0; ++axis) {
            for (double sign : {1.0, -1.0}) {
              const Mat3 cand = Mul(Rot(axis, sign * step), m);
              const double v = score(cand, false);
              if (v < best) {
                best = v;
                m = cand;
                improved = true;
              }
            }
          }
        }
      }
      if (best == 0) {
        if (frame_index) *frame_index = static_cast<int>(tries);  // a refined frame
        return Rejection{};
      }
    }
  }
  r.reason = Reason::kSpanNotOrdered;
  r.detail = "no monotone frame among " + std::to_string(tries) + " candidate frames" +
             (opt.frame_search ? " and their refinements" : "");
  return r;
}

Rejection CheckSkinsDisjoint(const Net& net, const CellCheckOptions& opt) {
  const double tol = opt.contact_tolerance * NetScale(net);
  for (int dir = 0; dir < 3; ++dir) {
    std::array<Skin, 4> skins;
    for (int s = 0; s < 4; ++s) skins[static_cast<size_t>(s)] = MakeSkin(net, dir, s);
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        const Skin& sa = skins[static_cast<size_t>(a)];
        const Skin& sb = skins[static_cast<size_t>(b)];
        if (!BoxesTouch(sa.box, sb.box, tol)) continue;
        for (int pa = 0; pa < 9; ++pa) {
          for (int pb = 0; pb < 9; ++pb) {
            const size_t ia = static_cast<size_t>(pa), ib = static_cast<size_t>(pb);
            if (!BoxesTouch(sa.patch_box[ia], sb.patch_box[ib], tol) ||
                SeparatedAlong(sa.normal[ia], sa.corners[ia], sb.corners[ib], tol) ||
                SeparatedAlong(sb.normal[ib], sa.corners[ia], sb.corners[ib], tol)) {
              continue;
            }
            for (const Tri& x : sa.tris[static_cast<size_t>(pa)]) {
              for (const Tri& y : sb.tris[static_cast<size_t>(pb)]) {
                if (TrianglesTouch(x, y, tol)) {
                  Rejection r;
                  r.reason = Reason::kSkinIntersect;
                  r.direction = dir;
                  r.skin_a = a;
                  r.skin_b = b;
                  r.detail = "patches " + std::to_string(pa) + " and " + std::to_string(pb) +
                             " touch";
                  return r;
                }
              }
            }
          }
        }
      }
    }
  }
  return Rejection{};
}

namespace {

// Values of a Bézier-form vector field with (nu, nv, nw) control points (degrees nu-1, ...) at
// the (n+1)^3 nodes t = i/n, by contracting one axis at a time (w, then v, then u).
template <int NU, int NV, int NW>
void EvaluateOnNodes(const Vec3 (&c)[NU][NV][NW], int n, std::vector<Vec3>* out) {
  auto basis = [](int count, double t, double* b) {
    if (count == 4) {
      const auto v = Bernstein3(t);
      std::copy(v.begin(), v.end(), b);
    } else {
      const auto v = Bernstein2(t);
      std::copy(v.begin(), v.end(), b);
    }
  };
  const int m = n + 1;
  std::vector<double> bu(static_cast<size_t>(m * NU)), bv(static_cast<size_t>(m * NV)),
      bw(static_cast<size_t>(m * NW));
  for (int t = 0; t < m; ++t) {
    basis(NU, static_cast<double>(t) / n, &bu[static_cast<size_t>(t * NU)]);
    basis(NV, static_cast<double>(t) / n, &bv[static_cast<size_t>(t * NV)]);
    basis(NW, static_cast<double>(t) / n, &bw[static_cast<size_t>(t * NW)]);
  }
  std::vector<Vec3> tw(static_cast<size_t>(NU * NV * m)), tv(static_cast<size_t>(NU * m * m));
  for (int i = 0; i < NU; ++i)
    for (int j = 0; j < NV; ++j)
      for (int w = 0; w < m; ++w) {
        Vec3 acc;
        for (int k = 0; k < NW; ++k) acc += c[i][j][k] * bw[static_cast<size_t>(w * NW + k)];
        tw[static_cast<size_t>((i * NV + j) * m + w)] = acc;
      }
  for (int i = 0; i < NU; ++i)
    for (int v = 0; v < m; ++v)
      for (int w = 0; w < m; ++w) {
        Vec3 acc;
        for (int j = 0; j < NV; ++j) acc += tw[static_cast<size_t>((i * NV + j) * m + w)] * bv[static_cast<size_t>(v * NV + j)];
        tv[static_cast<size_t>((i * m + v) * m + w)] = acc;
      }
  out->assign(static_cast<size_t>(m * m * m), Vec3{});
  for (int u = 0; u < m; ++u)
    for (int v = 0; v < m; ++v)
      for (int w = 0; w < m; ++w) {
        Vec3 acc;
        for (int i = 0; i < NU; ++i) acc += tv[static_cast<size_t>((i * m + v) * m + w)] * bu[static_cast<size_t>(u * NU + i)];
        (*out)[static_cast<size_t>((u * m + v) * m + w)] = acc;
      }
}

}  // namespace

Rejection CheckJacobianSign(const Hyperpatch& patch, int n, double relative_tolerance,
                            double* min_det, double* max_det) {
  const Net& net = patch.positions();
  const double scale = NetScale(net);
  const double tol = relative_tolerance * scale * scale * scale;
  n = std::max(n, 1);
  // Difference nets of the three partial derivatives (seed 001 §2.5 INFERENCE), without the 3s.
  Vec3 du[3][4][4], dv[4][3][4], dw[4][4][3];
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) {
        const Vec3& p = net[static_cast<size_t>(Hyperpatch::Index(i, j, k))];
        if (i < 3) du[i][j][k] = net[static_cast<size_t>(Hyperpatch::Index(i + 1, j, k))] - p;
        if (j < 3) dv[i][j][k] = net[static_cast<size_t>(Hyperpatch::Index(i, j + 1, k))] - p;
        if (k < 3) dw[i][j][k] = net[static_cast<size_t>(Hyperpatch::Index(i, j, k + 1))] - p;
      }
  std::vector<Vec3> pu, pv, pw;
  EvaluateOnNodes(du, n, &pu);
  EvaluateOnNodes(dv, n, &pv);
  EvaluateOnNodes(dw, n, &pw);
  const int m = n + 1;
  double lo = 1e300, hi = -1e300;
  Rejection first_zero;
  for (int node = 0; node < m * m * m; ++node) {
    const size_t s = static_cast<size_t>(node);
    const double det = 27.0 * pu[s].Dot(pv[s].Cross(pw[s]));
    if (std::abs(det) <= tol && first_zero.ok()) {
      first_zero.reason = Reason::kJacobianSign;
      first_zero.uvw = {static_cast<double>(node / (m * m)) / n,
                        static_cast<double>((node / m) % m) / n,
                        static_cast<double>(node % m) / n};
      first_zero.detail = "det J=" + FormatNumber(det) + " at a subdivision node";
    }
    lo = std::min(lo, det);
    hi = std::max(hi, det);
  }
  const double norm = scale * scale * scale;
  if (min_det) *min_det = lo / norm;
  if (max_det) *max_det = hi / norm;
  if (!first_zero.ok()) return first_zero;
  if (lo < 0 && hi > 0) {
    Rejection r;
    r.reason = Reason::kJacobianSign;
    r.detail = "det J changes sign over the subdivision nodes (min " + FormatNumber(lo / norm) +
               ", max " + FormatNumber(hi / norm) + ", scaled)";
    return r;
  }
  return Rejection{};
}

CellVerdict CheckCell(const Hyperpatch& patch, const CellCheckOptions& opt) {
  CellVerdict v;
  for (int i = 0; i < Hyperpatch::kCount; ++i) {
    if (!patch.position(i).IsFinite()) {
      v.rejection.reason = Reason::kNotFinite;
      v.rejection.detail = "point " + std::to_string(i) + " is not finite";
      return v;
    }
    const Status s = ValidateFractions("point[" + std::to_string(i) + "].a", patch.fractions(i),
                                       patch.materials());
    if (!s.ok()) {
      v.rejection.reason = Reason::kMaterialNotInSimplex;
      v.rejection.detail = s.message();
      return v;
    }
  }
  v.rejection = CheckSpansOrdered(patch.positions(), opt, &v.frame_index);
  if (!v.rejection.ok()) return v;
  v.rejection = CheckSkinsDisjoint(patch.positions(), opt);
  if (!v.rejection.ok()) return v;
  if (opt.jacobian_subdivisions > 0) {
    v.rejection = CheckJacobianSign(patch, opt.jacobian_subdivisions, opt.relative_tolerance,
                                    &v.min_det_j, &v.max_det_j);
    if (!v.rejection.ok()) return v;
  }
  v.valid = true;
  return v;
}

// ---------------------------------- Case 2: cell overlap ----------------------------------

namespace {

// A boundary element of a cell (corner, curve or face) in parameter space: fixed[a] is -1 for
// a free axis, else 0 or 1.
struct Element {
  std::array<int, 3> fixed;
};

struct SubCell {
  Net net;
  std::array<double, 3> lo{0, 0, 0}, hi{1, 1, 1};
};

std::vector<Element> AllElements() {
  std::vector<Element> out;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      for (int c = 0; c < 3; ++c) {
        const Element e{{a - 1 == 0 ? -1 : (a == 0 ? 0 : 1), b - 1 == 0 ? -1 : (b == 0 ? 0 : 1),
                         c - 1 == 0 ? -1 : (c == 0 ? 0 : 1)}};
        const int free = (e.fixed[0] < 0) + (e.fixed[1] < 0) + (e.fixed[2] < 0);
        if (free < 3) out.push_back(e);  // 8 corners, 12 curves, 6 faces
      }
    }
  }
  return out;
}

bool OnElement(const Element& e, int i, int j, int k) {
  const int idx[3] = {i, j, k};
  for (int a = 0; a < 3; ++a) {
    if (e.fixed[static_cast<size_t>(a)] >= 0 && idx[a] != 3 * e.fixed[static_cast<size_t>(a)]) {
      return false;
    }
  }
  return true;
}

// Elements of `self` every coefficient of which coincides with some coefficient of `other`.
std::vector<Element> SharedElements(const Net& self, const Net& other, double tol) {
  std::array<bool, 64> coincident{};
  const double tol2 = tol * tol;
  // Sort the other net by x so each lookup scans only the points within tol in x.
  std::array<std::pair<double, int>, 64> xs;
  for (int q = 0; q < 64; ++q) xs[static_cast<size_t>(q)] = {other[static_cast<size_t>(q)].x, q};
  std::sort(xs.begin(), xs.end());
  for (size_t s = 0; s < 64; ++s) {
    auto it = std::lower_bound(xs.begin(), xs.end(), std::pair<double, int>{self[s].x - tol, -1});
    for (; it != xs.end() && it->first <= self[s].x + tol; ++it) {
      if ((self[s] - other[static_cast<size_t>(it->second)]).LengthSqr() <= tol2) {
        coincident[s] = true;
        break;
      }
    }
  }
  std::vector<Element> shared;
  static const std::vector<Element> all = AllElements();
  for (const Element& e : all) {
    bool all_in = true;
    for (int i = 0; i < 4 && all_in; ++i) {
      for (int j = 0; j < 4 && all_in; ++j) {
        for (int k = 0; k < 4 && all_in; ++k) {
          if (OnElement(e, i, j, k) && !coincident[static_cast<size_t>(Hyperpatch::Index(i, j, k))]) {
            all_in = false;
          }
        }
      }
    }
    if (all_in) shared.push_back(e);
  }
  return shared;
}

// The sub-cell's control points on element e, when the sub-cell reaches e.
bool ElementPoints(const SubCell& s, const Element& e, std::vector<Vec3>* pts) {
  for (int a = 0; a < 3; ++a) {
    const int f = e.fixed[static_cast<size_t>(a)];
    if (f == 0 && s.lo[static_cast<size_t>(a)] != 0.0) return false;
    if (f == 1 && s.hi[static_cast<size_t>(a)] != 1.0) return false;
  }
  pts->clear();
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      for (int k = 0; k < 4; ++k) {
        if (OnElement(e, i, j, k)) pts->push_back(s.net[static_cast<size_t>(Hyperpatch::Index(i, j, k))]);
      }
    }
  }
  return true;
}

Aabb BoxOf(const std::vector<Vec3>& pts) {
  Aabb b;
  for (const Vec3& p : pts) b.Extend(p);
  return b;
}

void Project(const Vec3& n, std::span<const Vec3> pts, double* lo, double* hi) {
  for (const Vec3& p : pts) {
    const double x = n.Dot(p);
    *lo = std::min(*lo, x);
    *hi = std::max(*hi, x);
  }
}

struct OverlapJob {
  const std::vector<Element>* shared_a;
  const std::vector<Element>* shared_b;
  const OverlapOptions* opt;
  double tol;
  int boxes = 0;

  Aabb Box(const SubCell& s) const {
    Aabb b;
    for (const Vec3& p : s.net) b.Extend(p);
    return b;
  }

  // True when a and b face each other across a shared element: the parts of the shared element
  // each reaches are in contact, so their contact is the legitimate gluing of (6.8).
  // The pair is excused only when their contact is explained by the shared parts they reach:
  // across a shared face, the overlap of the two nets along the face normal must stay within
  // the face's own spread along it (a coefficient pushed through the face leaves it); at a
  // shared curve or corner, likewise along the direction between the two sub-cells.
  bool Facing(const SubCell& a, const SubCell& b, int level) const {
    std::vector<Vec3> pa, pb;
    for (const Element& ea : *shared_a) {
      if (!ElementPoints(a, ea, &pa)) continue;
      const Aabb ba = BoxOf(pa);
      for (const Element& eb : *shared_b) {
        if (!ElementPoints(b, eb, &pb)) continue;
        const Aabb bb = BoxOf(pb);
        if (!BoxesTouch(ba, bb, tol)) continue;
        // A shared face's normal test is decisive at once; curves and corners, whose test only
        // looks along one direction, wait until the sub-cells are small.
        const bool face = pa.size() == 16 && pb.size() == 16;
        if (!face && level < opt->excuse_depth) continue;
        // The axis along which the shared part must explain the contact: the face normal, or
        // for a curve or a corner the direction between the sub-cells' centroids (made
        // perpendicular to the curve's chord).
        Vec3 n;
        if (face) {
          n = (pa[15] - pa[0]).Cross(pa[12] - pa[3]);
        } else {
          Vec3 ca, cb;
          for (const Vec3& p : a.net) ca += p;
          for (const Vec3& p : b.net) cb += p;
          n = cb - ca;
          if (pa.size() == 4) {
            const Vec3 t = pa[3] - pa[0];
            if (t.LengthSqr() > 0) n = n - t * (n.Dot(t) / t.LengthSqr());
          }
        }
        const double len = n.Length();
        if (len <= 0) continue;
        const Vec3 u = n / len;
        double alo = 1e300, ahi = -1e300, blo = 1e300, bhi = -1e300, flo = 1e300, fhi = -1e300;
        Project(u, a.net, &alo, &ahi);
        Project(u, b.net, &blo, &bhi);
        Project(u, pa, &flo, &fhi);
        Project(u, pb, &flo, &fhi);
        const double olo = std::max(alo, blo), ohi = std::min(ahi, bhi);
        if (olo >= flo - tol && ohi <= fhi + tol) return true;
      }
    }
    return false;
  }

  // Separating axes beyond x, y, z: each sub-cell's canonical frame. The convex hull of the
  // control points holds the sub-cell, so disjoint projections of the nets separate the cells;
  // this keeps thin rotated sub-cells, whose world boxes are loose, from reaching the leaf level.
  bool Separated(const SubCell& a, const SubCell& b) const {
    for (const SubCell* s : {&a, &b}) {
      std::array<Vec3, 3> frame;
      if (!CanonicalFrame(s->net, &frame)) continue;
      for (const Vec3& n : frame) {
        double alo = 1e300, ahi = -1e300, blo = 1e300, bhi = -1e300;
        for (const Vec3& p : a.net) {
          const double x = n.Dot(p);
          alo = std::min(alo, x);
          ahi = std::max(ahi, x);
        }
        for (const Vec3& p : b.net) {
          const double x = n.Dot(p);
          blo = std::min(blo, x);
          bhi = std::max(bhi, x);
        }
        if (std::min(ahi, bhi) - std::max(alo, blo) <= tol) return true;
      }
    }
    return false;
  }

  static std::pair<SubCell, SubCell> Halve(const SubCell& s, int axis) {
    SubCell lo = s, hi = s;
    SplitNet(s.net, axis, 0.5, &lo.net, &hi.net);
    const double mid = 0.5 * (s.lo[static_cast<size_t>(axis)] + s.hi[static_cast<size_t>(axis)]);
    lo.hi[static_cast<size_t>(axis)] = mid;
    hi.lo[static_cast<size_t>(axis)] = mid;
    return {lo, hi};
  }

  bool Overlap(const SubCell& a, const SubCell& b, int level) {
    ++boxes;
    if (!Box(a).Overlaps(Box(b), tol)) return false;
    if (Separated(a, b)) return false;
    if (Facing(a, b, level)) return false;
    if (level >= opt->max_depth) return true;  // conservative leaf policy (digest §3.4 gap)
    const int axis = level % 3;  // alternate U, V, W (§7.3.2)
    const auto [a0, a1] = Halve(a, axis);
    const auto [b0, b1] = Halve(b, axis);
    return Overlap(a0, b0, level + 1) || Overlap(a0, b1, level + 1) ||
           Overlap(a1, b0, level + 1) || Overlap(a1, b1, level + 1);
  }
};

}  // namespace

bool NetsOverlap(const Net& a, const Net& b, const OverlapOptions& opt, int* boxes_tested) {
  const double scale = std::max(NetScale(a), NetScale(b));
  const double tol = opt.relative_tolerance * scale;
  SubCell sa{a}, sb{b};
  Aabb ba, bb;
  for (const Vec3& p : a) ba.Extend(p);
  for (const Vec3& p : b) bb.Extend(p);
  if (!ba.Overlaps(bb, tol)) {
    if (boxes_tested) *boxes_tested = 1;
    return false;
  }
  // Coincidence of coefficients is judged far tighter than the contact tolerance: shared
  // coefficients are copies of one value.
  const std::vector<Element> shared_a = SharedElements(a, b, 1e-9 * scale);
  const std::vector<Element> shared_b = SharedElements(b, a, 1e-9 * scale);
  OverlapJob job{&shared_a, &shared_b, &opt, tol};
  const bool overlap = job.Overlap(sa, sb, 0);
  if (boxes_tested) *boxes_tested = job.boxes;
  return overlap;
}

// ---------------------------------- ValidityChecker ----------------------------------

const Aabb& ValidityChecker::CellBox(const CompositeModel& model, int cell) {
  if (box_cache_.size() < model.cell_count()) box_cache_.resize(model.cell_count(), {0, Aabb{}});
  auto& e = box_cache_[static_cast<size_t>(cell)];
  if (e.first != model.cell(cell).version) e = {model.cell(cell).version, model.CellBounds(cell)};
  return e.second;
}

void ValidityChecker::Clear() {
  cell_cache_.clear();
  pair_cache_.clear();
  box_cache_.clear();
  hits_ = 0;
}

CellVerdict ValidityChecker::CheckOneCell(const CompositeModel& model, int cell) {
  const uint64_t version = model.cell(cell).version;
  auto it = cell_cache_.find(cell);
  if (it != cell_cache_.end() && it->second.version == version) {
    ++hits_;
    return it->second.verdict;
  }
  CellVerdict v = CheckCell(model.CellPatch(cell), cell_);
  v.rejection.cell = cell;
  cell_cache_[cell] = {version, v};
  return v;
}

Rejection ValidityChecker::CheckPair(const CompositeModel& model, int a, int b) {
  if (a > b) std::swap(a, b);
  const uint64_t key = (static_cast<uint64_t>(a) << 32) | static_cast<uint32_t>(b);
  const uint64_t va = model.cell(a).version, vb = model.cell(b).version;
  bool overlap;
  auto it = pair_cache_.find(key);
  if (it != pair_cache_.end() && it->second.version_a == va && it->second.version_b == vb) {
    ++hits_;
    overlap = it->second.overlap;
  } else {
    overlap = NetsOverlap(model.CellNet(a), model.CellNet(b), overlap_);
    pair_cache_[key] = {va, vb, overlap};
  }
  Rejection r;
  if (overlap) {
    r.reason = Reason::kCellOverlap;
    r.cell = a;
    r.other_cell = b;
    r.detail = "cells overlap beyond their shared corners, curves and faces";
  }
  return r;
}

ValidityChecker::Report ValidityChecker::CheckModel(const CompositeModel& model,
                                                    bool stop_at_first) {
  Report rep;
  const int hits0 = hits_;
  const int n = static_cast<int>(model.cell_count());
  std::vector<char> valid(static_cast<size_t>(n), 0);
  for (int c = 0; c < n; ++c) {
    const int h = hits_;
    const CellVerdict v = CheckOneCell(model, c);
    if (h == hits_) ++rep.cells_checked;
    valid[static_cast<size_t>(c)] = v.valid;
    if (!v.valid) {
      rep.valid = false;
      rep.rejections.push_back(v.rejection);
      if (stop_at_first) return rep;
    }
  }
  // Sweep and prune on x over the cells' control-point boxes; Case 2 only for valid cells.
  std::vector<Aabb> boxes(static_cast<size_t>(n));
  std::vector<int> order(static_cast<size_t>(n));
  double scale = 0;
  for (int c = 0; c < n; ++c) {
    boxes[static_cast<size_t>(c)] = CellBox(model, c);
    scale = std::max(scale, boxes[static_cast<size_t>(c)].Diagonal());
    order[static_cast<size_t>(c)] = c;
  }
  const double tol = overlap_.relative_tolerance * scale;
  std::sort(order.begin(), order.end(), [&](int x, int y) {
    return boxes[static_cast<size_t>(x)].min.x < boxes[static_cast<size_t>(y)].min.x ||
           (boxes[static_cast<size_t>(x)].min.x == boxes[static_cast<size_t>(y)].min.x && x < y);
  });
  for (size_t i = 0; i < order.size(); ++i) {
    const int a = order[i];
    if (!valid[static_cast<size_t>(a)]) continue;
    for (size_t j = i + 1; j < order.size(); ++j) {
      const int b = order[j];
      if (boxes[static_cast<size_t>(b)].min.x >= boxes[static_cast<size_t>(a)].max.x - tol) break;
      if (!valid[static_cast<size_t>(b)]) continue;
      if (!boxes[static_cast<size_t>(a)].Overlaps(boxes[static_cast<size_t>(b)], tol)) continue;
      const int h = hits_;
      const Rejection r = CheckPair(model, a, b);
      if (h == hits_) ++rep.pairs_tested;
      if (!r.ok()) {
        rep.valid = false;
        rep.rejections.push_back(r);
        if (stop_at_first) return rep;
      }
    }
  }
  rep.cache_hits = hits_ - hits0;
  return rep;
}

ValidityChecker::Report ValidityChecker::CheckCells(const CompositeModel& model,
                                                    std::span<const int> cells,
                                                    bool stop_at_first) {
  Report rep;
  const int hits0 = hits_;
  const int n = static_cast<int>(model.cell_count());
  for (int c : cells) {
    if (c < 0 || c >= n) continue;
    const int h = hits_;
    const CellVerdict v = CheckOneCell(model, c);
    if (h == hits_) ++rep.cells_checked;
    if (!v.valid) {
      rep.valid = false;
      rep.rejections.push_back(v.rejection);
      if (stop_at_first) return rep;
    }
  }
  if (!rep.valid) return rep;
  double scale = 0;
  std::vector<Aabb> boxes(static_cast<size_t>(n));
  for (int c = 0; c < n; ++c) {
    boxes[static_cast<size_t>(c)] = CellBox(model, c);
    scale = std::max(scale, boxes[static_cast<size_t>(c)].Diagonal());
  }
  const double tol = overlap_.relative_tolerance * scale;
  for (int a : cells) {
    if (a < 0 || a >= n) continue;
    for (int b = 0; b < n; ++b) {
      if (b == a || !boxes[static_cast<size_t>(a)].Overlaps(boxes[static_cast<size_t>(b)], tol)) {
        continue;
      }
      // A touched pair is checked once even when both cells were touched.
      if (std::find(cells.begin(), cells.end(), b) != cells.end() && b < a) continue;
      if (!CheckOneCell(model, b).valid) continue;
      const int h = hits_;
      const Rejection r = CheckPair(model, a, b);
      if (h == hits_) ++rep.pairs_tested;
      if (!r.ok()) {
        rep.valid = false;
        rep.rejections.push_back(r);
        if (stop_at_first) return rep;
      }
    }
  }
  rep.cache_hits = hits_ - hits0;
  return rep;
}

}  // namespace sculpt::hetero
