/// @brief Continuous contact detection by conservative marching along each sample's path.
#include "sculpt/haptics/contact.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sculpt::haptics {
namespace {

// Lipschitz bound of trilinear phi when neighbouring nodes differ by at most one cell: each
// partial derivative is at most 1, so |grad phi| <= sqrt(3).
constexpr double kLipschitz = 1.7320508075688772;
constexpr int kBisections = 12;

}  // namespace

SegmentHit SweepSegment(const SdfSampler& sdf, const Vec3& a, const Vec3& b, double iso) {
  return SweepSegment(sdf, a, b, iso, std::numeric_limits<double>::quiet_NaN(), nullptr);
}

SegmentHit SweepSegment(const SdfSampler& sdf, const Vec3& a, const Vec3& b, double iso,
                        double phi_a, double* phi_b, double known_phi_b) {
  SegmentHit r;
  if (phi_b != nullptr) *phi_b = std::numeric_limits<double>::quiet_NaN();
  if (!a.IsFinite() || !b.IsFinite()) return r;
  const double h = sdf.cell_size();
  const double length = (b - a).Length();
  const double start = (std::isnan(phi_a) ? sdf.Phi(a) : phi_a) - iso;
  if (start <= 0) {
    r.hit = true;
    r.time = 0;
    r.free_time = 0;
    return r;
  }
  if (length <= 0) {
    if (phi_b != nullptr) *phi_b = start + iso;
    return r;
  }
  const double min_step = 0.5 * h / length;  // half a cell, as a fraction of the segment
  double t_free = 0, phi_free = start;
  while (t_free < 1) {
    const double step = std::max(min_step, phi_free / kLipschitz / length);
    const double t = std::min(1.0, t_free + step);
    const double phi =
        (t == 1.0 && !std::isnan(known_phi_b) ? known_phi_b : sdf.Phi(a + (b - a) * t)) - iso;
    if (phi <= 0) {
      // Bisect [t_free, t] for the crossing; keep the free side for a proxy to stop on.
      double lo = t_free, hi = t;
      for (int i = 0; i < kBisections && (hi - lo) * length > 1e-3 * h; ++i) {
        const double mid = 0.5 * (lo + hi);
        if (sdf.Phi(a + (b - a) * mid) - iso <= 0) {
          hi = mid;
        } else {
          lo = mid;
        }
      }
      r.hit = true;
      r.time = hi;
      r.free_time = lo;
      return r;
    }
    t_free = t;
    phi_free = phi;
  }
  if (phi_b != nullptr) *phi_b = phi_free + iso;
  return r;
}

SweptContact FindFirstContact(const SdfSampler& sdf, const std::vector<Vec3>& from,
                              const std::vector<Vec3>& to, double iso) {
  std::vector<double> unknown(from.size(), std::numeric_limits<double>::quiet_NaN()), out;
  out.resize(from.size());
  return FindFirstContact(sdf, from, to, iso, unknown, &out);
}

SweptContact FindFirstContact(const SdfSampler& sdf, const std::vector<Vec3>& from,
                              const std::vector<Vec3>& to, double iso,
                              const std::vector<double>& phi_from, std::vector<double>* phi_to) {
  SweptContact c;
  if (from.size() != to.size() || phi_from.size() != from.size() ||
      phi_to->size() != from.size()) {
    return c;
  }
  for (size_t k = 0; k < from.size(); ++k) {
    const SegmentHit h = SweepSegment(sdf, from[k], to[k], iso, phi_from[k], &(*phi_to)[k]);
    if (h.hit && (!c.hit || h.time < c.time)) {
      c.hit = true;
      c.time = h.time;
      c.sample = static_cast<int>(k);
      c.point = from[k] + (to[k] - from[k]) * h.time;
    }
  }
  return c;
}

}  // namespace sculpt::haptics
