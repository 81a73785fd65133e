/// @brief HapticSettings: the per-scene choice of force model and its parameters, validated.
#ifndef SCULPT_HAPTICS_HAPTIC_SETTINGS_H_
#define SCULPT_HAPTICS_HAPTIC_SETTINGS_H_

#include <string>

#include "sculpt/core/status.h"

namespace sculpt::haptics {

/// Which force model renders contact.
enum class ForceModel {
  /// The thesis's penalty force at the tool's samples, averaged (seed 000 §2.4, eqs. 3.3-3.5).
  kPenalty,
  /// A god-object proxy held on the surface by the closest-point rule (seed 000 §8), joined to
  /// the device by a spring and damper.
  kProxy,
};

/// "penalty" / "proxy".
const char* ForceModelName(ForceModel m);
/// InvalidArgument naming the field, the value and the accepted names for anything else.
StatusOr<ForceModel> ParseForceModel(const std::string& name);

/// Per-scene haptic parameters. Lengths are world units, forces world force units (the thesis's
/// kappa is force per unit of penetration), times seconds unless the name says otherwise.
struct HapticSettings {
  ForceModel model = ForceModel::kProxy;
  /// kappa of the penalty model, and the proxy's spring (force per unit length). The thesis
  /// uses 0.5-1.5 (seed 000 §5 item 5).
  double stiffness = 1.0;
  /// The proxy's damper on the device's normal velocity while in contact (force per unit speed).
  /// For passivity at the loop period T it must be at least stiffness * T / 2 (the sampled-data
  /// virtual-wall bound of Colgate and Schenkel); validation enforces it for the proxy model.
  double damping = 0.05;
  /// No force output is ever longer than this.
  double max_force = 20.0;
  /// When a new snapshot arrives or the set of colliding samples changes, the output moves from
  /// the last force to the new one over this many milliseconds (0: at once).
  double blend_ms = 4.0;
  /// Loop rate.
  double rate_hz = 1000.0;
  /// The tool: a sphere of this radius around the device point, sampled at `tool_samples`
  /// points for the penalty model and for contact detection. 0 is a point tool.
  double tool_radius = 2.0;
  int tool_samples = 128;
  /// The penalty model's average: weighted by each sample's share of the contact area
  /// (ComputeAreaWeightedPenaltyForce), or the thesis's plain mean over colliding samples.
  bool area_weighted = true;
  /// The proxy keeps its centre on phi = proxy_radius (0: a point proxy on the surface). It
  /// must stay below the narrow band's half-width minus one voxel, where phi is not clamped.
  double proxy_radius = 0.0;
  /// Per-tick time budget in microseconds (0: none). The renderer visits the tool's samples
  /// coarse to fine and stops when the budget is spent, returning the force from the samples it
  /// has (HapticRenderer::Tick); the next tick resumes where it stopped. Off by default, so a
  /// renderer driven by a test or a recording gives the same forces however it is scheduled;
  /// the real-time callers (sculpt play, the load generator) set kLoopTickBudgetUs.
  double tick_budget_us = 0.0;
  /// The same budget as a count of samples evaluated per tick (0: none): deterministic, for
  /// tests and for hardware with a known cost per sample.
  int tick_budget_samples = 0;
};

inline constexpr double kMaxStiffness = 1e6;
inline constexpr double kMaxHapticForce = 1e9;
inline constexpr double kMaxBlendMs = 100;
inline constexpr double kMinRateHz = 100;
inline constexpr double kMaxRateHz = 10000;
inline constexpr double kMaxToolRadius = 1e4;
inline constexpr int kMaxToolSamples = 4096;
inline constexpr double kMaxTickBudgetUs = 1e6;
/// The budget the 1 kHz loop's callers use: a fifth of the period.
inline constexpr double kLoopTickBudgetUs = 200.0;

/// Ok, or InvalidArgument naming the field, the value and the allowed range
/// (e.g. "HapticSettings.damping=0 outside [0.0005, 1e+06]").
Status ValidateHapticSettings(const HapticSettings& s);

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_HAPTIC_SETTINGS_H_
