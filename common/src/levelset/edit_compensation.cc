/// @file edit_compensation.cc
/// @brief Volume compensation (seed 000 ch. 5): the shell around the tool that gives back what
/// a press pushed in, and the thesis's whole-interface region.
#include <algorithm>
#include <cmath>

#include "edit_block.h"
#include "edit_passes.h"

namespace sculpt::levelset::internal {

namespace {

// Weight of the compensation shell: zero inside the tool and a gap of 1.5 voxels around it (so
// the restored volume does not grow back into the tool), one across the shell, zero again at its
// outer edge, with 2-voxel smooth ramps so the bulge has no step.
float ShellWeight(double s, double gap, double outer, double dx) {
  auto smooth = [](double t) {
    t = std::clamp(t, 0.0, 1.0);
    return t * t * (3 - 2 * t);
  };
  if (s <= gap || s >= outer) return 0.f;
  return static_cast<float>(smooth((s - gap) / (2 * dx)) * smooth((outer - s) / (2 * dx)));
}

}  // namespace

CompensationOutcome CompensateShell(Block& b, double target, double base_volume,
                                    double shell_outer, const EditSettings& s, ShellCache& cache) {
  CompensationOutcome out;
  const double dx3 = b.dx * b.dx * b.dx;
  // Every shell voxel moves (offsetting only the band would leave a growing step at its
  // edge), but only band voxels can change their inside fraction by a sub-band offset, so the
  // volume and area sums run over those alone. Weights are kept beside the lists (w[n] for
  // shell[n], band_w[m] for shell_band[m]), not in a block-sized field.
  if (!cache.ready) {
    cache.shell = b.SelectNear(shell_outer,
                               [&](size_t, float t) { return t > 1.5 * b.dx && t < shell_outer; });
    cache.w.resize(cache.shell.size());
    for (size_t n = 0; n < cache.shell.size(); ++n) {
      cache.w[n] = ShellWeight(b.tool_sdf[cache.shell[n]], 1.5 * b.dx, shell_outer, b.dx);
    }
    cache.ready = true;
  }
  const VoxelList& shell = cache.shell;
  const std::vector<float>& w = cache.w;
  // in_band[n]: shell[n] is one of the band voxels the sums run over, which keep their order.
  std::vector<uint8_t> in_band(shell.size());
  for (size_t n = 0; n < shell.size(); ++n) {
    in_band[n] = std::abs(b.phi.data()[shell[n]]) < b.bg;
  }
  const double tol = s.compensation_tolerance_voxels * b.dx * b.dx * b.dx;
  // Only shell voxels change here, so the block's inside sum moves by their change alone. The
  // inside sum and the weighted smoothed area (seed 000 eq. 5.7 delta) of the band voxels, in
  // shell order: computed once here and then by each Newton step while it moves the voxels, so
  // an iteration is one pass over the shell.
  double sum = 0, area = 0;
  auto add_sums = [&](size_t n, float v) {
    sum += VolumeFraction(v, b.dx);
    area += w[n] * VolumeDelta(v, b.dx) * dx3;
  };
  for (size_t n = 0; n < shell.size(); ++n) {
    if (in_band[n]) add_sums(n, b.phi.data()[shell[n]]);
  }
  auto recompute_sums = [&] {
    sum = area = 0;
    for (size_t n = 0; n < shell.size(); ++n) {
      if (in_band[n]) add_sums(n, b.phi.data()[shell[n]]);
    }
  };
  const double change0 = b.InsideChange();
  const double shell_sum0 = sum;
  for (int it = 0; it < s.max_compensation_iterations; ++it) {
    const double vol = base_volume + (change0 - shell_sum0 + sum) * dx3;
    const double err = target - vol;
    if (std::abs(err) <= tol) break;
    if (area < 1e-9 * b.dx * b.dx) {
      out.failed = true;
      break;
    }
    const double d = err / area;  // Newton step along the normal, world units (digest §3.3)
    ++out.iterations;
    switch (s.compensation_method) {
      case CompensationMethod::kNewton: {
        // A normal offset of a signed distance field is phi - d (|grad phi| = 1), weighted by
        // the shell; no stencil, so an iteration costs one pass over the shell. Never move more
        // than the band can represent in one go; the next iteration continues.
        const double limit = 0.5 * b.bg;
        const float step = static_cast<float>(std::clamp(d, -limit, limit));
        sum = area = 0;
        for (size_t n = 0; n < shell.size(); ++n) {
          float& v = b.phi.data()[shell[n]];
          v = std::clamp(v - step * w[n], -b.bg, b.bg);
          if (in_band[n]) add_sums(n, v);
        }
        ++out.substeps;
        continue;  // clamped already, sums up to date
      }
      case CompensationMethod::kGradientDescentGrad: {
        // Eq. 5.8 with the digest's sign: phi += tau (Vol - c) |grad phi| chi; tau scaled so the
        // step is gradient_descent_dt Newton steps (a proportional controller).
        const double step = s.gradient_descent_dt * d;
        std::vector<float> speed(b.phi.size(), 0.f);
        for (size_t n = 0; n < shell.size(); ++n) {
          speed[shell[n]] = static_cast<float>(step * w[n]);
        }
        NormalMotionStep(b.phi, speed, shell, 1.0, b.dx, s.motion);
        ++out.substeps;
        break;
      }
      case CompensationMethod::kGradientDescentDelta: {
        // Eq. 5.6 with the digest's sign: phi += tau (Vol - c) delta_eps(phi) chi.
        const double tau = s.gradient_descent_dt * d * b.eps;
        for (size_t n = 0; n < shell.size(); ++n) {
          float& v = b.phi.data()[shell[n]];
          v = static_cast<float>(v - tau * SmoothedDelta(v, b.eps) * w[n]);
        }
        ++out.substeps;
        break;
      }
    }
    // Only shell voxels moved, and the block was within the band when this began.
    for (uint32_t idx : shell) {
      float& v = b.phi.data()[idx];
      v = std::clamp(v, -b.bg, b.bg);
    }
    recompute_sums();
  }
  return out;
}

void CompensateGlobal(Sculpture& sculpture, const std::vector<EditRequest>& reqs,
                      double reference, const EditSettings& s, EditResult& res) {
  Sculpture::Impl& impl = sculpture.impl();
  auto& grid = *impl.grid;
  const double dx = impl.dx();
  const double dx3 = dx * dx * dx;
  const float bg = impl.background();
  const double gap = 1.5 * dx;
  for (int it = 0; it < s.max_compensation_iterations; ++it) {
    const double err = reference - impl.volume;
    if (std::abs(err) <= s.compensation_tolerance_voxels * dx3) break;
    double area = 0;
    for (auto v = grid.tree().cbeginValueOn(); v; ++v) {
      const openvdb::Vec3d p = grid.indexToWorld(v.getCoord());
      if (UnionDistance(reqs, Vec3{p.x(), p.y(), p.z()}) > gap) {
        area += VolumeDelta(*v, dx) * dx3;
      }
    }
    if (area <= 0) {
      res.compensation_failed = true;
      break;
    }
    // A uniform normal offset of an SDF is phi - d (|grad phi| = 1); the band is not rebuilt (a
    // tracker pass would move the interface again), values are kept within +-background.
    const float d = static_cast<float>(std::clamp(err / area, -0.5 * bg, 0.5 * bg));
    for (auto v = grid.tree().beginValueOn(); v; ++v) {
      const openvdb::Vec3d p = grid.indexToWorld(v.getCoord());
      if (UnionDistance(reqs, Vec3{p.x(), p.y(), p.z()}) > gap) {
        v.setValue(std::clamp(*v - d, -bg, bg));
      }
    }
    impl.volume = sculpture.ComputeVolume();
    ++res.compensation_iterations;
  }
  res.changed = true;
}

}  // namespace sculpt::levelset::internal
