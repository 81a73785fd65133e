/// @brief The per-tick haptic pipeline: detect, model, blend, clamp.
#include "sculpt/haptics/haptic_renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "sculpt/levelset/tool.h"

namespace sculpt::haptics {

StatusOr<HapticRenderer> HapticRenderer::Create(const HapticSettings& settings) {
  SCULPT_RETURN_IF_ERROR(ValidateHapticSettings(settings));
  return HapticRenderer(settings);
}

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
// Bound on |grad phi| used to skip far samples without a lookup. Trilinear phi of a field whose
// nodes differ by at most a cell per cell changes by at most sqrt(3) per unit length; 2 leaves
// room for edits that steepen the field a little.
constexpr double kSkipLipschitz = 2.0;
// The time budget reads the clock once every this many evaluated samples (a steady_clock read
// costs a fraction of a sample's lookups); a tick overshoots by at most that many samples' cost
// plus its fixed tail (adding up the terms, the blend).
constexpr int kClockEvery = 2;

class SteadyTickClock : public TickClock {
 public:
  double NowUs() override {
    return std::chrono::duration<double, std::micro>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};
SteadyTickClock g_steady_clock;

// Farthest-point order: each next sample is the one farthest from all chosen so far, so every
// prefix is spread over the tool (coarse to fine). O(n^2) once per renderer.
std::vector<uint32_t> SpreadOrder(const std::vector<Vec3>& points) {
  const size_t n = points.size();
  std::vector<uint32_t> order;
  order.reserve(n);
  std::vector<double> nearest(n, std::numeric_limits<double>::infinity());
  std::vector<uint8_t> chosen(n, 0);
  size_t current = 0;
  for (size_t i = 0; i < n; ++i) {
    order.push_back(static_cast<uint32_t>(current));
    chosen[current] = 1;
    size_t next = current;
    double farthest = -1;
    for (size_t j = 0; j < n; ++j) {
      if (chosen[j]) continue;
      nearest[j] = std::min(nearest[j], (points[j] - points[current]).LengthSqr());
      if (nearest[j] > farthest) {
        farthest = nearest[j];
        next = j;
      }
    }
    current = next;
  }
  return order;
}

}  // namespace

HapticRenderer::HapticRenderer(const HapticSettings& s)
    : settings_(s), proxy_(s.stiffness, s.damping, s.proxy_radius), clock_(&g_steady_clock) {
  if (s.tool_radius > 0) {
    local_ = levelset::ToolSurfaceSamples(levelset::ToolShape::Sphere({0, 0, 0}, s.tool_radius),
                                          s.tool_samples);
    // Fibonacci samples split the sphere's area evenly.
    sample_area_ = 4 * M_PI * s.tool_radius * s.tool_radius / static_cast<double>(local_.size());
  } else {
    local_ = {Vec3{0, 0, 0}};
  }
  if (s.area_weighted && sample_area_ > 0) rho_ = std::sqrt(sample_area_ / M_PI);
  blend_ticks_ = static_cast<int>(std::lround(s.blend_ms * 1e-3 * s.rate_hz));
  order_ = SpreadOrder(local_);
  from_.resize(local_.size());
  anchor_.resize(local_.size());
  anchor_phi_.assign(local_.size(), kNan);
  anchor_exact_.assign(local_.size(), 0);
  skip_until_.assign(local_.size(), -std::numeric_limits<double>::infinity());
  term_.resize(local_.size());
  known_.assign(local_.size(), 0);
  pending_.resize(local_.size());
}

void HapticRenderer::set_clock(TickClock* clock) {
  clock_ = clock != nullptr ? clock : &g_steady_clock;
}

bool HapticRenderer::OutOfBudget(int evaluated, double start_us) const {
  if (settings_.tick_budget_samples > 0 && evaluated >= settings_.tick_budget_samples) return true;
  return settings_.tick_budget_us > 0 && evaluated % kClockEvery == 0 &&
         clock_->NowUs() - start_us >= settings_.tick_budget_us;
}

void HapticRenderer::CarryOverSwap(const SdfSampler* sdf) {
  // A new snapshot starts the visiting order afresh, so a tick cut short after a swap still has
  // samples spread over the tool.
  cursor_ = 0;
  double change = 0;
  Vec3 lo, hi;
  const bool bounded = sdf != nullptr && previous_snapshot_ != nullptr &&
                       sdf->ChangeSince(*previous_snapshot_, &change, &lo, &hi) &&
                       std::isfinite(change) && change >= 0;
  if (sdf != nullptr && previous_snapshot_ != nullptr) ++swaps_;
  if (!bounded) {
    // Nothing known of the change: what the samples learnt belongs to the old snapshot.
    std::fill(anchor_phi_.begin(), anchor_phi_.end(), kNan);
    std::fill(skip_until_.begin(), skip_until_.end(), -std::numeric_limits<double>::infinity());
    std::fill(known_.begin(), known_.end(), 0);
    known_count_ = 0;
    return;
  }
  // phi moved by at most `change` inside [lo, hi]: an anchor there keeps a lower bound (exact
  // when nothing changed), so the first tick on the new snapshot skips the far samples as every
  // other tick does instead of reading all of them. A sample's term is kept too: a tick cut
  // short by the budget uses it until the sample's next visit, as it does between swaps (the
  // term is then off by about the stiffness times the change), so the force does not fall
  // back to the estimate of a few spread samples at every swap.
  ++swaps_carried_;
  if (change == 0 && std::isinf(lo.x) && std::isinf(lo.y) && std::isinf(lo.z) &&
      std::isinf(hi.x) && std::isinf(hi.y) && std::isinf(hi.z)) {
    return;  // the same field everywhere: everything holds as it is
  }
  // Without branches (this runs for every sample on the swap tick): a NaN anchor phi stays NaN,
  // and a sample known on the old snapshot has an anchor (skipping or reading one set it).
  // The arrays through local pointers: a byte store may alias anything, and the members would
  // be loaded again after each one.
  const uint8_t exact = change == 0 ? 1 : 0;
  const size_t n = local_.size();
  const Vec3* anchor = anchor_.data();
  double* anchor_phi = anchor_phi_.data();
  uint8_t* anchor_exact = anchor_exact_.data();
  uint8_t* known_now = known_.data();
  double* skip_until = skip_until_.data();
  // The anchor's phi drops by `change`: its skip range by change / L.
  const double skip_drop = change / kSkipLipschitz;
  int known = 0;
  for (size_t k = 0; k < n; ++k) {
    const Vec3 q = anchor[k];
    const uint8_t inside = (q.x >= lo.x) & (q.y >= lo.y) & (q.z >= lo.z) & (q.x <= hi.x) &
                           (q.y <= hi.y) & (q.z <= hi.z);
    anchor_phi[k] = inside ? anchor_phi[k] - change : kNan;
    skip_until[k] = inside ? skip_until[k] - skip_drop : -std::numeric_limits<double>::infinity();
    anchor_exact[k] &= exact;
    known_now[k] &= inside;
    known += known_now[k];
  }
  known_count_ = known;
}

void HapticRenderer::VisitSamples(const SdfSampler& sdf, const Vec3& centre, double start_us,
                                  TickOutput* out) {
  const size_t n = local_.size();
  const bool penalty = settings_.model == ForceModel::kPenalty;
  const bool area = penalty && rho_ > 0;
  // Above this phi a sample neither touches (sweep, iso 0) nor adds force.
  const double range = area ? PenaltyContactRange(rho_) : 0.0;
  SweptContact& c = out->swept;
  int evaluated = 0, skipped = 0;
  // The arrays and the loop's state through locals: a store through a byte or double pointer
  // may alias any member, and the members would be loaded again after each one (this loop runs
  // for every sample, and most of them only take the skip test).
  const bool have_previous = have_previous_;
  const size_t cursor = cursor_;
  const uint32_t* order = order_.data();
  const Vec3* local = local_.data();
  Vec3* from = from_.data();
  Vec3* anchor = anchor_.data();
  double* anchor_phi = anchor_phi_.data();
  uint8_t* anchor_exact = anchor_exact_.data();
  uint8_t* known = known_.data();
  SampleForce* term = term_.data();
  double* skip_until = skip_until_.data();
  const double travelled = travelled_;
  int known_count = known_count_;
  const double stiffness = settings_.stiffness;
  const double rho = rho_;
  const Vec3 last_normal = last_normal_;
  const bool budgeted = settings_.tick_budget_samples > 0 || settings_.tick_budget_us > 0;
  // First the samples the tool's path length alone proves out of range (most of them, every
  // tick), in a loop of their own that keeps its few values in registers: only the path's start
  // moves. skip_until is finite only after a read on this snapshot (or one whose change
  // CarryOverSwap bounded) found phi above the contact range, which left the term zero and the
  // sample known, and a swap that forgets either resets it. The rest are listed in visiting
  // order for the budgeted pass below. Moving the start of a sample the budget then leaves
  // unvisited is sound: its path so far was proved clear.
  uint32_t* pending = pending_.data();
  size_t m = 0;
  for (size_t at = cursor; at < n; ++at) {
    const uint32_t k = order[at];
    if (travelled < skip_until[k]) {
      from[k] = centre + local[k];
    } else {
      pending[m++] = static_cast<uint32_t>(at);
    }
  }
  for (size_t at = 0; at < cursor; ++at) {
    const uint32_t k = order[at];
    if (travelled < skip_until[k]) {
      from[k] = centre + local[k];
    } else {
      pending[m++] = static_cast<uint32_t>(at);
    }
  }
  skipped = static_cast<int>(n - m);
  size_t stopped_at = 0;
  bool stopped = false;
  for (size_t visit = 0; visit < m; ++visit) {
    const size_t at = pending[visit];
    const size_t k = order[at];
    const Vec3 x = centre + local[k];
    const Vec3 a = have_previous ? from[k] : x;
    double phi_a = kNan;
    bool sure_to_touch = false;
    if (!std::isnan(anchor_phi[k])) {
      // phi >= anchor_phi - L |p - anchor| along a -> x: the distance to the anchor is convex
      // along the segment, so its largest value is at an end.
      // Compared squared: no square root for the samples skipped, most of them.
      const double margin = anchor_phi[k] - range;
      const double da2 = (a - anchor[k]).LengthSqr(), dx2 = (x - anchor[k]).LengthSqr();
      if (margin > 0 && margin * margin > kSkipLipschitz * kSkipLipschitz * std::max(da2, dx2)) {
        term[k] = SampleForce{};
        known_count += known[k] ? 0 : 1;
        known[k] = 1;
        from[k] = x;
        ++skipped;
        continue;
      }
      // A lower bound is a safe start for the sweep's steps only while it says "free", and
      // only for a path that has length (the sweep returns its start as phi at its end).
      const double bound = anchor_phi[k] - kSkipLipschitz * std::sqrt(da2);
      if (da2 == 0 && anchor_exact[k]) {
        phi_a = anchor_phi[k];
      } else if (bound > 0 && !(a == x)) {
        phi_a = bound;
      }
      // From an exact anchor phi at x is at most anchor_phi + L |x - anchor|: below the
      // contact range, the penalty needs the gradient at x whatever the sweep finds.
      sure_to_touch = anchor_exact[k] && anchor_phi[k] + kSkipLipschitz * std::sqrt(dx2) < range;
    }
    if (budgeted && evaluated > 0 && OutOfBudget(evaluated, start_us)) {
      stopped = true;
      stopped_at = at;
      break;
    }
    ++evaluated;
    // A sample sure to touch reads phi and the gradient at x from one stencil first, and the
    // sweep takes that phi where it reaches x instead of reading the 8 corners again.
    double phi_x = kNan;
    Vec3 g;
    bool have_g = false;
    if (penalty && sure_to_touch) {
      sdf.PhiAndGradient(x, &phi_x, &g);
      have_g = true;
    }
    double phi = kNan;
    bool hit = false;
    if (have_previous) {
      const SegmentHit h = SweepSegment(sdf, a, x, 0.0, phi_a, &phi, phi_x);
      hit = h.hit;
      // Ties go to the lowest index, whatever the visiting order.
      const int index = static_cast<int>(k);
      if (h.hit && (!c.hit || h.time < c.time || (h.time == c.time && index < c.sample))) {
        c.hit = true;
        c.time = h.time;
        c.sample = index;
        c.point = a + (x - a) * h.time;
      }
    }
    SampleForce f;
    if (penalty) {
      if (std::isnan(phi)) {
        if (have_g) {
          phi = phi_x;
        } else if (hit) {
          // Touching: the gradient is needed; one stencil gives both.
          sdf.PhiAndGradient(x, &phi, &g);
          have_g = true;
        } else {
          phi = sdf.Phi(x);
        }
      }
      if (area ? phi < rho : phi <= 0) {
        if (!have_g) g = sdf.Gradient(x);
        f = area ? AreaWeightedSampleForce(x, phi, g, rho, stiffness, centre, last_normal)
                 : PenaltySampleForce(phi, g, stiffness, last_normal);
      }
    } else if (std::isnan(phi)) {
      phi = sdf.Phi(x);
    }
    term[k] = f;
    known_count += known[k] ? 0 : 1;
    known[k] = 1;
    from[k] = x;
    anchor[k] = x;
    anchor_phi[k] = phi;
    anchor_exact[k] = 1;
    // phi(p) >= phi - L |p - x| > range while L (path length from here) < phi - range; a
    // thousandth less, so the path length's rounding never matters.
    skip_until[k] = phi > range ? travelled + (phi - range) * (0.999 / kSkipLipschitz)
                                : -std::numeric_limits<double>::infinity();
  }
  known_count_ = known_count;
  // Resume at the first sample not visited; a complete tick starts the next at the coarsest.
  cursor_ = stopped ? stopped_at : 0;
  out->over_budget = stopped;
  out->samples_evaluated = evaluated;
  out->samples_skipped = skipped;
}

const TickOutput& HapticRenderer::Tick(const std::shared_ptr<const SdfSampler>& snapshot,
                                       const DeviceSample& sample) {
  ++ticks_;
  if (!sample.position.IsFinite() || !std::isfinite(sample.time)) {
    ++nan_samples_;
    out_.nan_ignored = true;  // force, contact and proxy stay as they were
    return out_;
  }
  const double start_us = settings_.tick_budget_us > 0 ? clock_->NowUs() : 0.0;
  if (have_centre_) travelled_ += (sample.position - last_centre_).Length();
  last_centre_ = sample.position;
  have_centre_ = true;
  const double period = 1.0 / settings_.rate_hz;
  double dt = have_previous_ ? sample.time - previous_time_ : period;
  if (!(dt > 0) || dt > 10 * period) dt = period;  // a stalled or reset device clock

  const SdfSampler* sdf = snapshot.get();
  TickOutput out;
  if (sdf != previous_snapshot_) CarryOverSwap(sdf);
  if (settings_.model == ForceModel::kProxy) {
    // The proxy's force is the output: it runs first, whatever the samples' budget leaves.
    const ProxyState& p = proxy_.Update(sdf, sample.position, dt);
    out.model_force = p.force;
    out.contact = p.contact;
    out.colliding = p.contact ? 1 : 0;
    out.proxy = p.proxy;
    out.normal_fallback = p.normal_fallback;
  }
  if (sdf != nullptr) {
    // Both models report the tool surface's first contact (the proxy also sweeps its own
    // centre inside ProxyModel).
    VisitSamples(*sdf, sample.position, start_us, &out);
  } else {
    for (size_t k = 0; k < local_.size(); ++k) from_[k] = sample.position + local_[k];
  }
  out.samples_known = known_count_;

  bool contact_set_changed = false;
  if (settings_.model == ForceModel::kPenalty) {
    out.proxy = sample.position;
    if (sdf != nullptr) {
      // The terms of every sample known on this snapshot, added in index order (as
      // ComputeAreaWeightedPenaltyForce adds them, so a complete tick gives the same bits).
      // A tick cut short before every sample is known sums a spread subset: scaled by
      // n / known, sum and area are estimates of the whole tool's, and their ratio, the
      // force, needs no scaling at all.
      PenaltyForce f;
      double covered = 0;
      for (size_t k = 0; k < local_.size(); ++k) {
        if (!known_[k]) continue;
        const SampleForce& t = term_[k];
        f.colliding += t.colliding ? 1 : 0;
        if (rho_ > 0 && t.inside <= 0) continue;
        covered += t.inside;
        f.without_normal += t.without_normal ? 1 : 0;
        f.sum += t.force;
      }
      if (rho_ > 0) {
        if (covered > 0) f.average = f.sum / covered;
      } else if (f.colliding > 0) {
        f.average = f.sum / f.colliding;
      }
      out.model_force = f.average;
      out.colliding = f.colliding;
      out.normal_fallback = f.without_normal > 0;
      const double m = f.average.Length();
      if (m > 0 && f.without_normal == 0) last_normal_ = f.average / m;
    }
    out.contact = out.colliding > 0 || out.swept.hit;
    contact_set_changed = out.colliding != previous_colliding_;
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

  have_previous_ = true;
  previous_time_ = sample.time;
  previous_snapshot_ = sdf;
  previous_snapshot_ref_ = snapshot;
  previous_colliding_ = out.colliding;
  out_ = out;
  return out_;
}

}  // namespace sculpt::haptics
