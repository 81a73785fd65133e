/// @brief Finite-difference level-set kernels on a DenseField: normal-speed motion, curvature flow,
/// reinitialisation, Eikonal error, smoothed Heaviside/delta. No OpenVDB here.
#ifndef SCULPT_LEVELSET_KERNELS_H_
#define SCULPT_LEVELSET_KERNELS_H_

#include <cmath>
#include <cstdint>
#include <vector>

#include "sculpt/levelset/dense_field.h"

namespace sculpt::levelset {

/// Spatial discretisation of |grad phi|.
/// kCentral: central differences, the thesis's choice in its experiments (seed 000 §2.7, §6.2);
///   only stable with dt ~ dx^2, kept for reproduction.
/// kUpwind: first-order Godunov upwind (seed 000 §4.3).
/// kWeno5: fifth-order Hamilton-Jacobi WENO one-sided derivatives with the Godunov Hamiltonian.
enum class SpatialScheme : uint8_t { kCentral = 0, kUpwind = 1, kWeno5 = 2 };

/// TVD Runge-Kutta (Shu-Osher) of order 1 (forward Euler), 2 or 3.
enum class TemporalScheme : uint8_t { kRk1 = 1, kRk2 = 2, kRk3 = 3 };

/// What the stencil sees beyond the box.
/// kClamp: zero-gradient extension (values beyond the box equal the nearest box value).
/// kAdiabatic: the thesis's boundary condition (5.10): |grad phi| := 0 on the box's border voxels,
///   so border voxels never move (seed 000 §2.7 `normgrad`). Used only for reproduction. An axis
///   whose extent is 1 (a one-voxel slab) has no border and contributes no derivative.
enum class Boundary : uint8_t { kClamp = 0, kAdiabatic = 1 };

struct MotionSettings {
  SpatialScheme spatial = SpatialScheme::kWeno5;
  TemporalScheme temporal = TemporalScheme::kRk2;
  Boundary boundary = Boundary::kClamp;
};

/// Active voxel list: linear indices into a DenseField (only these are updated).
using VoxelList = std::vector<uint32_t>;

/// One time step of phi_t + F |grad phi| = 0 (seed 000 eq. 4.x, normal-speed motion) of length dt
/// on the voxels in `active`; `speed` holds F per voxel (same layout as phi; F < 0 moves the
/// interface inward, i.e. phi grows: the press of eq. 5.1 with the digest's sign correction).
/// Voxels not in `active` keep their values but feed the stencils. dx is the voxel size in the
/// same length unit as F*dt. Godunov flux selection per voxel by the sign of F. For kCentral the
/// update is phi -= dt * F * |grad phi|_central, exactly the thesis's `objdef`.
/// No CFL control: the caller chooses dt (see MaxStableStep).
void NormalMotionStep(DenseField& phi, const std::vector<float>& speed, const VoxelList& active,
                      double dt, double dx, const MotionSettings& settings);

/// Largest dt with CFL number `cfl` for speeds up to max_abs_speed: cfl * dx / max_abs_speed.
double MaxStableStep(double max_abs_speed, double dx, double cfl);

/// One explicit step of mean-curvature flow phi_t = w * kappa * |grad phi| on `active`, with kappa
/// from central differences (seed 000 eq. 2.8) and `weight` w per voxel (>= 0). Stable for
/// dt <= dx^2 / (6 max w). Where |grad phi| < 1e-6 the voxel is left unchanged.
void CurvatureFlowStep(DenseField& phi, const std::vector<float>& weight, const VoxelList& active,
                       double dt, double dx);

/// Reinitialisation by the Sussman-Smereka-Osher equation (seed 000 eq. 4.9) with the smoothed
/// sign S(phi0) = phi0 / sqrt(phi0^2 + dx^2) (eq. 4.10), pseudo-time step cfl*dx, `iterations`
/// steps, on `active` only. Voxels adjacent to the interface (a sign change to a 6-neighbour) use
/// the Russo-Smereka subcell fix so the zero level set does not move. Returns the number of steps.
int Reinitialize(DenseField& phi, const VoxelList& active, int iterations, double dx,
                 const MotionSettings& settings, double cfl = 0.5);

/// Eikonal error ||grad phi| - 1| over voxels of `active` with |phi| < band (world units), away
/// from the box border, measured with first-order Godunov differences that choose the upwind side
/// by sign(phi). Voxels where phi has a kink (both one-sided differences point away) are skipped.
struct EikonalStats {
  double mean_abs_error = 0;
  double max_abs_error = 0;
  uint64_t samples = 0;
};
EikonalStats MeasureEikonal(const DenseField& phi, const VoxelList& active, double dx,
                            double band);

/// When MeasureAndReinitialize reinitialises: the measured mean error (over |phi| < band)
/// exceeds `threshold`, or `force`.
struct ReinitTrigger {
  double band = 0;
  double threshold = 0;
  bool force = false;
};
struct MeasuredReinit {
  EikonalStats before;     // MeasureEikonal's figures before any step
  bool triggered = false;  // whether `trigger` asked for the reinitialisation
  int passes = 0;          // Reinitialize's return value, 0 when not triggered
};
/// MeasureEikonal(phi, active, dx, trigger.band), then, when `trigger` holds,
/// Reinitialize(phi, active, iterations, dx, settings, cfl): the same figures and field bit for
/// bit. For the edits' scheme (upwind, RK1, kClamp, stencils inside the box) one pass reads each
/// stencil for the measure, the frozen sign and distance and the first step. A non-positive dx
/// measures nothing and changes nothing.
MeasuredReinit MeasureAndReinitialize(DenseField& phi, const VoxelList& active, int iterations,
                                      double dx, const MotionSettings& settings, double cfl,
                                      const ReinitTrigger& trigger);

namespace internal {
/// sin(pi u) / pi for |u| <= 1/2, by its Taylor series to u^21 (the first term left out is below
/// 1e-18). Plain double arithmetic in a fixed order instead of libm's sin and cos: the smoothed
/// Heaviside and delta, hence every tracked volume, are then the same with every libm version and
/// CPU (a replica on another machine must agree bit for bit), and cost a fifth of the calls.
inline double SinPiOverPi(double u) {
  constexpr double c[] = {1.0,
                          -1.6449340668482264,
                          0.8117424252833536,
                          -0.19075182412208422,
                          0.0261478478176548,
                          -0.0023460810354558235,
                          0.000148428793031071,
                          -6.975873661656381e-06,
                          2.5312174041370274e-07,
                          -7.304711822217775e-09,
                          1.7165384749821432e-10};  // (-1)^k pi^2k / (2k+1)!
  const double u2 = u * u;
  double s = c[10];
  for (int k = 9; k >= 0; --k) s = s * u2 + c[k];
  return s * u;
}
}  // namespace internal

/// Smoothed delta of seed 000 eq. 5.7: (1/(2 eps))(1 + cos(pi phi / eps)) on |phi| <= eps (the
/// cosine evaluated as sin(pi (1/2 - |t|)) by internal::SinPiOverPi, not by libm).
inline double SmoothedDelta(double phi, double eps) {
  // A non-positive eps is the sharp limit, whose delta is zero almost everywhere.
  if (!(eps > 0.0) || std::abs(phi) > eps) return 0.0;
  constexpr double kPi = 3.141592653589793;
  const double t = std::abs(phi / eps);
  return (0.5 / eps) * (1.0 + kPi * internal::SinPiOverPi(0.5 - t));
}
/// Its integral from -inf: 0 below -eps, 1 above eps, 1/2 (1 + phi/eps + sin(pi phi/eps)/pi)
/// inside (sin(pi t) = sin(pi (+-1 - t)) keeps the series' argument within 1/2).
inline double SmoothedHeaviside(double phi, double eps) {
  if (!(eps > 0.0)) return phi > 0.0 ? 1.0 : 0.0;
  if (phi < -eps) return 0.0;
  if (phi > eps) return 1.0;
  const double t = phi / eps;
  const double u = t > 0.5 ? 1.0 - t : (t < -0.5 ? -1.0 - t : t);
  return 0.5 * (1.0 + t + internal::SinPiOverPi(u));
}
/// Fraction of a voxel inside the material: 1 - SmoothedHeaviside(phi, eps).
inline double InsideFraction(double phi, double eps) { return 1.0 - SmoothedHeaviside(phi, eps); }

/// The tracked volume's inside fraction: (4 F(phi, dx) - F(phi, 2 dx)) / 3 with F =
/// InsideFraction, 1 at phi <= -2 dx and 0 at phi >= 2 dx.
///
/// Summed over a grid, eq. 5.7's fraction at eps = 1.5 voxels measures more than the surface
/// encloses: a smoothed step of second moment m2 = int t^2 delta(t) dt adds (m2 / 2) times the
/// integral of the mean curvature sum over the surface, about 0.065 eps^2 per unit of
/// int kappa dA (+0.35% on a sphere of 16 voxels' radius, +1.4% at 8 voxels). The second moment
/// grows as eps^2, so four thirds of the step at eps = dx less a third of the step at 2 dx has
/// none: the same sums then match the enclosed volume of a sphere of 8 voxels to 2e-5. Both
/// widths are whole voxels, at which the raised cosine is a partition of unity along an axis,
/// so a plane moving through the grid changes the sum linearly. Between |phi| = dx and 2 dx the
/// fraction leaves [0, 1] by up to 1/6 (its delta is negative there); only its sums have meaning.
inline double VolumeFraction(double phi, double dx) {
  if (phi <= -2.0 * dx) return 1.0;
  if (phi >= 2.0 * dx) return 0.0;
  return (4.0 * InsideFraction(phi, dx) - InsideFraction(phi, 2.0 * dx)) / 3.0;
}
/// -d VolumeFraction / d phi: the area weight of a normal offset of the tracked volume.
inline double VolumeDelta(double phi, double dx) {
  return (4.0 * SmoothedDelta(phi, dx) - SmoothedDelta(phi, 2.0 * dx)) / 3.0;
}

/// |grad phi| at one voxel with central differences (one-sided at the box border), as the
/// thesis's `normgrad`; with Boundary::kAdiabatic it returns 0 on border voxels.
double CentralGradientNorm(const DenseField& phi, int i, int j, int k, double dx,
                           Boundary boundary);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_KERNELS_H_
