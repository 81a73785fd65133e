/// @brief The thesis's penalty haptic model (seed 000 §2.4, eqs. 3.1-3.5 with the digest's sign
/// correction) on a dense sample of phi: contact at tool samples, per-sample force
/// F_k = kappa |phi| N, summed and averaged over the colliding samples.
#ifndef SCULPT_HAPTICS_PENALTY_H_
#define SCULPT_HAPTICS_PENALTY_H_

#include <vector>

#include "sculpt/core/vec3.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::haptics {

/// Anything that gives phi and its gradient at a world point. Implementations are read-only.
class SdfSampler {
 public:
  virtual ~SdfSampler() = default;
  virtual double Phi(const Vec3& p) const = 0;
  /// Not necessarily unit length; zero where phi has no direction (medial axis, beyond the band).
  virtual Vec3 Gradient(const Vec3& p) const = 0;
};

/// phi of a Sculpture (trilinear in its narrow band) and its central-difference gradient over
/// one voxel. The sculpture must outlive the sampler and not be edited while it is read.
class SculptureSdf : public SdfSampler {
 public:
  explicit SculptureSdf(const levelset::Sculpture& sculpture) : sculpture_(sculpture) {}
  double Phi(const Vec3& p) const override { return sculpture_.SampleWorld(p); }
  Vec3 Gradient(const Vec3& p) const override;

 private:
  const levelset::Sculpture& sculpture_;
};

/// A dense field of phi on nodes origin + (i, j, k) * h (world units). Axes of extent 1 are
/// flat (a one-voxel slab is 2D). Read-only; safe to share between threads.
struct DenseSdf : SdfSampler {
  DenseSdf() = default;
  DenseSdf(const levelset::DenseField* f, Vec3 o, double spacing) : field(f), origin(o), h(spacing) {}
  const levelset::DenseField* field = nullptr;
  Vec3 origin;
  double h = 1.0;

  /// Trilinear phi at p (eq. 3.1 in 3D), clamped into the box.
  double Phi(const Vec3& p) const override;
  /// Trilinear interpolation of the nodes' central-difference gradients (eq. 3.2, App. A.4
  /// `respcol`: one-sided at the box border), not normalised.
  Vec3 Gradient(const Vec3& p) const override;
};

struct PenaltyForce {
  Vec3 sum;          // eq. 3.4
  Vec3 average;      // eq. 3.5, divided by the colliding samples (digest claim 7)
  int colliding = 0;
};

/// Force on a tool given by its surface samples: every sample with phi <= 0 (eq. 3.1, §3.1)
/// contributes kappa |phi| N (eq. 3.3 as the thesis's code computes it: outward). Where the
/// interpolated gradient vanishes (the medial axis) the sample contributes no direction.
PenaltyForce ComputePenaltyForce(const SdfSampler& sdf, const std::vector<Vec3>& samples,
                                 double kappa);

/// The thesis's circle tool samples (App. A.1): k + 1 points r (cos 2 pi i/k, sin 2 pi i/k) + c,
/// i = 0..k, in the z = c.z plane (the last repeats the first, as the MATLAB code does).
std::vector<Vec3> CircleSamples(const Vec3& center, double radius, int k);

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_PENALTY_H_
