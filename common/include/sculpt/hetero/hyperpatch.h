/// @brief The heterogeneous tricubic Bézier hyperpatch (seed 001 §6.3, (6.3)–(6.6)): 64 control
/// points, each a position and a material distribution; evaluation of position, partial
/// derivatives, Jacobian and materials; de Casteljau splitting.
#ifndef SCULPT_HETERO_HYPERPATCH_H_
#define SCULPT_HETERO_HYPERPATCH_H_

#include <array>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/hetero/material.h"

namespace sculpt::hetero {

/// An axis-aligned box. Empty when min > max.
struct Aabb {
  Vec3 min{1e300, 1e300, 1e300};
  Vec3 max{-1e300, -1e300, -1e300};
  void Extend(const Vec3& p);
  /// True when the boxes overlap by more than `tol` along every axis (touching is not overlap).
  bool Overlaps(const Aabb& o, double tol) const;
  bool Contains(const Vec3& p, double tol) const;
  /// True when the boxes overlap or come within `tol` of each other (closed sets).
  bool Touches(const Aabb& o, double tol) const;
  double Diagonal() const { return (max - min).Length(); }
};

/// One heterogeneous geometric coefficient h = (p, a) (seed 001 §6.3).
struct ControlPoint {
  Vec3 p;
  Fractions a;
};

/// Cubic Bernstein basis (6.2) at t: {(1-t)^3, 3t(1-t)^2, 3t^2(1-t), t^3}.
std::array<double, 4> Bernstein3(double t);
/// Quadratic Bernstein basis at t (the derivative's basis).
std::array<double, 3> Bernstein2(double t);

/// A heterogeneous tricubic Bézier hyperpatch: P(u,v,w) = Σ p_ijk B_i(u) B_j(v) B_k(w) and
/// A(u,v,w) = Σ a_ijk B_i(u) B_j(v) B_k(w), with control point (i,j,k) at Index(i,j,k).
/// A value type; const methods may be called from several threads.
class Hyperpatch {
 public:
  static constexpr int kCount = 64;
  static constexpr int Index(int i, int j, int k) { return i * 16 + j * 4 + k; }

  Hyperpatch() = default;
  /// All positions at the origin, every fraction vector material 0 (n = `materials`).
  explicit Hyperpatch(int materials);

  /// Builds a patch from 64 control points. InvalidArgument naming the point, the field and the
  /// range when a position is not finite or a distribution is not in V with `materials` entries.
  static StatusOr<Hyperpatch> Create(std::span<const ControlPoint> points, int materials);

  int materials() const { return materials_; }
  const Vec3& position(int idx) const { return positions_[static_cast<size_t>(idx)]; }
  const Vec3& position(int i, int j, int k) const { return position(Index(i, j, k)); }
  void set_position(int idx, const Vec3& p) { positions_[static_cast<size_t>(idx)] = p; }
  std::span<const double> fractions(int idx) const;
  /// Unvalidated write of a distribution (size must be materials()); see Validate().
  void set_fractions(int idx, std::span<const double> a);
  const std::array<Vec3, kCount>& positions() const { return positions_; }

  /// Ok, or InvalidArgument naming `field`[idx].p / .a, the value and the range.
  Status Validate(const std::string& field) const;

  /// P(u,v,w) (6.5).
  Vec3 Evaluate(double u, double v, double w) const;
  /// Columns of the Jacobian: {∂P/∂u, ∂P/∂v, ∂P/∂w} (seed 001 §2.5 INFERENCE formulas).
  std::array<Vec3, 3> Derivatives(double u, double v, double w) const;
  /// det J = ∂P/∂u · (∂P/∂v × ∂P/∂w).
  double JacobianDeterminant(double u, double v, double w) const;
  /// A(u,v,w) (6.6) written into `out` (size materials()); in V whenever every a_ijk is.
  void Materials(double u, double v, double w, std::span<double> out) const;
  Fractions Materials(double u, double v, double w) const;

  /// The box of the 64 positions; holds the whole cell (convex hull property, §7.3.2).
  Aabb Bounds() const;

  /// De Casteljau split at parameter t along `axis` (0=u, 1=v, 2=w): {[0,t], [t,1]} pieces,
  /// reparametrised to [0,1]; positions and fractions alike (fractions stay in V).
  std::pair<Hyperpatch, Hyperpatch> Split(int axis, double t) const;

 private:
  int materials_ = 0;
  std::array<Vec3, kCount> positions_{};
  std::vector<double> fractions_;  // kCount * materials_, point-major
};

/// Positions-only de Casteljau split of a 64-point net along `axis` at t (used by the overlap
/// test, which needs no materials).
void SplitNet(const std::array<Vec3, 64>& net, int axis, double t, std::array<Vec3, 64>* lo,
              std::array<Vec3, 64>* hi);

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_HYPERPATCH_H_
