/// @brief The thesis's penalty haptic model on a dense phi sample (seed 000 §2.4).
#include "sculpt/haptics/penalty.h"

#include <algorithm>
#include <cmath>

namespace sculpt::haptics {
namespace {

// Below this |grad phi| (per world unit) a sample has no usable direction.
constexpr double kMinGradient = 1e-6;

struct Cell {
  int i0[3];
  double t[3];
};

// The cell holding p and p's fractional position in it, clamped into the box; an axis of
// extent 1 has a single node and weight 0.
Cell Locate(const DenseSdf& s, const Vec3& p) {
  const levelset::Int3 d = s.field->dims();
  const int dims[3] = {d.x, d.y, d.z};
  const double o[3] = {s.origin.x, s.origin.y, s.origin.z};
  Cell c{};
  for (int a = 0; a < 3; ++a) {
    if (dims[a] == 1) {
      c.i0[a] = 0;
      c.t[a] = 0;
      continue;
    }
    const double u = std::clamp((p[a] - o[a]) / s.h, 0.0, static_cast<double>(dims[a] - 1));
    int i = std::min(static_cast<int>(std::floor(u)), dims[a] - 2);
    c.i0[a] = i;
    c.t[a] = u - i;
  }
  return c;
}

template <typename F>
auto Trilinear(const DenseSdf& s, const Cell& c, F node) {
  const levelset::Int3 d = s.field->dims();
  const int step[3] = {d.x > 1 ? 1 : 0, d.y > 1 ? 1 : 0, d.z > 1 ? 1 : 0};
  decltype(node(0, 0, 0)) acc{};
  for (int dk = 0; dk <= step[2]; ++dk) {
    for (int dj = 0; dj <= step[1]; ++dj) {
      for (int di = 0; di <= step[0]; ++di) {
        const double w = (di ? c.t[0] : 1 - c.t[0]) * (dj ? c.t[1] : 1 - c.t[1]) *
                         (dk ? c.t[2] : 1 - c.t[2]);
        acc += node(c.i0[0] + di, c.i0[1] + dj, c.i0[2] + dk) * w;
      }
    }
  }
  return acc;
}

}  // namespace

double DenseSdf::Phi(const Vec3& p) const {
  return Trilinear(*this, Locate(*this, p),
                   [this](int i, int j, int k) { return static_cast<double>(field->at(i, j, k)); });
}

Vec3 DenseSdf::Gradient(const Vec3& p) const {
  const levelset::Int3 d = field->dims();
  auto node_gradient = [this, d](int i, int j, int k) {
    // Central differences, one-sided at the border (App. A.4 `respcol`); a flat axis gives 0.
    auto diff = [&](int a) {
      const int dims[3] = {d.x, d.y, d.z};
      int idx[3] = {i, j, k};
      if (dims[a] == 1) return 0.0;
      int lo[3] = {i, j, k}, hi[3] = {i, j, k};
      lo[a] = std::max(0, idx[a] - 1);
      hi[a] = std::min(dims[a] - 1, idx[a] + 1);
      return (field->at(hi[0], hi[1], hi[2]) - field->at(lo[0], lo[1], lo[2])) /
             ((hi[a] - lo[a]) * h);
    };
    return Vec3{diff(0), diff(1), diff(2)};
  };
  return Trilinear(*this, Locate(*this, p), node_gradient);
}

Vec3 SculptureSdf::Gradient(const Vec3& p) const {
  const double h = sculpture_.voxel_size();
  auto d = [&](const Vec3& e) {
    return (sculpture_.SampleWorld(p + e * h) - sculpture_.SampleWorld(p - e * h)) / (2 * h);
  };
  return {d({1, 0, 0}), d({0, 1, 0}), d({0, 0, 1})};
}

PenaltyForce ComputePenaltyForce(const SdfSampler& sdf, const std::vector<Vec3>& samples,
                                 double kappa) {
  return ComputePenaltyForce(sdf, samples, kappa, Vec3{});
}

SampleForce PenaltySampleForce(double phi, const Vec3& g, double kappa,
                               const Vec3& fallback_normal) {
  SampleForce f;
  if (phi > 0) return f;
  f.colliding = true;
  const double n = g.Length();
  // Eq. 3.3 with the digest's correction (errata 1): kappa |phi| times the outward normal.
  if (n < kMinGradient) {
    f.without_normal = true;  // medial axis or beyond the band: no defined normal here
    f.force = fallback_normal * (kappa * std::abs(phi));
    return f;
  }
  f.force = g * (kappa * std::abs(phi) / n);
  return f;
}

SampleForce AreaWeightedSampleForce(const Vec3& x, double phi, const Vec3& g, double rho,
                                    double kappa, const Vec3& tool_centre,
                                    const Vec3& fallback_normal) {
  SampleForce f;
  if (phi >= rho) return f;  // |grad phi| <= 1: no part of the patch can be inside
  f.colliding = phi <= 0;
  const double n = g.Length();
  // Over the patch (a disc of radius rho on the tool's surface) phi changes by the gradient's
  // component along the tool surface: a spread of +-s around phi.
  Vec3 m = x - tool_centre;
  const double ml = m.Length();
  m = ml > 0 ? m / ml : Vec3{};
  const double s = rho * (g - m * g.Dot(m)).Length();
  double inside, depth;
  if (s < 1e-9 * rho) {
    inside = phi <= 0 ? 1.0 : 0.0;
    depth = phi <= 0 ? -phi : 0.0;
  } else {
    // phi + s y with y distributed over the disc, density (2/pi) sqrt(1 - y^2) on [-1, 1]:
    // inside for y < b = -phi / s.
    const double b = std::clamp(-phi / s, -1.0, 1.0);
    const double root = std::sqrt(1 - b * b);
    inside = (b * root + std::asin(b) + M_PI / 2) / M_PI;
    depth = -phi * inside + s * (2.0 / (3.0 * M_PI)) * root * root * root;
  }
  if (inside <= 0) return f;
  f.inside = inside;
  if (n < kMinGradient) {
    f.without_normal = true;
    f.force = fallback_normal * (kappa * depth);
    return f;
  }
  f.force = g * (kappa * depth / n);
  return f;
}

PenaltyForce ComputePenaltyForce(const SdfSampler& sdf, const std::vector<Vec3>& samples,
                                 double kappa, const Vec3& fallback_normal) {
  PenaltyForce f;
  for (const Vec3& x : samples) {
    const double phi = sdf.Phi(x);
    if (phi > 0) continue;
    const SampleForce k = PenaltySampleForce(phi, sdf.Gradient(x), kappa, fallback_normal);
    ++f.colliding;
    f.without_normal += k.without_normal ? 1 : 0;
    f.sum += k.force;
  }
  if (f.colliding > 0) f.average = f.sum / f.colliding;
  return f;
}

PenaltyForce ComputeAreaWeightedPenaltyForce(const SdfSampler& sdf,
                                             const std::vector<Vec3>& samples, double sample_area,
                                             double kappa, const Vec3& tool_centre,
                                             const Vec3& fallback_normal,
                                             const std::vector<double>* known) {
  PenaltyForce f;
  if (!(sample_area > 0) || !std::isfinite(sample_area)) return f;
  if (known != nullptr && known->size() != samples.size()) known = nullptr;
  const double rho = std::sqrt(sample_area / M_PI);
  double covered = 0;  // sum of inside fractions, in units of one patch
  for (size_t i = 0; i < samples.size(); ++i) {
    const Vec3& x = samples[i];
    const double phi = known != nullptr && !std::isnan((*known)[i]) ? (*known)[i] : sdf.Phi(x);
    if (phi >= rho) continue;
    const SampleForce k =
        AreaWeightedSampleForce(x, phi, sdf.Gradient(x), rho, kappa, tool_centre, fallback_normal);
    f.colliding += k.colliding ? 1 : 0;
    if (k.inside <= 0) continue;
    covered += k.inside;
    f.without_normal += k.without_normal ? 1 : 0;
    f.sum += k.force;
  }
  if (covered > 0) f.average = f.sum / covered;
  return f;
}

std::vector<Vec3> CircleSamples(const Vec3& center, double radius, int k) {
  std::vector<Vec3> out;
  out.reserve(static_cast<size_t>(k) + 1);
  for (int i = 0; i <= k; ++i) {
    const double a = 2 * M_PI * i / k;
    out.push_back(center + Vec3{radius * std::cos(a), radius * std::sin(a), 0});
  }
  return out;
}

}  // namespace sculpt::haptics
