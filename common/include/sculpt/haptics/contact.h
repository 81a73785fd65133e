/// @brief Continuous contact detection (seed 000 §2.4/§3.1 remedy, §5 item 1): each tool sample's
/// path since the previous tick is searched for the first point where phi <= iso.
#ifndef SCULPT_HAPTICS_CONTACT_H_
#define SCULPT_HAPTICS_CONTACT_H_

#include <limits>
#include <vector>

#include "sculpt/core/vec3.h"
#include "sculpt/haptics/penalty.h"

namespace sculpt::haptics {

/// Where a swept segment first reaches the level set phi = iso.
struct SegmentHit {
  bool hit = false;
  /// Parameter of the first point with phi <= iso on [0, 1] (a <= t <= b), refined by bisection
  /// to 1e-3 of a cell; 0 when the start already touches.
  double time = 1;
  /// The last parameter known to be free (phi > iso), <= time: where a proxy may stop.
  double free_time = 1;
};

/// Marches a -> b in steps of at most half a cell (SdfSampler::cell_size), longer where phi says
/// the surface is far: trilinear phi of a field whose nodes differ by at most one cell per cell
/// changes by at most sqrt(3) per unit length, so a step of (phi - iso) / sqrt(3) cannot cross
/// phi = iso. A one-cell-thick wall is therefore never stepped over. Non-finite a or b: no hit.
SegmentHit SweepSegment(const SdfSampler& sdf, const Vec3& a, const Vec3& b, double iso = 0);
/// As above with phi(a) already known (`phi_a`, not offset by iso; NaN: unknown); phi(b) is
/// written to `*phi_b` when the march reaches b without a hit, NaN otherwise. The haptic
/// renderer carries each sample's phi from one tick to the next this way.
/// `known_phi_b` (not offset by iso; NaN: unknown), when given, is Phi(b): the step that reaches
/// b takes it instead of reading phi again (the renderer reads it with the gradient first).
SegmentHit SweepSegment(const SdfSampler& sdf, const Vec3& a, const Vec3& b, double iso,
                        double phi_a, double* phi_b,
                        double known_phi_b = std::numeric_limits<double>::quiet_NaN());

/// The first contact of a tool moving from `from` to `to` (sample k moves from from[k] to to[k];
/// the two must have the same size, otherwise no contact is reported).
struct SweptContact {
  bool hit = false;
  double time = 1;  // time of impact as a fraction of the tick, 0 at `from`
  int sample = -1;  // index of the sample that touches first
  Vec3 point;       // where it touches
};
SweptContact FindFirstContact(const SdfSampler& sdf, const std::vector<Vec3>& from,
                              const std::vector<Vec3>& to, double iso = 0);
/// As above, reading phi at `from` from `phi_from` (NaN entries: unknown) and writing phi at `to`
/// into `phi_to` (NaN where the march stopped at a hit). Both must have from.size() entries.
SweptContact FindFirstContact(const SdfSampler& sdf, const std::vector<Vec3>& from,
                              const std::vector<Vec3>& to, double iso,
                              const std::vector<double>& phi_from, std::vector<double>* phi_to);

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_CONTACT_H_
