/// @brief The per-tick haptic pipeline: detect, model, blend, clamp.
#include "sculpt/haptics/haptic_renderer.h"

#include <algorithm>
#include <cmath>

#include "sculpt/levelset/tool.h"

namespace sculpt::haptics {

StatusOr<HapticRenderer> HapticRenderer::Create(const HapticSettings& settings) {
  SCULPT_RETURN_IF_ERROR(ValidateHapticSettings(settings));
  return HapticRenderer(settings);
}

HapticRenderer::HapticRenderer(const HapticSettings& s)
    : settings_(s), proxy_(s.stiffness, s.damping, s.proxy_radius) {
  if (s.tool_radius > 0) {
    local_ = levelset::ToolSurfaceSamples(levelset::ToolShape::Sphere({0, 0, 0}, s.tool_radius),
                                          s.tool_samples);
    // Fibonacci samples split the sphere's area evenly.
    sample_area_ = 4 * M_PI * s.tool_radius * s.tool_radius / static_cast<double>(local_.size());
  } else {
    local_ = {Vec3{0, 0, 0}};
  }
  blend_ticks_ = static_cast<int>(std::lround(s.blend_ms * 1e-3 * s.rate_hz));
  previous_.resize(local_.size());
  current_.resize(local_.size());
  previous_phi_.assign(local_.size(), std::nan(""));
  current_phi_.assign(local_.size(), std::nan(""));
}

const TickOutput& HapticRenderer::Tick(const std::shared_ptr<const SdfSampler>& snapshot,
                                       const DeviceSample& sample) {
  ++ticks_;
  if (!sample.position.IsFinite() || !std::isfinite(sample.time)) {
    ++nan_samples_;
    out_.nan_ignored = true;  // force, contact and proxy stay as they were
    return out_;
  }
  const double period = 1.0 / settings_.rate_hz;
  double dt = have_previous_ ? sample.time - previous_time_ : period;
  if (!(dt > 0) || dt > 10 * period) dt = period;  // a stalled or reset device clock

  for (size_t k = 0; k < local_.size(); ++k) current_[k] = sample.position + local_[k];
  const SdfSampler* sdf = snapshot.get();

  TickOutput out;
  // phi carried over is only valid on the same snapshot.
  if (sdf != previous_snapshot_) std::fill(previous_phi_.begin(), previous_phi_.end(), std::nan(""));
  std::fill(current_phi_.begin(), current_phi_.end(), std::nan(""));
  if (sdf != nullptr && have_previous_) {
    // Both models report the tool surface's first contact; the proxy also sweeps its own
    // centre inside ProxyModel.
    out.swept = FindFirstContact(*sdf, previous_, current_, 0.0, previous_phi_, &current_phi_);
  }

  bool contact_set_changed = false;
  if (settings_.model == ForceModel::kPenalty) {
    out.proxy = sample.position;
    if (sdf != nullptr) {
      const PenaltyForce f =
          settings_.area_weighted && sample_area_ > 0
              ? ComputeAreaWeightedPenaltyForce(*sdf, current_, sample_area_, settings_.stiffness,
                                                sample.position, last_normal_, &current_phi_)
              : ComputePenaltyForce(*sdf, current_, settings_.stiffness, last_normal_);
      out.model_force = f.average;
      out.colliding = f.colliding;
      out.normal_fallback = f.without_normal > 0;
      const double m = f.average.Length();
      if (m > 0 && f.without_normal == 0) last_normal_ = f.average / m;
    }
    out.contact = out.colliding > 0 || out.swept.hit;
    contact_set_changed = out.colliding != previous_colliding_;
  } else {
    const ProxyState& p = proxy_.Update(sdf, sample.position, dt);
    out.model_force = p.force;
    out.contact = p.contact;
    out.colliding = p.contact ? 1 : 0;
    out.proxy = p.proxy;
    out.normal_fallback = p.normal_fallback;
  }

  // A new snapshot, or a sample entering or leaving the penalty's colliding set, would step the
  // force: move from what was last sent to the model's force over blend_ms instead.
  const bool new_snapshot = ticks_ > 1 && sdf != previous_snapshot_;
  if ((new_snapshot || contact_set_changed) && blend_ticks_ > 0) {
    blend_from_ = out_.force;
    blend_left_ = blend_ticks_;
  }
  Vec3 f = out.model_force;
  if (blend_left_ > 0) {
    const double s = 1.0 - static_cast<double>(blend_left_) / (blend_ticks_ + 1);
    f = blend_from_ + (out.model_force - blend_from_) * s;
    --blend_left_;
    out.blending = true;
  }
  const double m = f.Length();
  if (m > settings_.max_force) {
    f = f * (settings_.max_force / m);
    out.clamped = true;
  }
  out.force = f;

  std::swap(previous_, current_);
  std::swap(previous_phi_, current_phi_);
  have_previous_ = true;
  previous_time_ = sample.time;
  previous_snapshot_ = sdf;
  previous_colliding_ = out.colliding;
  out_ = out;
  return out_;
}

}  // namespace sculpt::haptics
