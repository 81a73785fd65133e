/// @brief The god-object proxy: sweep, slide, project (seed 000 §8, closest point x - phi grad phi).
#include "sculpt/haptics/proxy.h"

#include <cmath>

#include "sculpt/haptics/contact.h"

namespace sculpt::haptics {
namespace {

constexpr double kMinGradient = 1e-6;
constexpr int kProjectIterations = 6;
constexpr int kSlideIterations = 3;
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
  Vec3 goal = device;
  bool contact = false, fallback = false;
  Vec3 normal = last_normal_;
  for (int iter = 0; iter < kSlideIterations; ++iter) {
    const SegmentHit hit = SweepSegment(*sdf, p, goal, iso_);
    if (!hit.hit) {
      p = goal;
      break;
    }
    contact = true;
    const Vec3 stop = p + (goal - p) * hit.free_time;
    bool fb = false;
    normal = NormalAt(*sdf, stop, &fb);
    fallback = fallback || fb;
    // Slide: drop the inward normal part of what is left of the motion.
    Vec3 rest = goal - stop;
    const double inward = rest.Dot(normal);
    if (inward < 0) rest -= normal * inward;
    Vec3 q = stop + rest;
    // Back onto phi = iso by the closest-point rule; where it cannot (no gradient), stay put.
    if (sdf->Phi(q) - iso_ < 0 && !Project(*sdf, &q)) q = stop;
    p = stop;
    if ((q - stop).Length() < 1e-6 * h) break;
    goal = q;
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
