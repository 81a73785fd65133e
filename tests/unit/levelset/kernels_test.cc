/// @brief Unit tests of the level-set kernels: motion, curvature, reinit, Eikonal, smoothed H.
#include "sculpt/levelset/kernels.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

namespace sculpt::levelset {
namespace {

constexpr double kPi = std::numbers::pi;

/// A field whose voxel (i, j, k) holds f(i*dx, j*dx, k*dx).
DenseField MakeField(Int3 dims, double dx, const std::function<double(double, double, double)>& f) {
  DenseField field(Int3{0, 0, 0}, dims, 0.0f);
  for (int k = 0; k < dims.z; ++k) {
    for (int j = 0; j < dims.y; ++j) {
      for (int i = 0; i < dims.x; ++i) {
        field.at(i, j, k) = static_cast<float>(f(i * dx, j * dx, k * dx));
      }
    }
  }
  return field;
}

/// Signed distance to a sphere (or, in a slab, a circle when cz is the slab's plane).
DenseField MakeSphere(Int3 dims, double dx, double cx, double cy, double cz, double r,
                      double scale = 1.0) {
  return MakeField(dims, dx, [=](double x, double y, double z) {
    return scale * (std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz)) - r);
  });
}

VoxelList AllVoxels(const DenseField& f) {
  VoxelList out(f.size());
  for (size_t n = 0; n < f.size(); ++n) out[n] = static_cast<uint32_t>(n);
  return out;
}

std::vector<float> Uniform(const DenseField& f, float value) {
  return std::vector<float>(f.size(), value);
}

/// Radius of the sphere whose volume is the smoothed inside volume of phi (needs |grad phi| ~ 1).
double VolumeRadius(const DenseField& f, double dx) {
  double volume = 0.0;
  for (float v : f.data()) volume += InsideFraction(v, 1.5 * dx);
  volume *= dx * dx * dx;
  return std::cbrt(3.0 * volume / (4.0 * kPi));
}

/// Radius of the disc whose area is the smoothed inside area of a one-voxel slab.
double AreaRadius(const DenseField& f, double dx) {
  double area = 0.0;
  for (float v : f.data()) area += InsideFraction(v, 1.5 * dx);
  return std::sqrt(area * dx * dx / kPi);
}

/// Mean distance from voxel `center` to the zero crossings along the +-x, +-y (and +-z unless
/// the box is a slab) axis lines, each found by linear interpolation between voxels.
double AxisCrossingRadius(const DenseField& f, Int3 center, double dx) {
  double sum = 0.0;
  int count = 0;
  const Int3 d = f.dims();
  const int axes = d.z == 1 ? 2 : 3;
  for (int a = 0; a < axes; ++a) {
    for (int dir : {-1, 1}) {
      int c[3] = {center.x, center.y, center.z};
      const int n = a == 0 ? d.x : (a == 1 ? d.y : d.z);
      for (int step = 0; c[a] + dir >= 0 && c[a] + dir < n; ++step) {
        const double p0 = f.at(c[0], c[1], c[2]);
        c[a] += dir;
        const double p1 = f.at(c[0], c[1], c[2]);
        if (p0 <= 0.0 && p1 > 0.0) {
          sum += (step + p0 / (p0 - p1)) * dx;
          ++count;
          break;
        }
      }
    }
  }
  EXPECT_EQ(count, 2 * axes) << "no zero crossing on some axis";
  return count > 0 ? sum / count : 0.0;
}

/// Deterministic pseudo-random numbers in [0, 1).
class Lcg {
 public:
  explicit Lcg(uint64_t seed) : state_(seed) {}
  double Next() {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state_ >> 11) * (1.0 / 9007199254740992.0);
  }

 private:
  uint64_t state_;
};

/// Max over voxels with |phi| < band of | |grad phi| - 1 |, where |grad phi| is read back from one
/// forward-Euler step at F = +1 (phi_new = phi - dt |grad phi|).
double MaxGodunovGradientError(SpatialScheme scheme, double radius_voxels) {
  const double dx = 1.0 / radius_voxels;
  const int n = static_cast<int>(std::ceil(3.0 * radius_voxels)) + 8;
  const double c = 0.5 * n * dx + 0.137 * dx;
  DenseField phi = MakeSphere(Int3{n, n, n}, dx, c, c - 0.291 * dx, c + 0.053 * dx, 1.0);
  const DenseField before = phi;
  const double dt = dx;
  NormalMotionStep(phi, Uniform(phi, 1.0f), AllVoxels(phi), dt, dx,
                   MotionSettings{scheme, TemporalScheme::kRk1, Boundary::kClamp});
  double max_err = 0.0;
  for (size_t m = 0; m < phi.size(); ++m) {
    const double p0 = before.data()[m];
    if (std::abs(p0) >= 2.0 * dx) continue;
    const double grad = (p0 - phi.data()[m]) / dt;
    max_err = std::max(max_err, std::abs(grad - 1.0));
  }
  return max_err;
}

TEST(KernelsTest, Weno5SphereGradientIsUnitToHighOrder) {
  const double coarse = MaxGodunovGradientError(SpatialScheme::kWeno5, 8.0);
  const double fine = MaxGodunovGradientError(SpatialScheme::kWeno5, 16.0);
  RecordProperty("max_error_r8", std::to_string(coarse));
  RecordProperty("max_error_r16", std::to_string(fine));
  // Measured 1.2e-4 and 4.1e-6 (ratio ~30, fifth order on smooth data). Wrong linear weights
  // drop it to third order (ratio ~8), which these bounds reject.
  EXPECT_LT(coarse, 4e-4);
  EXPECT_LT(fine, 2e-5);
  EXPECT_GT(coarse / fine, 12.0) << "WENO5 error must fall faster than dx^3";
}

TEST(KernelsTest, UpwindSphereGradientIsUnitToFirstOrder) {
  const double coarse = MaxGodunovGradientError(SpatialScheme::kUpwind, 8.0);
  const double fine = MaxGodunovGradientError(SpatialScheme::kUpwind, 16.0);
  const double weno = MaxGodunovGradientError(SpatialScheme::kWeno5, 8.0);
  RecordProperty("max_error_r8", std::to_string(coarse));
  RecordProperty("max_error_r16", std::to_string(fine));
  EXPECT_LT(coarse, 0.15);
  EXPECT_GT(coarse / fine, 1.6) << "first-order upwind error must fall about as dx";
  EXPECT_GT(coarse, 5.0 * weno) << "WENO5 should be much closer to 1 than first-order upwind";
}

TEST(KernelsTest, PlaneMovesInwardByElapsedTimeForEverySchemeAndOrder) {
  const double dx = 0.5;
  const double z0 = 10.0;
  const double total = 3.0;
  for (SpatialScheme spatial :
       {SpatialScheme::kCentral, SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    for (TemporalScheme temporal :
         {TemporalScheme::kRk1, TemporalScheme::kRk2, TemporalScheme::kRk3}) {
      DenseField phi =
          MakeField(Int3{6, 5, 64}, dx, [&](double, double, double z) { return z - z0; });
      const DenseField before = phi;
      const double dt = MaxStableStep(1.0, dx, 0.5);
      const int steps = static_cast<int>(std::lround(total / dt));
      const std::vector<float> speed = Uniform(phi, -1.0f);
      const VoxelList active = AllVoxels(phi);
      for (int s = 0; s < steps; ++s) {
        NormalMotionStep(phi, speed, active, dt, dx, MotionSettings{spatial, temporal});
      }
      // F = -1 raises an SDF by the elapsed time: the interface moves by `total` into the
      // material. The clamped faces z = 0 and z = top halve the central difference there, so
      // voxels within their reach are left out.
      double max_err = 0.0;
      for (int k = 16; k < 40; ++k) {
        for (int j = 0; j < 5; ++j) {
          for (int i = 0; i < 6; ++i) {
            max_err = std::max(max_err, std::abs(phi.at(i, j, k) - (before.at(i, j, k) + total)));
          }
        }
      }
      EXPECT_LT(max_err, 1e-4) << "spatial=" << static_cast<int>(spatial)
                               << " temporal=" << static_cast<int>(temporal);
    }
  }
}

TEST(KernelsTest, ObliquePlaneMovesInwardByElapsedTime) {
  const double dx = 1.0;
  const double nx = 1.0 / 3.0, ny = 2.0 / 3.0, nz = 2.0 / 3.0;
  for (SpatialScheme spatial : {SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    DenseField phi = MakeField(Int3{40, 40, 40}, dx, [&](double x, double y, double z) {
      return nx * x + ny * y + nz * z - 25.0;
    });
    const DenseField before = phi;
    const double dt = MaxStableStep(1.0, dx, 0.5);
    const std::vector<float> speed = Uniform(phi, -1.0f);
    const VoxelList active = AllVoxels(phi);
    for (int s = 0; s < 8; ++s) {
      NormalMotionStep(phi, speed, active, dt, dx, MotionSettings{spatial, TemporalScheme::kRk3});
    }
    // Upstream information comes from larger phi; stay 10 voxels clear of every face.
    double max_err = 0.0;
    for (int k = 10; k < 30; ++k) {
      for (int j = 10; j < 30; ++j) {
        for (int i = 10; i < 30; ++i) {
          max_err = std::max(max_err, std::abs(phi.at(i, j, k) - (before.at(i, j, k) + 4.0)));
        }
      }
    }
    EXPECT_LT(max_err, 1e-4) << "spatial=" << static_cast<int>(spatial);
  }
}

TEST(KernelsTest, RungeKuttaStepIsTheTaylorPolynomialOfItsOrder) {
  // phi = z - z0 with F = a z is a linear ODE per voxel: every stage keeps phi linear in z (all
  // schemes differentiate it exactly), with slope alpha' = -a alpha. One Shu-Osher TVD RK step of
  // order q multiplies alpha by the Taylor polynomial of exp(-a dt) to degree q.
  const double dx = 1.0;
  const double a = 0.04;
  const double dt = 10.0;  // a dt = 0.4: one step, so only the stage weights matter.
  const double z0 = 17.0;
  for (SpatialScheme spatial :
       {SpatialScheme::kCentral, SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    for (TemporalScheme temporal :
         {TemporalScheme::kRk1, TemporalScheme::kRk2, TemporalScheme::kRk3}) {
      DenseField phi =
          MakeField(Int3{3, 3, 40}, dx, [&](double, double, double z) { return z - z0; });
      std::vector<float> speed(phi.size());
      for (int k = 0; k < 40; ++k) {
        for (int j = 0; j < 3; ++j) {
          for (int i = 0; i < 3; ++i) speed[phi.Index(i, j, k)] = static_cast<float>(a * k * dx);
        }
      }
      NormalMotionStep(phi, speed, AllVoxels(phi), dt, dx, MotionSettings{spatial, temporal});
      const double h = a * dt;
      double alpha = 1.0 - h;
      if (temporal != TemporalScheme::kRk1) alpha += h * h / 2.0;
      if (temporal == TemporalScheme::kRk3) alpha -= h * h * h / 6.0;
      // Clamped faces disturb 3 voxels per stage; check well inside.
      for (int k = 12; k < 28; ++k) {
        EXPECT_NEAR(phi.at(1, 1, k), alpha * k * dx - z0, 1e-4)
            << "k=" << k << " spatial=" << static_cast<int>(spatial)
            << " temporal=" << static_cast<int>(temporal);
      }
    }
  }
}

TEST(KernelsTest, KinksBetweenCollidingFrontsMoveAtUnitSpeed) {
  const double dx = 1.0;
  const double c = 20.0;
  const double gap = 6.0;
  const double total = 2.0;
  for (SpatialScheme spatial : {SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    // Expanding (F = +1) into a gap: the ridge phi = gap - |z - c| falls at unit speed. Pressing
    // (F = -1) a sheet: the trough phi = |z - c| - gap rises at unit speed (viscosity solution:
    // phi(z, t) = min / max of phi0 over |y - z| <= t). Summing the two upwind terms instead of
    // taking Godunov's max would move both at sqrt(2).
    for (float f : {1.0f, -1.0f}) {
      DenseField phi = MakeField(Int3{4, 4, 40}, dx, [&](double, double, double z) {
        return f * (gap - std::abs(z - c));
      });
      const std::vector<float> speed = Uniform(phi, f);
      const VoxelList active = AllVoxels(phi);
      const double dt = MaxStableStep(1.0, dx, 0.5);
      for (int s = 0; s < static_cast<int>(std::lround(total / dt)); ++s) {
        NormalMotionStep(phi, speed, active, dt, dx, MotionSettings{spatial, TemporalScheme::kRk2});
      }
      EXPECT_NEAR(phi.at(1, 2, 20), f * (gap - total), 0.05)
          << "spatial=" << static_cast<int>(spatial) << " F=" << f;
    }
  }
}

TEST(KernelsTest, SphereExpandingAtUnitSpeedGrowsRadiusByElapsedTime) {
  const double dx = 1.0;
  const double r0 = 8.0;
  const double total = 4.0;
  const Int3 dims{40, 40, 40};
  const double cx = 19.6, cy = 20.3, cz = 19.9;
  // The smoothed-volume radius of a curved SDF is biased by O(eps^2 / R); compare like with like.
  const double expected = VolumeRadius(MakeSphere(dims, dx, cx, cy, cz, r0 + total), dx);
  struct Case {
    SpatialScheme spatial;
    TemporalScheme temporal;
    double tolerance;  // Voxels.
  };
  for (const Case& c : {Case{SpatialScheme::kWeno5, TemporalScheme::kRk2, 0.02},
                        Case{SpatialScheme::kWeno5, TemporalScheme::kRk3, 0.02},
                        Case{SpatialScheme::kUpwind, TemporalScheme::kRk1, 0.25}}) {
    DenseField phi = MakeSphere(dims, dx, cx, cy, cz, r0);
    const double dt = MaxStableStep(1.0, dx, 0.5);
    const std::vector<float> speed = Uniform(phi, 1.0f);
    const VoxelList active = AllVoxels(phi);
    const int steps = static_cast<int>(std::lround(total / dt));
    for (int s = 0; s < steps; ++s) {
      NormalMotionStep(phi, speed, active, dt, dx, MotionSettings{c.spatial, c.temporal});
    }
    const double r = VolumeRadius(phi, dx);
    EXPECT_NEAR(r, expected, c.tolerance) << "spatial=" << static_cast<int>(c.spatial)
                                          << " temporal=" << static_cast<int>(c.temporal);
  }
}

TEST(KernelsTest, InactiveVoxelsNeverChange) {
  const double dx = 1.0;
  DenseField phi = MakeSphere(Int3{24, 22, 20}, dx, 11.3, 10.8, 9.7, 6.0, 2.0);
  Lcg rng(42);
  VoxelList active;
  std::vector<bool> is_active(phi.size(), false);
  for (size_t n = 0; n < phi.size(); ++n) {
    if (rng.Next() < 0.5) {
      active.push_back(static_cast<uint32_t>(n));
      is_active[n] = true;
    }
  }
  std::vector<float> speed(phi.size());
  for (float& s : speed) s = static_cast<float>(2.0 * rng.Next() - 1.0);
  const DenseField before = phi;
  for (SpatialScheme spatial :
       {SpatialScheme::kCentral, SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    NormalMotionStep(phi, speed, active, 0.3, dx,
                     MotionSettings{spatial, TemporalScheme::kRk3, Boundary::kClamp});
    Reinitialize(phi, active, 2, dx, MotionSettings{spatial, TemporalScheme::kRk2});
  }
  CurvatureFlowStep(phi, Uniform(phi, 1.0f), active, 0.1, dx);
  size_t changed_active = 0;
  for (size_t n = 0; n < phi.size(); ++n) {
    if (is_active[n]) {
      changed_active += phi.data()[n] != before.data()[n];
    } else {
      ASSERT_EQ(phi.data()[n], before.data()[n]) << "inactive voxel " << n << " changed";
    }
  }
  EXPECT_GT(changed_active, active.size() / 2) << "the active voxels should have moved";
}

TEST(KernelsTest, AdiabaticBorderVoxelsNeverChange) {
  const double dx = 1.0;
  // The sphere crosses the box faces so the border voxels see real gradients.
  DenseField phi = MakeSphere(Int3{20, 18, 16}, dx, 3.0, 9.0, 8.0, 9.0);
  Lcg rng(7);
  std::vector<float> speed(phi.size());
  for (float& s : speed) s = static_cast<float>(2.0 * rng.Next() - 1.0);
  const VoxelList active = AllVoxels(phi);
  const DenseField before = phi;
  for (SpatialScheme spatial :
       {SpatialScheme::kCentral, SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    const MotionSettings settings{spatial, TemporalScheme::kRk3, Boundary::kAdiabatic};
    for (int s = 0; s < 3; ++s) NormalMotionStep(phi, speed, active, 0.4, dx, settings);
    Reinitialize(phi, active, 2, dx, settings);
  }
  const Int3 d = phi.dims();
  size_t changed_interior = 0;
  for (int k = 0; k < d.z; ++k) {
    for (int j = 0; j < d.y; ++j) {
      for (int i = 0; i < d.x; ++i) {
        const bool border =
            i == 0 || j == 0 || k == 0 || i == d.x - 1 || j == d.y - 1 || k == d.z - 1;
        if (border) {
          ASSERT_EQ(phi.at(i, j, k), before.at(i, j, k))
              << "border voxel " << i << "," << j << "," << k << " moved";
        } else {
          changed_interior += phi.at(i, j, k) != before.at(i, j, k);
        }
      }
    }
  }
  EXPECT_GT(changed_interior, 1000u);
}

TEST(KernelsTest, OneVoxelSlabShrinksCircleAsIn2D) {
  const double dx = 1.0;
  const double r0 = 10.0;
  const double total = 3.0;
  for (Boundary boundary : {Boundary::kClamp, Boundary::kAdiabatic}) {
    DenseField phi = MakeSphere(Int3{32, 30, 1}, dx, 15.4, 14.7, 0.0, r0);
    const double dt = MaxStableStep(1.0, dx, 0.5);
    const std::vector<float> speed = Uniform(phi, -1.0f);
    const VoxelList active = AllVoxels(phi);
    const MotionSettings settings{SpatialScheme::kWeno5, TemporalScheme::kRk2, boundary};
    for (int s = 0; s < static_cast<int>(std::lround(total / dt)); ++s) {
      NormalMotionStep(phi, speed, active, dt, dx, settings);
    }
    // A circle under F = -1 shrinks by the elapsed time; a 3D reading (z clamped) would be the
    // same, but an adiabatic z border would freeze every voxel of the slab.
    EXPECT_NEAR(AreaRadius(phi, dx), r0 - total, 0.05) << "boundary=" << static_cast<int>(boundary);
  }
}

TEST(KernelsTest, CurvatureFlowShrinksSphereAtTwoOverRadius) {
  const double dx = 1.0;
  const double r0 = 10.0;
  DenseField phi = MakeSphere(Int3{28, 28, 28}, dx, 14.0, 14.0, 14.0, r0);
  const double dt = 0.9 * dx * dx / 6.0;
  const int steps = 30;
  const std::vector<float> weight = Uniform(phi, 1.0f);
  const VoxelList active = AllVoxels(phi);
  for (int s = 0; s < steps; ++s) CurvatureFlowStep(phi, weight, active, dt, dx);
  // dR/dt = -2/R, so R^2 = R0^2 - 4t (seed 000 eq. 2.8: kappa = 2/R for a sphere).
  const double expected = std::sqrt(r0 * r0 - 4.0 * steps * dt);
  const double r = AxisCrossingRadius(phi, Int3{14, 14, 14}, dx);
  EXPECT_NEAR(r, expected, 0.05 * (r0 - expected));
}

TEST(KernelsTest, CurvatureFlowShrinksCircleInSlabAtOneOverRadius) {
  const double dx = 0.5;
  const double r0 = 5.0;
  DenseField phi = MakeSphere(Int3{28, 28, 1}, dx, 7.0, 7.0, 0.0, r0);
  const double dt = 0.9 * dx * dx / 6.0;
  const int steps = 60;
  const std::vector<float> weight = Uniform(phi, 1.0f);
  const VoxelList active = AllVoxels(phi);
  for (int s = 0; s < steps; ++s) CurvatureFlowStep(phi, weight, active, dt, dx);
  // dR/dt = -1/R in 2D, so R^2 = R0^2 - 2t.
  const double expected = std::sqrt(r0 * r0 - 2.0 * steps * dt);
  const double r = AxisCrossingRadius(phi, Int3{14, 14, 0}, dx);
  EXPECT_NEAR(r, expected, 0.05 * (r0 - expected));
}

TEST(KernelsTest, CurvatureFlowLeavesZeroWeightAndFlatVoxelsUnchanged) {
  const double dx = 1.0;
  DenseField phi = MakeSphere(Int3{16, 16, 16}, dx, 8.0, 8.0, 8.0, 5.0);
  const DenseField before = phi;
  std::vector<float> weight = Uniform(phi, 1.0f);
  const size_t zero_weight = phi.Index(3, 8, 8);
  weight[zero_weight] = 0.0f;
  CurvatureFlowStep(phi, weight, AllVoxels(phi), 0.1, dx);
  EXPECT_EQ(phi.data()[zero_weight], before.data()[zero_weight]);
  // At the exact centre the central gradient vanishes by symmetry.
  EXPECT_EQ(phi.at(8, 8, 8), before.at(8, 8, 8));
  EXPECT_NE(phi.at(3, 9, 8), before.at(3, 9, 8));
}

TEST(KernelsTest, ReinitializeRestoresUnitGradientWithoutMovingSphere) {
  const double dx = 1.0;
  const double r0 = 9.37;
  const Int3 center{20, 20, 20};
  const DenseField exact = MakeSphere(Int3{40, 40, 40}, dx, 20.0, 20.0, 20.0, r0);
  for (SpatialScheme spatial : {SpatialScheme::kUpwind, SpatialScheme::kWeno5}) {
    DenseField phi = MakeSphere(Int3{40, 40, 40}, dx, 20.0, 20.0, 20.0, r0, 3.0);
    const DenseField before = phi;
    const VoxelList active = AllVoxels(phi);
    const double r_before = AxisCrossingRadius(phi, center, dx);
    const EikonalStats steep = MeasureEikonal(phi, active, dx, 9.0 * dx);
    EXPECT_NEAR(steep.mean_abs_error, 2.0, 0.1);
    const int steps =
        Reinitialize(phi, active, 12, dx, MotionSettings{spatial, TemporalScheme::kRk2});
    EXPECT_EQ(steps, 12);
    const EikonalStats after = MeasureEikonal(phi, active, dx, 3.0 * dx);
    EXPECT_LT(after.mean_abs_error, 0.05) << "spatial=" << static_cast<int>(spatial);
    EXPECT_LT(after.max_abs_error, 0.2) << "spatial=" << static_cast<int>(spatial);
    EXPECT_GT(after.samples, 1000u);
    EXPECT_NEAR(AxisCrossingRadius(phi, center, dx), r_before, 0.1)
        << "spatial=" << static_cast<int>(spatial);
    // Once |grad phi| = 1 the smoothed volume sees the whole surface, not just the axes.
    EXPECT_NEAR(VolumeRadius(phi, dx), VolumeRadius(exact, dx), 0.1)
        << "spatial=" << static_cast<int>(spatial);
    // The zero level set stays put, so no voxel changes sign.
    for (size_t n = 0; n < phi.size(); ++n) {
      ASSERT_EQ(phi.data()[n] > 0.0f, before.data()[n] > 0.0f) << "voxel " << n;
    }
  }
}

TEST(KernelsTest, RepeatedReinitializeKeepsExactSphereInPlace) {
  const double dx = 1.0;
  const double r0 = 8.3;
  DenseField phi = MakeSphere(Int3{30, 30, 30}, dx, 15.0, 15.0, 15.0, r0);
  // A narrow band, as the sculpting loop runs it; the rest of the box only feeds the stencils.
  VoxelList active;
  for (size_t n = 0; n < phi.size(); ++n) {
    if (std::abs(phi.data()[n]) < 4.0 * dx) active.push_back(static_cast<uint32_t>(n));
  }
  const double r_axes = AxisCrossingRadius(phi, Int3{15, 15, 15}, dx);
  const double r_volume = VolumeRadius(phi, dx);
  const MotionSettings settings{SpatialScheme::kWeno5, TemporalScheme::kRk2};
  for (int call = 0; call < 50; ++call) Reinitialize(phi, active, 3, dx, settings);
  const double r_axes_after = AxisCrossingRadius(phi, Int3{15, 15, 15}, dx);
  const double r_volume_after = VolumeRadius(phi, dx);
  EXPECT_NEAR(r_axes_after, r_axes, 0.1);
  EXPECT_NEAR(r_volume_after, r_volume, 0.1);
}

TEST(KernelsTest, ReinitializeStepUsesSmoothedSignAndRussoSmerekaDistance) {
  const double dx = 1.0;
  const double cfl = 0.5;
  // phi0 = 3 (z - 20.5): |grad| = 3, the interface between voxels 20 and 21.
  DenseField phi =
      MakeField(Int3{3, 3, 40}, dx, [](double, double, double z) { return 3.0 * (z - 20.5); });
  Reinitialize(phi, AllVoxels(phi), 1, dx,
               MotionSettings{SpatialScheme::kUpwind, TemporalScheme::kRk1}, cfl);
  // Away from the interface, seed 000 eqs. 4.9-4.10: phi -= dt S(phi0) (|grad phi| - 1) with
  // S(phi0) = phi0 / sqrt(phi0^2 + dx^2).
  const double p0 = 4.5;
  EXPECT_NEAR(phi.at(1, 1, 22), p0 - cfl * dx * (p0 / std::sqrt(p0 * p0 + dx * dx)) * 2.0, 1e-5);
  // Next to it, Russo-Smereka: D = dx phi0 / Delta = 0.5 with Delta = 3, and
  // phi -= dt/dx (sgn(phi0)|phi| - D).
  EXPECT_NEAR(phi.at(1, 1, 21), 1.5 - cfl * (1.5 - 0.5), 1e-5);
  EXPECT_NEAR(phi.at(1, 1, 20), -1.5 - cfl * (-1.5 + 0.5), 1e-5);
}

TEST(KernelsTest, ReinitializeKeepsOneVoxelThinSheet) {
  const double dx = 1.0;
  // A sheet one voxel thick at z = 20 with |grad| = 2: the central difference there is 0, so
  // only the one-sided differences across the interface give the distance 0.5 to both faces.
  DenseField phi = MakeField(Int3{3, 3, 40}, dx, [](double, double, double z) {
    return 2.0 * (std::abs(z - 20.0) - 0.5);
  });
  Reinitialize(phi, AllVoxels(phi), 30, dx, MotionSettings{});
  EXPECT_NEAR(phi.at(1, 1, 20), -0.5, 0.01);
  EXPECT_NEAR(phi.at(1, 1, 19), 0.5, 0.01);
  EXPECT_NEAR(phi.at(1, 1, 21), 0.5, 0.01);
  EXPECT_NEAR(phi.at(1, 1, 23), 2.5, 0.01);
}

TEST(KernelsTest, ReinitializeWithZeroIterationsDoesNothing) {
  DenseField phi = MakeSphere(Int3{12, 12, 12}, 1.0, 6.0, 6.0, 6.0, 4.0, 3.0);
  const DenseField before = phi;
  EXPECT_EQ(Reinitialize(phi, AllVoxels(phi), 0, 1.0, MotionSettings{}), 0);
  EXPECT_EQ(phi.data(), before.data());
}

// The edits' reinitialisation (upwind, RK1, a list inside the box) takes a fused path that
// measures, freezes and steps in one pass and steps adjacent voxels in pairs; its figures and
// field must be those of MeasureEikonal and of the clamping path, which Reinitialize takes when
// one voxel of the list lies on the box's border.
TEST(KernelsTest, FusedMeasureAndReinitializeMatchesTheClampingPathBitForBit) {
  const double dx = 0.5;
  const Int3 dims{26, 23, 24};
  // Not a distance: |grad| from about 1 to 2.5, a second blob, ridges between them.
  DenseField field = MakeField(dims, dx, [](double x, double y, double z) {
    const double a =
        std::sqrt((x - 6.1) * (x - 6.1) + (y - 5.7) * (y - 5.7) + (z - 6.3) * (z - 6.3));
    const double b =
        std::sqrt((x - 8.2) * (x - 8.2) + (y - 6.4) * (y - 6.4) + (z - 5.1) * (z - 5.1));
    return std::min(1.7 * (a - 3.2), 1.2 * (b - 1.4)) + 0.3 * std::sin(1.3 * x) * std::cos(0.9 * y);
  });
  VoxelList list;
  for (int k = 2; k < dims.z - 2; ++k) {
    for (int j = 2; j < dims.y - 2; ++j) {
      for (int i = 2; i < dims.x - 2; ++i) {
        if (std::abs(field.at(i, j, k)) < 4.0 * dx) {
          list.push_back(static_cast<uint32_t>(field.Index(i, j, k)));
        }
      }
    }
  }
  ASSERT_GT(list.size(), 2000u);
  // Voxels exactly on the interface, and a repeated entry, take their own branches.
  field.data()[list[list.size() / 3]] = 0.0f;
  field.data()[list[list.size() / 2]] = 0.0f;
  list.push_back(list[100]);
  const double band = 3.0 * dx;
  const MotionSettings upwind_rk1{SpatialScheme::kUpwind, TemporalScheme::kRk1};
  // The corner voxel puts the clamping path's list on the border; no listed voxel reads it.
  VoxelList with_corner = list;
  with_corner.push_back(static_cast<uint32_t>(field.Index(0, 0, 0)));
  DenseField clamped = field;
  const EikonalStats measured = MeasureEikonal(clamped, list, dx, band);
  ASSERT_GT(measured.mean_abs_error, 0.05);
  EXPECT_EQ(Reinitialize(clamped, with_corner, 4, dx, upwind_rk1, 0.5), 4);
  clamped.at(0, 0, 0) = field.at(0, 0, 0);
  ASSERT_NE(clamped.data(), field.data());

  const auto SameBits = [](const DenseField& a, const DenseField& b) {
    return a.size() == b.size() &&
           std::memcmp(a.data().data(), b.data().data(), a.size() * sizeof(float)) == 0;
  };
  DenseField fused = field;
  const MeasuredReinit r =
      MeasureAndReinitialize(fused, list, 4, dx, upwind_rk1, 0.5, ReinitTrigger{band, 0.05, false});
  EXPECT_TRUE(r.triggered);
  EXPECT_EQ(r.passes, 4);
  EXPECT_EQ(r.before.samples, measured.samples);
  EXPECT_EQ(r.before.mean_abs_error, measured.mean_abs_error);
  EXPECT_EQ(r.before.max_abs_error, measured.max_abs_error);
  EXPECT_TRUE(SameBits(fused, clamped));
  DenseField plain = field;
  EXPECT_EQ(Reinitialize(plain, list, 4, dx, upwind_rk1, 0.5), 4);
  EXPECT_TRUE(SameBits(plain, clamped));

  // Below the threshold and not forced: measured, nothing moved.
  DenseField calm = field;
  const MeasuredReinit skipped =
      MeasureAndReinitialize(calm, list, 4, dx, upwind_rk1, 0.5, ReinitTrigger{band, 1e3, false});
  EXPECT_FALSE(skipped.triggered);
  EXPECT_EQ(skipped.passes, 0);
  EXPECT_EQ(skipped.before.mean_abs_error, measured.mean_abs_error);
  EXPECT_EQ(calm.data(), field.data());
  // Forced: reinitialised whatever the error.
  DenseField forced = field;
  EXPECT_TRUE(
      MeasureAndReinitialize(forced, list, 4, dx, upwind_rk1, 0.5, ReinitTrigger{band, 1e3, true})
          .triggered);
  EXPECT_EQ(forced.data(), fused.data());
}

TEST(KernelsTest, MeasureEikonalIsZeroOnSdfAndTwoOnTripledSdf) {
  const double dx = 0.5;
  const VoxelList active = AllVoxels(DenseField(Int3{0, 0, 0}, Int3{40, 40, 40}, 0.0f));
  const DenseField plane = MakeField(Int3{40, 40, 40}, dx, [](double x, double y, double z) {
    return (2.0 * x - y + 2.0 * z) / 3.0 - 15.0;
  });
  const EikonalStats flat = MeasureEikonal(plane, active, dx, 3.0);
  EXPECT_GT(flat.samples, 1000u);
  EXPECT_LT(flat.max_abs_error, 1e-5);

  const DenseField sphere = MakeSphere(Int3{40, 40, 40}, dx, 10.1, 9.8, 10.3, 6.0);
  const EikonalStats exact = MeasureEikonal(sphere, active, dx, 1.5);
  EXPECT_GT(exact.samples, 1000u);
  // First-order one-sided differences of a sphere of 12 voxels: O(dx / R) error, not zero.
  EXPECT_LT(exact.mean_abs_error, 0.04);
  EXPECT_LT(exact.max_abs_error, 0.08);

  const DenseField steep = MakeSphere(Int3{40, 40, 40}, dx, 10.1, 9.8, 10.3, 6.0, 3.0);
  const EikonalStats tripled = MeasureEikonal(steep, active, dx, 4.5);
  EXPECT_EQ(tripled.samples, exact.samples);
  EXPECT_NEAR(tripled.mean_abs_error, 2.0, 0.06);
}

TEST(KernelsTest, MeasureEikonalSkipsBorderKinksAndFarVoxels) {
  const double dx = 1.0;
  // A ridge of phi > 0 at voxel i = 8: the skeleton of the distance to two parallel planes.
  const DenseField vee = MakeField(
      Int3{16, 3, 3}, dx, [](double x, double, double) { return -std::abs(x - 8.0) + 2.0; });
  // Off the border only j = k = 1, i in 1..14 remain; |phi| < 3 keeps i in 4..12; the ridge
  // i = 8 (phi = 2 > 0, both neighbours lower) is a kink and is skipped: 8 samples.
  const EikonalStats stats = MeasureEikonal(vee, AllVoxels(vee), dx, 3.0);
  EXPECT_EQ(stats.samples, 8u);
  EXPECT_LT(stats.max_abs_error, 1e-6);
}

TEST(KernelsTest, SmoothedDeltaIntegratesToOneAndHeavisideIsItsIntegral) {
  const double eps = 1.5 * 0.7;
  // Composite Simpson on [-eps, eps]; the integrand is smooth there, so this is ~exact.
  const int n = 2000;
  const double h = 2.0 * eps / n;
  double integral = SmoothedDelta(-eps, eps) + SmoothedDelta(eps, eps);
  double running = 0.0;
  for (int m = 1; m < n; ++m) {
    integral += (m % 2 == 1 ? 4.0 : 2.0) * SmoothedDelta(-eps + m * h, eps);
  }
  integral *= h / 3.0;
  EXPECT_NEAR(integral, 1.0, 1e-10);
  // Trapezoid running integral against H at every node.
  double max_gap = 0.0;
  for (int m = 1; m <= n; ++m) {
    const double a = -eps + (m - 1) * h;
    const double b = -eps + m * h;
    running += 0.5 * h * (SmoothedDelta(a, eps) + SmoothedDelta(b, eps));
    max_gap = std::max(max_gap, std::abs(running - SmoothedHeaviside(b, eps)));
  }
  EXPECT_LT(max_gap, 1e-5);
  EXPECT_EQ(SmoothedDelta(1.01 * eps, eps), 0.0);
  EXPECT_EQ(SmoothedDelta(-1.01 * eps, eps), 0.0);
  EXPECT_NEAR(SmoothedDelta(0.0, eps), 1.0 / eps, 1e-12);
  EXPECT_EQ(SmoothedHeaviside(-2.0 * eps, eps), 0.0);
  EXPECT_EQ(SmoothedHeaviside(2.0 * eps, eps), 1.0);
  EXPECT_NEAR(SmoothedHeaviside(0.0, eps), 0.5, 1e-15);
  EXPECT_NEAR(SmoothedHeaviside(-eps, eps), 0.0, 1e-15);
  EXPECT_NEAR(SmoothedHeaviside(eps, eps), 1.0, 1e-15);
  EXPECT_NEAR(InsideFraction(-0.3, eps) + InsideFraction(0.3, eps), 1.0, 1e-15);
}

TEST(KernelsTest, SmoothedFunctionsMatchTheLibmFormulaToRounding) {
  // The series replaces libm's sin and cos (a result independent of the libm version); it must
  // agree with them to a few units in the last place across the whole smoothing width.
  const double eps = 1.5;
  double worst_h = 0.0, worst_d = 0.0;
  for (int m = -20000; m <= 20000; ++m) {
    const double phi = eps * m / 20000.0;
    const double t = phi / eps;
    const double h = 0.5 * (1.0 + t + std::sin(std::numbers::pi * t) / std::numbers::pi);
    const double d = (0.5 / eps) * (1.0 + std::cos(std::numbers::pi * t));
    worst_h = std::max(worst_h, std::abs(SmoothedHeaviside(phi, eps) - h));
    worst_d = std::max(worst_d, std::abs(SmoothedDelta(phi, eps) - d));
  }
  EXPECT_LT(worst_h, 1e-15);
  EXPECT_LT(worst_d, 1e-15);
  // H is monotone (the inside fraction never grows with phi) and symmetric about 1/2.
  for (int m = -1000; m < 1000; ++m) {
    const double a = eps * m / 1000.0, b = eps * (m + 1) / 1000.0;
    EXPECT_LE(SmoothedHeaviside(a, eps), SmoothedHeaviside(b, eps));
    EXPECT_NEAR(SmoothedHeaviside(a, eps) + SmoothedHeaviside(-a, eps), 1.0, 1e-15);
  }
}

TEST(KernelsTest, SmoothedFunctionsWithNonPositiveEpsAreSharp) {
  EXPECT_EQ(SmoothedDelta(0.0, 0.0), 0.0);
  EXPECT_EQ(SmoothedHeaviside(-1e-9, 0.0), 0.0);
  EXPECT_EQ(SmoothedHeaviside(1e-9, -1.0), 1.0);
}

TEST(KernelsTest, StepsAreBitIdenticalAcrossRuns) {
  const double dx = 0.5;
  auto run = [&] {
    DenseField phi = MakeSphere(Int3{30, 26, 24}, dx, 7.3, 6.6, 6.1, 4.0, 1.7);
    Lcg rng(99);
    std::vector<float> speed(phi.size());
    for (float& s : speed) s = static_cast<float>(2.0 * rng.Next() - 1.0);
    VoxelList active;
    for (size_t n = 0; n < phi.size(); n += 2) active.push_back(static_cast<uint32_t>(n));
    for (int s = 0; s < 3; ++s) {
      NormalMotionStep(phi, speed, active, 0.2, dx, MotionSettings{});
      Reinitialize(phi, active, 2, dx, MotionSettings{});
      CurvatureFlowStep(phi, Uniform(phi, 0.5f), active, 0.02, dx);
    }
    return phi;
  };
  const DenseField a = run();
  const DenseField b = run();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data().data(), b.data().data(), a.size() * sizeof(float)), 0);
}

TEST(KernelsTest, ActiveListOrderAndDuplicatesDoNotChangeTheResult) {
  const double dx = 1.0;
  DenseField a = MakeSphere(Int3{20, 20, 20}, dx, 9.7, 10.2, 10.1, 6.0);
  DenseField b = a;
  const std::vector<float> speed = Uniform(a, -1.0f);
  VoxelList forward = AllVoxels(a);
  VoxelList shuffled(forward.rbegin(), forward.rend());
  shuffled.insert(shuffled.end(), forward.begin(), forward.begin() + 500);
  NormalMotionStep(a, speed, forward, 0.5, dx, MotionSettings{});
  NormalMotionStep(b, speed, shuffled, 0.5, dx, MotionSettings{});
  EXPECT_EQ(a.data(), b.data());
}

TEST(KernelsTest, MismatchedSpeedOrWeightSizeLeavesPhiUnchanged) {
  DenseField phi = MakeSphere(Int3{10, 10, 10}, 1.0, 5.0, 5.0, 5.0, 3.0);
  const DenseField before = phi;
  const std::vector<float> short_field(phi.size() - 1, 1.0f);
  NormalMotionStep(phi, short_field, AllVoxels(phi), 0.5, 1.0, MotionSettings{});
  CurvatureFlowStep(phi, short_field, AllVoxels(phi), 0.1, 1.0);
  EXPECT_EQ(phi.data(), before.data());
}

TEST(KernelsTest, OutOfRangeActiveIndicesAreIgnored) {
  DenseField phi = MakeSphere(Int3{10, 10, 10}, 1.0, 5.0, 5.0, 5.0, 3.0);
  DenseField reference = phi;
  VoxelList active = AllVoxels(phi);
  const std::vector<float> speed = Uniform(phi, 1.0f);
  NormalMotionStep(reference, speed, active, 0.5, 1.0, MotionSettings{});
  active.push_back(static_cast<uint32_t>(phi.size()));
  active.push_back(0xFFFFFFFFu);
  NormalMotionStep(phi, speed, active, 0.5, 1.0, MotionSettings{});
  EXPECT_EQ(phi.data(), reference.data());
}

TEST(KernelsTest, MaxStableStepIsCflTimesDxOverSpeed) {
  EXPECT_DOUBLE_EQ(MaxStableStep(4.0, 0.5, 0.5), 0.0625);
  EXPECT_DOUBLE_EQ(MaxStableStep(-4.0, 0.5, 0.5), 0.0625) << "a speed's sign does not matter";
  EXPECT_TRUE(std::isinf(MaxStableStep(0.0, 0.5, 0.5)));
}

TEST(KernelsTest, CentralGradientNormIsOneSidedAtBorderAndZeroWhenAdiabatic) {
  const double dx = 0.25;
  // phi = x^2 + 3y: at the x border the one-sided difference sees the quadratic.
  const DenseField phi =
      MakeField(Int3{8, 6, 5}, dx, [](double x, double y, double) { return x * x + 3.0 * y; });
  // Interior: central difference of x^2 is exact, 2x.
  const double x = 3 * dx;
  EXPECT_NEAR(CentralGradientNorm(phi, 3, 2, 2, dx, Boundary::kClamp), std::sqrt(4.0 * x * x + 9.0),
              1e-5);
  EXPECT_NEAR(CentralGradientNorm(phi, 3, 2, 2, dx, Boundary::kAdiabatic),
              std::sqrt(4.0 * x * x + 9.0), 1e-5);
  // Border i = 0: forward difference (dx^2 - 0)/dx = dx.
  EXPECT_NEAR(CentralGradientNorm(phi, 0, 2, 2, dx, Boundary::kClamp), std::sqrt(dx * dx + 9.0),
              1e-5);
  EXPECT_EQ(CentralGradientNorm(phi, 0, 2, 2, dx, Boundary::kAdiabatic), 0.0);
  EXPECT_EQ(CentralGradientNorm(phi, 3, 2, 4, dx, Boundary::kAdiabatic), 0.0);
  EXPECT_EQ(CentralGradientNorm(phi, 8, 2, 2, dx, Boundary::kClamp), 0.0) << "outside the box";
  // A one-voxel slab has no z border: adiabatic leaves its interior voxels alone.
  const DenseField slab =
      MakeField(Int3{6, 6, 1}, dx, [](double x, double y, double) { return 0.6 * x + 0.8 * y; });
  EXPECT_NEAR(CentralGradientNorm(slab, 2, 3, 0, dx, Boundary::kAdiabatic), 1.0, 1e-5);
}

TEST(KernelsTest, CentralRk1AdiabaticIsTheThesisObjdef) {
  const double dx = 0.5;
  DenseField phi = MakeSphere(Int3{14, 12, 10}, dx, 3.2, 2.9, 2.4, 2.0);
  const DenseField before = phi;
  Lcg rng(3);
  std::vector<float> speed(phi.size());
  for (float& s : speed) s = static_cast<float>(3.0 * rng.Next() - 1.5);
  const double dt = 0.05;
  NormalMotionStep(
      phi, speed, AllVoxels(phi), dt, dx,
      MotionSettings{SpatialScheme::kCentral, TemporalScheme::kRk1, Boundary::kAdiabatic});
  // seed 000 §2.9: phi <- phi - dt * F * |grad phi|_central, |grad phi| := 0 on the border.
  const Int3 d = phi.dims();
  for (int k = 0; k < d.z; ++k) {
    for (int j = 0; j < d.y; ++j) {
      for (int i = 0; i < d.x; ++i) {
        const size_t n = phi.Index(i, j, k);
        const double expected =
            before.data()[n] -
            dt * speed[n] * CentralGradientNorm(before, i, j, k, dx, Boundary::kAdiabatic);
        ASSERT_NEAR(phi.data()[n], expected, 1e-6) << i << "," << j << "," << k;
      }
    }
  }
}

// Summed over the voxels of an exact sphere, eq. 5.7's fraction (eps = 1.5 voxels) measures the
// curvature bias VolumeFraction removes: +1.4% at 8 voxels' radius, +0.35% at 16; VolumeFraction
// gives the enclosed volume to 1e-4 at both, wherever the centre falls between samples; and its
// delta is the derivative of the fraction (a central difference) and integrates to one.
TEST(KernelsTest, VolumeFractionSumsToTheEnclosedVolumeOfASphere) {
  const double dx = 1.0;
  for (const double radius : {8.0, 16.0}) {
    for (const double shift : {0.0, 0.25, 0.5}) {
      const int n = static_cast<int>(radius) + 4;
      double thesis = 0, unbiased = 0;
      for (int k = -n; k <= n; ++k) {
        for (int j = -n; j <= n; ++j) {
          for (int i = -n; i <= n; ++i) {
            const double x = i - shift, y = j - 0.5 * shift, z = k;
            const double phi = std::sqrt(x * x + y * y + z * z) - radius;
            thesis += InsideFraction(phi, 1.5 * dx);
            unbiased += VolumeFraction(phi, dx);
          }
        }
      }
      const double exact = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
      SCOPED_TRACE("radius " + std::to_string(radius) + ", shift " + std::to_string(shift));
      EXPECT_NEAR(unbiased / exact, 1.0, 1e-4);
      EXPECT_GT(thesis / exact - 1.0, radius < 10 ? 0.012 : 0.003);
    }
  }
  double integral = 0;
  const double h = 1e-3;
  for (double phi = -2.5; phi <= 2.5; phi += h) {
    EXPECT_NEAR(VolumeDelta(phi, dx),
                (VolumeFraction(phi - 1e-6, dx) - VolumeFraction(phi + 1e-6, dx)) / 2e-6, 1e-4)
        << "phi " << phi;
    integral += VolumeDelta(phi, dx) * h;
  }
  EXPECT_NEAR(integral, 1.0, 1e-3);
  EXPECT_EQ(VolumeFraction(-2.0 * dx, dx), 1.0);
  EXPECT_EQ(VolumeFraction(2.0 * dx, dx), 0.0);
}

}  // namespace
}  // namespace sculpt::levelset
