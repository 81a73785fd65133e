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
  /// The tick reached HapticSettings' budget before visiting every tool sample: the force is
  /// estimated from the samples known so far, and the next tick resumes after the last visited.
  bool over_budget = false;
  int samples_evaluated = 0;  // samples that took a field lookup this tick
  int samples_skipped = 0;    // samples a distance bound showed too far to touch: no lookup
  /// Samples whose term (for the current snapshot) the force is made of, this tick's or an
  /// earlier one's; the tool's sample count when no tick since the last swap stopped early.
  int samples_known = 0;
};

/// Where the renderer reads the time for its per-tick budget (microseconds, any origin). The
/// default reads std::chrono::steady_clock; a test injects one to force an overrun.
/// Thread safety: called from the renderer's thread only.
class TickClock {
 public:
  virtual ~TickClock() = default;
  virtual double NowUs() = 0;
};

/// Runs the per-tick pipeline on whatever snapshot it is given. Its state (previous samples,
/// proxy, blend, last valid normal) belongs to one tool.
///
/// Cost: the tool's samples are visited in a fixed order in which every prefix is spread over the
/// tool (farthest-point order). A sample whose last known phi, less twice the distance it moved
/// since, still exceeds the contact range cannot touch (trilinear phi changes by at most sqrt(3)
/// per unit length) and costs no lookup; a sample near the surface reads phi and its gradient
/// from one stencil. With a budget (HapticSettings::tick_budget_us / tick_budget_samples) a tick
/// stops when it is spent; samples not visited keep their term from their last visit on the
/// same snapshot, and each one's path is swept from where it was last visited, so no contact is
/// missed, only felt a tick or two later. Across a snapshot swap the bounds and terms are kept
/// where the new snapshot bounds the change (SdfSampler::ChangeSince: a windowed snapshot made
/// with its predecessor, or one of the same sculpture), lowered by that change, so the first tick
/// on a new snapshot does the lookups of any other; otherwise they are forgotten.
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
  /// Snapshot swaps seen, and of those the ones whose distance bounds were carried over
  /// (SdfSampler::ChangeSince knew the change) instead of forgotten.
  uint64_t swaps() const { return swaps_; }
  uint64_t swaps_carried() const { return swaps_carried_; }
  const TickOutput& last() const { return out_; }
  /// Reads time for the budget from `clock` (not owned; null: steady_clock).
  void set_clock(TickClock* clock);
  /// The tool's samples relative to its centre.
  const std::vector<Vec3>& tool_samples() const { return local_; }

 private:
  explicit HapticRenderer(const HapticSettings& settings);

  HapticSettings settings_;
  std::vector<Vec3> local_;
  double sample_area_ = 0;
  int blend_ticks_ = 0;
  ProxyModel proxy_;

  // Visits samples from order_[cursor_] on, updating their state; stops at the budget.
  void VisitSamples(const SdfSampler& sdf, const Vec3& centre, double start_us, TickOutput* out);
  // On a new snapshot: keeps what SdfSampler::ChangeSince lets the samples' state keep, forgets
  // the rest.
  void CarryOverSwap(const SdfSampler* sdf);
  bool OutOfBudget(int evaluated, double start_us) const;

  double rho_ = 0;  // area-weighted patch radius; 0 for the plain penalty average
  TickClock* clock_;
  std::vector<uint32_t> order_;  // farthest-point visiting order
  size_t cursor_ = 0;            // where in order_ the next tick starts
  std::vector<uint32_t> pending_;  // scratch: this tick's positions in order_ left to visit
  // Per sample: where its path was last swept to; the last point phi was read at and that phi
  // (NaN: unknown on this snapshot); its force term and whether that term is for this snapshot.
  std::vector<Vec3> from_, anchor_;
  std::vector<double> anchor_phi_;
  std::vector<uint8_t> anchor_exact_;  // anchor_phi_ is phi itself (not a bound) on this snapshot
  // The tool centre's path length so far (each tick adds how far it moved), and per sample the
  // path length below which its anchor alone proves it out of range: a sample is within
  // travelled_ - (travelled_ at its anchor) of the anchor, so one compare skips it where the
  // distances to the anchor would otherwise be worked out (most samples, every tick).
  double travelled_ = 0;
  Vec3 last_centre_;
  bool have_centre_ = false;
  std::vector<double> skip_until_;
  std::vector<SampleForce> term_;
  std::vector<uint8_t> known_;
  int known_count_ = 0;
  bool have_previous_ = false;
  double previous_time_ = 0;
  const SdfSampler* previous_snapshot_ = nullptr;
  // Keeps the previous snapshot alive, so a new one can never reuse its address and be taken for
  // it: the samples' phi bounds outlive many ticks and are only valid on their own snapshot.
  std::shared_ptr<const SdfSampler> previous_snapshot_ref_;
  int previous_colliding_ = 0;
  Vec3 last_normal_{0, 0, 1};
  Vec3 blend_from_;
  int blend_left_ = 0;
  uint64_t nan_samples_ = 0;
  uint64_t ticks_ = 0;
  uint64_t swaps_ = 0, swaps_carried_ = 0;
  TickOutput out_;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_HAPTIC_RENDERER_H_
