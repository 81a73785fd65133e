/// @brief ProxyModel: a god-object proxy kept on the surface by the closest-point rule
/// x - phi grad phi (seed 000 §8, eqs. 2.26/2.28), coupled to the device by a spring-damper.
#ifndef SCULPT_HAPTICS_PROXY_H_
#define SCULPT_HAPTICS_PROXY_H_

#include "sculpt/core/vec3.h"
#include "sculpt/haptics/penalty.h"

namespace sculpt::haptics {

/// The proxy's state after one update.
struct ProxyState {
  Vec3 proxy;     // where the proxy is (free space: phi >= iso)
  Vec3 force;     // stiffness (proxy - device) - damping (v_device . n) n, never inward; zero
                  // when free
  bool contact = false;
  Vec3 normal;    // outward unit normal at the proxy while in contact (the last valid one)
  bool normal_fallback = false;  // grad phi vanished at the proxy; `normal` is the previous one
};

/// A point proxy (or a sphere of radius `iso`: its centre kept on phi = iso). Each update moves
/// the proxy towards the device along a swept segment, stops it at the first contact, slides the
/// rest of the motion along the tangent plane and projects the result back onto phi = iso with
/// the closest-point rule, iterated. The proxy never enters the material, so the force stays
/// bounded and outward however deep the device is: it needs phi and its gradient only near the
/// surface, where the narrow band holds them, never at the device.
/// Thread safety: not thread-safe; one instance per haptic loop.
class ProxyModel {
 public:
  ProxyModel(double stiffness, double damping, double iso = 0)
      : stiffness_(stiffness), damping_(damping), iso_(iso) {}

  /// Puts the proxy at `position` (projected out of the material if it is inside and the
  /// field has a direction there) and forgets the contact.
  void Reset(const SdfSampler* sdf, const Vec3& position);

  /// One tick of length dt > 0 with the device at `device`. A null `sdf` (no snapshot) frees
  /// the proxy. A non-finite device position leaves the state unchanged and returns it.
  const ProxyState& Update(const SdfSampler* sdf, const Vec3& device, double dt);

  const ProxyState& state() const { return state_; }
  double stiffness() const { return stiffness_; }

 private:
  // Closest-point projection of q onto phi = iso_, iterated; false if it did not converge to
  // within a small tolerance (medial axis, clamped band), q is then unchanged.
  bool Project(const SdfSampler& sdf, Vec3* q) const;
  // The outward unit normal at p, or the last valid one (flagged) where grad phi vanishes.
  Vec3 NormalAt(const SdfSampler& sdf, const Vec3& p, bool* fallback) const;

  double stiffness_, damping_, iso_;
  bool initialised_ = false;
  bool has_previous_device_ = false;
  Vec3 previous_device_;  // for the damper's device velocity
  Vec3 last_normal_{0, 0, 1};
  ProxyState state_;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_PROXY_H_
