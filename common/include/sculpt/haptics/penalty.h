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
  /// Both at once, equal to Phi(p) and Gradient(p); samplers whose gradient reads the value's
  /// own corners override it to read them once.
  virtual void PhiAndGradient(const Vec3& p, double* phi, Vec3* gradient) const {
    *phi = Phi(p);
    *gradient = Gradient(p);
  }
  /// Grid spacing in world units: continuous contact detection steps at most half of it.
  virtual double cell_size() const = 0;
  /// What is known of how phi changed from `previous` (a sampler read before this one) to this
  /// one: true with *bound >= 0 and the world box [*lo, *hi] such that |Phi(p) -
  /// previous.Phi(p)| <= *bound for every p in the box; false when nothing is known (the
  /// default). The haptic renderer keeps the distance bounds it learnt on `previous` through a
  /// swap with it, so the first tick on a new snapshot skips the same far samples as any other.
  virtual bool ChangeSince(const SdfSampler& previous, double* bound, Vec3* lo, Vec3* hi) const {
    (void)previous, (void)bound, (void)lo, (void)hi;
    return false;
  }
};

/// phi of a Sculpture (trilinear in its narrow band) and its central-difference gradient over
/// one voxel. The sculpture must outlive the sampler and not be edited while it is read.
class SculptureSdf : public SdfSampler {
 public:
  explicit SculptureSdf(const levelset::Sculpture& sculpture) : sculpture_(sculpture) {}
  double Phi(const Vec3& p) const override { return sculpture_.SampleWorld(p); }
  Vec3 Gradient(const Vec3& p) const override;
  double cell_size() const override { return sculpture_.voxel_size(); }

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
  double cell_size() const override { return h; }
};

struct PenaltyForce {
  Vec3 sum;          // eq. 3.4
  Vec3 average;      // eq. 3.5, divided by the colliding samples (digest claim 7)
  int colliding = 0;
  /// Colliding samples whose gradient vanished (medial axis, beyond the band): they took the
  /// fallback normal, or no direction when none was given.
  int without_normal = 0;
};

/// Force on a tool given by its surface samples: every sample with phi <= 0 (eq. 3.1, §3.1)
/// contributes kappa |phi| N (eq. 3.3 as the thesis's code computes it: outward). Where the
/// interpolated gradient vanishes (the medial axis) the sample contributes no direction.
PenaltyForce ComputePenaltyForce(const SdfSampler& sdf, const std::vector<Vec3>& samples,
                                 double kappa);

/// As above, but a colliding sample whose gradient vanishes pushes along `fallback_normal` (unit,
/// or zero for no direction) instead of contributing nothing: the renderer passes the last valid
/// normal (seed 000 §5 item 15, the previous-frame rule of §8).
PenaltyForce ComputePenaltyForce(const SdfSampler& sdf, const std::vector<Vec3>& samples,
                                 double kappa, const Vec3& fallback_normal);

/// The penalty average weighted by each sample's share of the tool surface that lies inside the
/// material. Sample k stands for a disc of area `sample_area` (the tool's area over the sample
/// count: ToolSurfaceSamples spreads a sphere's samples evenly) and radius rho = sqrt(area/pi) on
/// the surface of a sphere tool centred at `tool_centre`; over the disc phi changes linearly by
/// the gradient's component along the tool surface (+-s, s = rho |grad_t phi|). The disc's
/// inside fraction f_k and mean depth d_k are then closed-form and smooth in phi_k, and samples
/// up to rho outside still count. average = kappa sum_k d_k N_k / sum_k f_k (sum: the
/// numerator): the mean depth over the contact area instead of over the colliding samples
/// (eq. 3.5 with each sample's area as its weight). `colliding` counts samples with phi <= 0.
/// A non-positive or non-finite sample_area gives an empty force.
/// `phi`, when given, holds phi at each sample (NaN entries are sampled here).
PenaltyForce ComputeAreaWeightedPenaltyForce(const SdfSampler& sdf,
                                             const std::vector<Vec3>& samples, double sample_area,
                                             double kappa, const Vec3& tool_centre,
                                             const Vec3& fallback_normal = {},
                                             const std::vector<double>* phi = nullptr);

/// One sample's term of the sums above, from phi and the gradient at the sample: what
/// ComputePenaltyForce (`rho` 0) or ComputeAreaWeightedPenaltyForce (`rho` = sqrt(area / pi))
/// adds for it, bit for bit, so a caller may keep each sample's term and add them up itself.
struct SampleForce {
  Vec3 force;           // added to PenaltyForce::sum
  double inside = 0;    // added to the area-weighted denominator (0 for the plain model)
  bool colliding = false;
  bool without_normal = false;
};
/// The largest phi at which a sample can still contribute: rho for the area-weighted model
/// (samples up to a patch radius outside count), 0 for the plain one. A sample whose phi is
/// known to be above it contributes nothing and needs no gradient.
inline double PenaltyContactRange(double rho) { return rho > 0 ? rho : 0.0; }
SampleForce PenaltySampleForce(double phi, const Vec3& gradient, double kappa,
                               const Vec3& fallback_normal);
SampleForce AreaWeightedSampleForce(const Vec3& x, double phi, const Vec3& gradient, double rho,
                                    double kappa, const Vec3& tool_centre,
                                    const Vec3& fallback_normal);

/// The thesis's circle tool samples (App. A.1): k + 1 points r (cos 2 pi i/k, sin 2 pi i/k) + c,
/// i = 0..k, in the z = c.z plane (the last repeats the first, as the MATLAB code does).
std::vector<Vec3> CircleSamples(const Vec3& center, double radius, int k);

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_PENALTY_H_
