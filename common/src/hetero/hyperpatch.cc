/// @brief Heterogeneous tricubic Bézier hyperpatch: evaluation, derivatives, splitting.
#include "sculpt/hetero/hyperpatch.h"

#include <algorithm>
#include <cmath>

#include "sculpt/core/check.h"

namespace sculpt::hetero {

void Aabb::Extend(const Vec3& p) {
  min = {std::min(min.x, p.x), std::min(min.y, p.y), std::min(min.z, p.z)};
  max = {std::max(max.x, p.x), std::max(max.y, p.y), std::max(max.z, p.z)};
}

bool Aabb::Overlaps(const Aabb& o, double tol) const {
  return std::min(max.x, o.max.x) - std::max(min.x, o.min.x) > tol &&
         std::min(max.y, o.max.y) - std::max(min.y, o.min.y) > tol &&
         std::min(max.z, o.max.z) - std::max(min.z, o.min.z) > tol;
}

bool Aabb::Contains(const Vec3& p, double tol) const {
  return p.x >= min.x - tol && p.x <= max.x + tol && p.y >= min.y - tol && p.y <= max.y + tol &&
         p.z >= min.z - tol && p.z <= max.z + tol;
}

bool Aabb::Touches(const Aabb& o, double tol) const {
  return min.x <= o.max.x + tol && o.min.x <= max.x + tol && min.y <= o.max.y + tol &&
         o.min.y <= max.y + tol && min.z <= o.max.z + tol && o.min.z <= max.z + tol;
}

std::array<double, 4> Bernstein3(double t) {
  const double s = 1.0 - t;
  return {s * s * s, 3 * t * s * s, 3 * t * t * s, t * t * t};
}

std::array<double, 3> Bernstein2(double t) {
  const double s = 1.0 - t;
  return {s * s, 2 * t * s, t * t};
}

Hyperpatch::Hyperpatch(int materials)
    : materials_(materials), fractions_(static_cast<size_t>(kCount * std::max(materials, 0)), 0.0) {
  if (materials_ > 0) {
    for (int p = 0; p < kCount; ++p) fractions_[static_cast<size_t>(p * materials_)] = 1.0;
  }
}

StatusOr<Hyperpatch> Hyperpatch::Create(std::span<const ControlPoint> points, int materials) {
  if (points.size() != kCount) {
    return Outside("hyperpatch.points.size", std::to_string(points.size()), "[64, 64]");
  }
  SCULPT_RETURN_IF_ERROR(CheckRange("hyperpatch.materials", materials, 1, kMaxMaterials));
  Hyperpatch h(materials);
  for (int i = 0; i < kCount; ++i) {
    h.positions_[static_cast<size_t>(i)] = points[static_cast<size_t>(i)].p;
    if (static_cast<int>(points[static_cast<size_t>(i)].a.size()) != materials) {
      return Outside(
          std::string("hyperpatch.points[") + std::to_string(i) + "].a.size",
          std::to_string(points[static_cast<size_t>(i)].a.size()),
          std::string("[") + std::to_string(materials) + ", " + std::to_string(materials) + "]");
    }
    h.set_fractions(i, points[static_cast<size_t>(i)].a);
  }
  SCULPT_RETURN_IF_ERROR(h.Validate("hyperpatch.points"));
  return h;
}

std::span<const double> Hyperpatch::fractions(int idx) const {
  return {fractions_.data() + static_cast<size_t>(idx * materials_),
          static_cast<size_t>(materials_)};
}

void Hyperpatch::set_fractions(int idx, std::span<const double> a) {
  std::copy(a.begin(), a.end(), fractions_.begin() + idx * materials_);
}

Status Hyperpatch::Validate(const std::string& field) const {
  for (int i = 0; i < kCount; ++i) {
    const std::string f = field + "[" + std::to_string(i) + "]";
    SCULPT_RETURN_IF_ERROR(CheckFinitePoint(f + ".p", position(i)));
    SCULPT_RETURN_IF_ERROR(ValidateFractions(f + ".a", fractions(i), materials_));
  }
  return Status::Ok();
}

Vec3 Hyperpatch::Evaluate(double u, double v, double w) const {
  const auto bu = Bernstein3(u), bv = Bernstein3(v), bw = Bernstein3(w);
  Vec3 p;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double bij = bu[i] * bv[j];
      for (int k = 0; k < 4; ++k) p += position(i, j, k) * (bij * bw[k]);
    }
  }
  return p;
}

std::array<Vec3, 3> Hyperpatch::Derivatives(double u, double v, double w) const {
  const auto bu = Bernstein3(u), bv = Bernstein3(v), bw = Bernstein3(w);
  const auto du = Bernstein2(u), dv = Bernstein2(v), dw = Bernstein2(w);
  Vec3 pu, pv, pw;
  // ∂P/∂u = 3 Σ (p_{i+1,j,k} − p_{i,j,k}) B²_i(u) B³_j(v) B³_k(w), likewise v and w.
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      for (int k = 0; k < 4; ++k) {
        const Vec3& p = position(i, j, k);
        if (i < 3) pu += (position(i + 1, j, k) - p) * (du[i] * bv[j] * bw[k]);
        if (j < 3) pv += (position(i, j + 1, k) - p) * (bu[i] * dv[j] * bw[k]);
        if (k < 3) pw += (position(i, j, k + 1) - p) * (bu[i] * bv[j] * dw[k]);
      }
    }
  }
  return {pu * 3.0, pv * 3.0, pw * 3.0};
}

double Hyperpatch::JacobianDeterminant(double u, double v, double w) const {
  const auto d = Derivatives(u, v, w);
  return d[0].Dot(d[1].Cross(d[2]));
}

void Hyperpatch::Materials(double u, double v, double w, std::span<double> out) const {
  const auto bu = Bernstein3(u), bv = Bernstein3(v), bw = Bernstein3(w);
  std::fill(out.begin(), out.end(), 0.0);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      for (int k = 0; k < 4; ++k) {
        const double b = bu[i] * bv[j] * bw[k];
        const auto a = fractions(Index(i, j, k));
        for (int m = 0; m < materials_; ++m) out[m] += a[m] * b;
      }
    }
  }
}

Fractions Hyperpatch::Materials(double u, double v, double w) const {
  Fractions out(static_cast<size_t>(materials_));
  Materials(u, v, w, out);
  return out;
}

Aabb Hyperpatch::Bounds() const {
  Aabb b;
  for (const Vec3& p : positions_) b.Extend(p);
  return b;
}

namespace {

// Index of control point q (0..3) along `axis` on the line through (a, b) in the other two.
int LineIndex(int axis, int a, int b, int q) {
  switch (axis) {
    case 0: return Hyperpatch::Index(q, a, b);
    case 1: return Hyperpatch::Index(a, q, b);
    default: return Hyperpatch::Index(a, b, q);
  }
}

// Cubic de Casteljau on 4 values of any type with + and scalar *.
template <typename T>
void DeCasteljau(const T in[4], double t, T lo[4], T hi[4]) {
  const double s = 1.0 - t;
  const T a1 = in[0] * s + in[1] * t, b1 = in[1] * s + in[2] * t, c1 = in[2] * s + in[3] * t;
  const T a2 = a1 * s + b1 * t, b2 = b1 * s + c1 * t;
  const T a3 = a2 * s + b2 * t;
  lo[0] = in[0]; lo[1] = a1; lo[2] = a2; lo[3] = a3;
  hi[0] = a3; hi[1] = b2; hi[2] = c1; hi[3] = in[3];
}

}  // namespace

void SplitNet(const std::array<Vec3, 64>& net, int axis, double t, std::array<Vec3, 64>* lo,
              std::array<Vec3, 64>* hi) {
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      Vec3 in[4], l[4], h[4];
      for (int q = 0; q < 4; ++q) in[q] = net[static_cast<size_t>(LineIndex(axis, a, b, q))];
      DeCasteljau(in, t, l, h);
      for (int q = 0; q < 4; ++q) {
        (*lo)[static_cast<size_t>(LineIndex(axis, a, b, q))] = l[q];
        (*hi)[static_cast<size_t>(LineIndex(axis, a, b, q))] = h[q];
      }
    }
  }
}

std::pair<Hyperpatch, Hyperpatch> Hyperpatch::Split(int axis, double t) const {
  Hyperpatch lo(materials_), hi(materials_);
  SplitNet(positions_, axis, t, &lo.positions_, &hi.positions_);
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      for (int m = 0; m < materials_; ++m) {
        double in[4], l[4], h[4];
        for (int q = 0; q < 4; ++q) in[q] = fractions(LineIndex(axis, a, b, q))[m];
        DeCasteljau(in, t, l, h);
        for (int q = 0; q < 4; ++q) {
          lo.fractions_[static_cast<size_t>(LineIndex(axis, a, b, q) * materials_ + m)] = l[q];
          hi.fractions_[static_cast<size_t>(LineIndex(axis, a, b, q) * materials_ + m)] = h[q];
        }
      }
    }
  }
  return {std::move(lo), std::move(hi)};
}

}  // namespace sculpt::hetero
