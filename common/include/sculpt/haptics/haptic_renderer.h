/// @brief HapticRenderer: one haptic tick without a thread: contact detection, the scene's force
/// model, blending across snapshot and contact changes, the force clamp and NaN handling.
#ifndef SCULPT_HAPTICS_HAPTIC_RENDERER_H_
#define SCULPT_HAPTICS_HAPTIC_RENDERER_H_

#include <cstdint>
#include <memory>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/haptics/contact.h"
#include "sculpt/haptics/haptic_settings.h"
#include "sculpt/haptics/penalty.h"
#include "sculpt/haptics/proxy.h"

namespace sculpt::haptics {

/// A device reading: when (seconds on the device's clock) and where the tool's centre is.
struct DeviceSample {
  double time = 0;
  Vec3 position;
  Quat orientation;
};

/// What one tick produced.
struct TickOutput {
  Vec3 force;         // what the device is sent: blended, clamped
  Vec3 model_force;   // the model's force before blending and the clamp
  bool contact = false;
  int colliding = 0;  // penalty: samples with phi <= 0; proxy: 1 in contact
  SweptContact swept;  // continuous detection along the tool's path since the previous tick
  Vec3 proxy;         // proxy model: the proxy; penalty: the device position
  bool nan_ignored = false;      // the sample was not finite: nothing moved, the force is held
  bool blending = false;         // the output is between the previous force and the model's
  bool clamped = false;          // the output hit HapticSettings::max_force
  bool normal_fallback = false;  // some direction came from the last valid normal
};

/// Runs the per-tick pipeline on whatever snapshot it is given. Its state (previous samples,
/// proxy, blend, last valid normal) belongs to one tool.
/// Thread safety: not thread-safe; the haptic loop's thread owns it.
class HapticRenderer {
 public:
  /// InvalidArgument (field, value, range) for settings ValidateHapticSettings refuses.
  static StatusOr<HapticRenderer> Create(const HapticSettings& settings);

  /// One tick. `snapshot` may be null (nothing to touch: zero model force). A snapshot that is
  /// not the previous tick's, or a change in the colliding set (penalty), starts a blend of
  /// HapticSettings::blend_ms from the force last sent. A non-finite sample is counted and
  /// ignored: the previous output is returned again with nan_ignored set.
  const TickOutput& Tick(const std::shared_ptr<const SdfSampler>& snapshot,
                         const DeviceSample& sample);

  const HapticSettings& settings() const { return settings_; }
  uint64_t nan_samples() const { return nan_samples_; }
  uint64_t ticks() const { return ticks_; }
  const TickOutput& last() const { return out_; }
  /// The tool's samples relative to its centre.
  const std::vector<Vec3>& tool_samples() const { return local_; }

 private:
  explicit HapticRenderer(const HapticSettings& settings);

  HapticSettings settings_;
  std::vector<Vec3> local_;
  double sample_area_ = 0;
  int blend_ticks_ = 0;
  ProxyModel proxy_;

  std::vector<Vec3> previous_, current_;
  // phi at each sample on the previous and current tick (NaN: not known), so each sample's phi
  // is sampled once per tick, by the sweep, and reused by the force.
  std::vector<double> previous_phi_, current_phi_;
  bool have_previous_ = false;
  double previous_time_ = 0;
  const SdfSampler* previous_snapshot_ = nullptr;
  int previous_colliding_ = 0;
  Vec3 last_normal_{0, 0, 1};
  Vec3 blend_from_;
  int blend_left_ = 0;
  uint64_t nan_samples_ = 0;
  uint64_t ticks_ = 0;
  TickOutput out_;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_HAPTIC_RENDERER_H_
