/// @brief Force model names and the validation of HapticSettings.
#include "sculpt/haptics/haptic_settings.h"

#include "sculpt/core/check.h"

namespace sculpt::haptics {

const char* ForceModelName(ForceModel m) {
  switch (m) {
    case ForceModel::kPenalty:
      return "penalty";
    case ForceModel::kProxy:
      return "proxy";
  }
  return "unknown";
}

StatusOr<ForceModel> ParseForceModel(const std::string& name) {
  if (name == "penalty") return ForceModel::kPenalty;
  if (name == "proxy") return ForceModel::kProxy;
  return InvalidArgument("HapticSettings.model=\"" + name + "\" is not one of {penalty, proxy}");
}

Status ValidateHapticSettings(const HapticSettings& s) {
  if (s.model != ForceModel::kPenalty && s.model != ForceModel::kProxy) {
    return InvalidArgument("HapticSettings.model=" + std::to_string(static_cast<int>(s.model)) +
                           " is not one of {penalty, proxy}");
  }
  SCULPT_RETURN_IF_ERROR(CheckRange("HapticSettings.rate_hz", s.rate_hz, kMinRateHz, kMaxRateHz));
  SCULPT_RETURN_IF_ERROR(CheckRange("HapticSettings.stiffness", s.stiffness, 1e-9, kMaxStiffness));
  // Sampled-data passivity of a spring rendered at period T needs damping >= k T / 2.
  const double min_damping = s.model == ForceModel::kProxy ? s.stiffness / (2 * s.rate_hz) : 0.0;
  SCULPT_RETURN_IF_ERROR(
      CheckRange("HapticSettings.damping", s.damping, min_damping, kMaxStiffness));
  SCULPT_RETURN_IF_ERROR(CheckRange("HapticSettings.max_force", s.max_force, 1e-9, kMaxHapticForce));
  SCULPT_RETURN_IF_ERROR(CheckRange("HapticSettings.blend_ms", s.blend_ms, 0, kMaxBlendMs));
  SCULPT_RETURN_IF_ERROR(CheckRange("HapticSettings.tool_radius", s.tool_radius, 0, kMaxToolRadius));
  SCULPT_RETURN_IF_ERROR(
      CheckRange("HapticSettings.tool_samples", s.tool_samples, 1, kMaxToolSamples));
  SCULPT_RETURN_IF_ERROR(
      CheckRange("HapticSettings.proxy_radius", s.proxy_radius, 0, kMaxToolRadius));
  SCULPT_RETURN_IF_ERROR(
      CheckRange("HapticSettings.tick_budget_us", s.tick_budget_us, 0, kMaxTickBudgetUs));
  SCULPT_RETURN_IF_ERROR(CheckRange("HapticSettings.tick_budget_samples", s.tick_budget_samples, 0,
                                    kMaxToolSamples));
  return Status::Ok();
}

}  // namespace sculpt::haptics
