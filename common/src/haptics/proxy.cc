/// @brief The god-object proxy: sweep, slide, project (seed 000 §8, closest point x - phi grad phi).
#include "sculpt/haptics/proxy.h"

#include <cmath>

#include "sculpt/haptics/contact.h"

namespace sculpt::haptics {
namespace {

constexpr double kMinGradient = 1e-6;
constexpr int kProjectIterations = 6;
constexpr int kSlideIterations = 8;
// Normals further apart than 30 degrees between two slide steps mean a crease between them.
constexpr double kCreaseCos = 0.8660254037844387;
// Proxies rest this fraction of a cell outside phi = iso, so round-off never puts them inside.
constexpr double kSkin = 1e-3;

}  // namespace

Vec3 ProxyModel::NormalAt(const SdfSampler& sdf, const Vec3& p, bool* fallback) const {
  const Vec3 g = sdf.Gradient(p);
  const double n = g.Length();
  if (n < kMinGradient || !std::isfinite(n)) {
    *fallback = true;
    return last_normal_;
  }
  return g / n;
}

bool ProxyModel::Project(const SdfSampler& sdf, Vec3* q) const {
  const double h = sdf.cell_size();
  Vec3 x = *q;
  for (int i = 0; i < kProjectIterations; ++i) {
    const double phi = sdf.Phi(x) - iso_;
    if (std::abs(phi) < 1e-4 * h) break;
    const Vec3 g = sdf.Gradient(x);
    const double g2 = g.LengthSqr();
    if (g2 < kMinGradient * kMinGradient) return false;
    // x - phi grad phi / |grad phi|^2: the closest-point rule, exact where |grad phi| = 1.
    x -= g * (phi / g2);
  }
  const double phi = sdf.Phi(x) - iso_;
  if (std::abs(phi) > 0.05 * h) return false;
  // Rest on the free side.
  if (phi < kSkin * h) {
    const Vec3 g = sdf.Gradient(x);
    const double n = g.Length();
    if (n < kMinGradient) return false;
    x += g * ((kSkin * h - phi) / (n * n));
  }
  *q = x;
  return true;
}

void ProxyModel::Reset(const SdfSampler* sdf, const Vec3& position) {
  state_ = ProxyState{};
  state_.proxy = position;
  if (sdf != nullptr && sdf->Phi(position) - iso_ < 0) Project(*sdf, &state_.proxy);
  initialised_ = true;
  has_previous_device_ = false;
}

const ProxyState& ProxyModel::Update(const SdfSampler* sdf, const Vec3& device, double dt) {
  if (!device.IsFinite() || !(dt > 0)) return state_;
  if (!initialised_) Reset(sdf, device);
  if (sdf == nullptr) {
    state_ = ProxyState{device, {}, false, last_normal_, false};
    previous_device_ = device;
    has_previous_device_ = true;
    return state_;
  }
  const double h = sdf->cell_size();
  Vec3 p = state_.proxy;
  bool contact = false, fallback = false;
  Vec3 normal = last_normal_;
  const SegmentHit first = SweepSegment(*sdf, p, device, iso_);
  if (!first.hit) {
    p = device;
  } else {
    contact = true;
    p = p + (device - p) * first.free_time;
    // Slide towards the device on the surface: the proxy settles where (device - proxy) lies
    // along the normal, the surface point locally closest to the device. Each step moves along
    // the tangent plane and back onto phi = iso by the closest-point rule.
    bool fb = false;
    normal = NormalAt(*sdf, p, &fb);
    fallback = fallback || fb;
    for (int iter = 0; iter < kSlideIterations; ++iter) {
      const Vec3 r = device - p;
      const double in = r.Dot(normal);
      const Vec3 step = in < 0 ? r - normal * in : r;
      if (step.Length() < 1e-4 * h) break;
      Vec3 q = p + step;
      if (!Project(*sdf, &q)) break;
      // Thin-feature guard: sliding must not cross material more than half a cell deep.
      if (SweepSegment(*sdf, p, q, iso_ - 0.5 * h).hit) break;
      const Vec3 nq = NormalAt(*sdf, q, &fb);
      fallback = fallback || fb;
      if (nq.Dot(normal) < kCreaseCos) {
        // A crease between p and q (a concave one made the projection jump faces): the proxy
        // goes to the point of the two faces' common line closest to the device, as a
        // god-object constrained by two planes does, instead of bouncing between them.
        const double c = normal.Dot(nq);
        const double c1 = normal.Dot(p), c2 = nq.Dot(q);
        const double det = 1 - c * c;
        Vec3 x = (normal * (c1 - c2 * c) + nq * (c2 - c1 * c)) / det;
        Vec3 u = normal.Cross(nq);
        u = u / u.Length();
        x += u * u.Dot(device - x);
        if (x.IsFinite() && sdf->Phi(x) - iso_ >= -0.05 * h &&
            !SweepSegment(*sdf, p, x, iso_ - 0.5 * h).hit) {
          p = x;
          const Vec3 sum = normal + nq;
          normal = sum / sum.Length();
        }
        break;
      }
      p = q;
      normal = nq;
    }
  }
  // A proxy that ended in the material (it cannot by construction, but a snapshot swap can put
  // material where it stands) is projected out.
  if (sdf->Phi(p) - iso_ < 0) {
    if (!Project(*sdf, &p)) p = state_.proxy;
    contact = true;
  }
  if (contact) {
    last_normal_ = normal;
  }
  const Vec3 offset = p - device;
  Vec3 force = offset * stiffness_;
  // The damper acts on the device's own velocity along the normal (a virtual wall's damper),
  // not on d/dt (proxy - device): a snapshot swap or a first contact moves the proxy by a finite
  // step in one tick, and differentiating that would be a spike of damping * step / dt.
  if (contact && has_previous_device_) {
    const Vec3 v = (device - previous_device_) / dt;
    force -= normal * (damping_ * v.Dot(normal));
  }
  // Nothing may pull the device into the material: clip any inward component.
  if (contact) {
    const double along = force.Dot(normal);
    if (along < 0) force -= normal * along;
  } else {
    force = {};
  }
  state_ = ProxyState{p, force, contact, normal, fallback};
  previous_device_ = device;
  has_previous_device_ = true;
  return state_;
}

}  // namespace sculpt::haptics
