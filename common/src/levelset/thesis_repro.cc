/// @brief The thesis's 2D carve and volume-compensation experiments (seed 000 §3.2, §3.3, App. A)
/// run through the production finite-difference kernels.
#include "sculpt/levelset/thesis_repro.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>

namespace sculpt::levelset::thesis {
namespace {

bool FieldIsBounded(const DenseField& phi, double bound) {
  for (float v : phi.data()) {
    if (!std::isfinite(v) || std::fabs(v) > bound) return false;
  }
  return true;
}

int Sign(double v) { return v > 0 ? 1 : (v < 0 ? -1 : 0); }

double ReinitCfl(const DenseField& phi, double h, double fixed_cfl) {
  return fixed_cfl > 0 ? fixed_cfl : ReinitSdCfl(phi, h, kReinitAlpha);
}

}  // namespace

DenseField GridSpec::MakeField(float fill) const {
  return DenseField(Int3{0, 0, 0}, Int3{nodes(), nodes(), 1}, fill);
}

double ShapeSignedDistance(const Shape2D& shape, double x, double y) {
  const double dx = x - shape.center.x;
  const double dy = y - shape.center.y;
  if (shape.kind == ShapeKind::kCircle) return std::sqrt(dx * dx + dy * dy) - shape.half_x;
  // App. A.1 'REC': inside the box or on one of its axis bands the distance is the larger axis
  // distance; in the corner regions it is the distance to the corner.
  const double qx = std::fabs(dx) - shape.half_x;
  const double qy = std::fabs(dy) - shape.half_y;
  if (qx <= 0 || qy <= 0) return std::max(qx, qy);
  return std::sqrt(qx * qx + qy * qy);
}

DenseField MaterialField(const Shape2D& material, const GridSpec& grid) {
  DenseField phi = grid.MakeField(0.0f);
  const double h = grid.h();
  for (int j = 0; j < grid.nodes(); ++j) {
    for (int i = 0; i < grid.nodes(); ++i) {
      phi.at(i, j, 0) = static_cast<float>(ShapeSignedDistance(material, i * h, j * h));
    }
  }
  return phi;
}

std::vector<uint8_t> ToolMask(const Shape2D& tool, const GridSpec& grid) {
  const int n = grid.nodes();
  const double h = grid.h();
  std::vector<uint8_t> mask(static_cast<size_t>(n) * n, 0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double dx = i * h - tool.center.x;
      const double dy = j * h - tool.center.y;
      bool in = false;
      if (tool.kind == ShapeKind::kCircle) {
        in = dx * dx + dy * dy <= tool.half_x * tool.half_x;
      } else {
        in = std::fabs(dx) <= tool.half_x && std::fabs(dy) <= tool.half_y;
      }
      mask[static_cast<size_t>(j) * n + i] = in ? 1 : 0;
    }
  }
  return mask;
}

std::vector<Point2> ToolSamples(const Shape2D& tool, int k) {
  std::vector<Point2> pts;
  const double cx = tool.center.x;
  const double cy = tool.center.y;
  if (tool.kind == ShapeKind::kCircle) {
    pts.reserve(static_cast<size_t>(k) + 1);
    for (int i = 0; i <= k; ++i) {
      const double a = 2.0 * std::numbers::pi * i / k;
      pts.push_back({tool.half_x * std::cos(a) + cx, tool.half_x * std::sin(a) + cy});
    }
    return pts;
  }
  const int k1 = (k + 3) / 4;
  const double a = tool.half_x;
  const double b = tool.half_y;
  pts.reserve(4 * static_cast<size_t>(k1));
  for (int t = 0; t < k1; ++t) pts.push_back({cx - a + 2.0 * t * a / k1, cy + b});
  for (int t = 0; t < k1; ++t) pts.push_back({cx + a, cy + b - 2.0 * t * b / k1});
  for (int t = 0; t < k1; ++t) pts.push_back({cx + a - 2.0 * t * a / k1, cy - b});
  for (int t = 0; t < k1; ++t) pts.push_back({cx - a, cy - b + 2.0 * t * b / k1});
  return pts;
}

double Bilinear(const DenseField& phi, const GridSpec& grid, double x, double y) {
  const double h = grid.h();
  const int last = grid.intervals - 1;
  x = std::clamp(x, 0.0, grid.length);
  y = std::clamp(y, 0.0, grid.length);
  const int i = std::clamp(static_cast<int>(std::floor(x / h)), 0, last);
  const int j = std::clamp(static_cast<int>(std::floor(y / h)), 0, last);
  const double x0 = i * h;
  const double y0 = j * h;
  const double x1 = x0 + h;
  const double y1 = y0 + h;
  // Eq. (3.1), as written in `detcol`.
  return (phi.at(i, j, 0) * (x1 - x) * (y1 - y) + phi.at(i + 1, j, 0) * (x - x0) * (y1 - y) +
          phi.at(i, j + 1, 0) * (x1 - x) * (y - y0) +
          phi.at(i + 1, j + 1, 0) * (x - x0) * (y - y0)) /
         (h * h);
}

int CountCollidingSamples(const DenseField& phi, const GridSpec& grid,
                          const std::vector<Point2>& samples) {
  int count = 0;
  for (const Point2& p : samples) {
    if (Bilinear(phi, grid, p.x, p.y) <= 0.0) ++count;
  }
  return count;
}

double PointwiseArea(const DenseField& phi, double h) {
  size_t count = 0;
  for (float v : phi.data()) {
    if (v <= 0.0f) ++count;
  }
  return static_cast<double>(count) * h * h;
}

double PointwiseAreaOutside(const DenseField& phi, const std::vector<uint8_t>& mask, double h) {
  size_t count = 0;
  const std::vector<float>& d = phi.data();
  for (size_t n = 0; n < d.size(); ++n) {
    if (d[n] <= 0.0f && mask[n] == 0) ++count;
  }
  return static_cast<double>(count) * h * h;
}

double PointwiseAreaInside(const DenseField& phi, const std::vector<uint8_t>& mask, double h) {
  size_t count = 0;
  const std::vector<float>& d = phi.data();
  for (size_t n = 0; n < d.size(); ++n) {
    if (d[n] <= 0.0f && mask[n] != 0) ++count;
  }
  return static_cast<double>(count) * h * h;
}

double IslandAreaInside(const DenseField& phi, const std::vector<uint8_t>& mask, double h) {
  const Int3 d = phi.dims();
  const std::vector<float>& v = phi.data();
  std::vector<uint8_t> seen(v.size(), 0);
  std::vector<size_t> stack;
  std::vector<size_t> component;
  size_t island_nodes = 0;
  for (size_t start = 0; start < v.size(); ++start) {
    if (seen[start] || v[start] > 0.0f) continue;
    // Flood fill one 4-connected component of {phi <= 0} in the slab.
    bool touches_outside = false;
    component.clear();
    stack.assign(1, start);
    seen[start] = 1;
    while (!stack.empty()) {
      const size_t n = stack.back();
      stack.pop_back();
      component.push_back(n);
      if (mask[n] == 0) touches_outside = true;
      const int i = static_cast<int>(n % d.x);
      const int j = static_cast<int>(n / d.x);
      const int ni[4] = {i - 1, i + 1, i, i};
      const int nj[4] = {j, j, j - 1, j + 1};
      for (int q = 0; q < 4; ++q) {
        if (ni[q] < 0 || nj[q] < 0 || ni[q] >= d.x || nj[q] >= d.y) continue;
        const size_t m = phi.Index(ni[q], nj[q], 0);
        if (seen[m] || v[m] > 0.0f) continue;
        seen[m] = 1;
        stack.push_back(m);
      }
    }
    if (!touches_outside) island_nodes += component.size();
  }
  return static_cast<double>(island_nodes) * h * h;
}

VoxelList MaskVoxels(const std::vector<uint8_t>& mask, bool want) {
  VoxelList list;
  for (size_t n = 0; n < mask.size(); ++n) {
    if ((mask[n] != 0) == want) list.push_back(static_cast<uint32_t>(n));
  }
  return list;
}

MotionSettings ReinitSettings() {
  return MotionSettings{SpatialScheme::kWeno5, TemporalScheme::kRk1, Boundary::kClamp};
}

double ReinitSdCfl(const DenseField& phi, double h, double alpha) {
  const Int3 d = phi.dims();
  double max_rate = 0.0;
  for (int j = 0; j < d.y; ++j) {
    for (int i = 0; i < d.x; ++i) {
      const double c = phi.at(i, j, 0);
      const double s = c / std::sqrt(c * c + h * h);
      double grad_sq = 0.0;
      for (int axis = 0; axis < 2; ++axis) {
        const int n = axis == 0 ? d.x : d.y;
        const int at = axis == 0 ? i : j;
        if (n < 3) continue;
        auto value = [&](int o) {
          return static_cast<double>(axis == 0 ? phi.at(i + o, j, 0) : phi.at(i, j + o, 0));
        };
        // Ghost nodes beyond the border are linear extrapolations (`der_ENO1_minus/plus`), so
        // the missing one-sided difference equals the other one.
        double dm = at > 0 ? (c - value(-1)) / h : (value(1) - c) / h;
        double dp = at < n - 1 ? (value(1) - c) / h : (c - value(-1)) / h;
        // `select_der_normal` with Vn = S(phi0).
        const double vm = s * dm;
        const double vp = s * dp;
        double der = 0.0;
        if (vm <= 0 && vp <= 0) {
          der = dp;
        } else if (vm >= 0 && vp >= 0) {
          der = dm;
        } else if (vm <= 0 && vp >= 0) {
          der = 0.0;
        } else {
          der = std::fabs(vp) >= std::fabs(vm) ? dp : dm;
        }
        grad_sq += der * der;
      }
      max_rate = std::max(max_rate, std::fabs(s) * std::sqrt(grad_sq));
    }
  }
  return max_rate > 0.0 ? alpha / max_rate : alpha;
}

CarveResult RunLocalCarve(const CarveSetup& setup) {
  const GridSpec& grid = setup.grid;
  const double h = grid.h();
  CarveResult result;
  result.phi = MaterialField(setup.material, grid);
  const std::vector<uint8_t> gamma = ToolMask(setup.tool, grid);
  const VoxelList gamma_voxels = MaskVoxels(gamma, true);
  const VoxelList all_voxels = MaskVoxels(std::vector<uint8_t>(gamma.size(), 1), true);
  const std::vector<Point2> samples = ToolSamples(setup.tool, setup.samples);
  // F = -v on Gamma: phi_t - v |grad phi| = 0, i.e. phi <- phi + dt v |grad phi| (eq. 5.1 with
  // the code's sign, seed 000 §9 erratum 3).
  std::vector<float> speed(gamma.size(), 0.0f);
  for (uint32_t n : gamma_voxels) speed[n] = static_cast<float>(-setup.speed);

  result.initial_area = PointwiseArea(result.phi, h);
  int colliding = 0;
  int pass = 0;
  while (pass < setup.max_passes) {
    ++pass;
    // `objdef`, accion = 1: detect on the current field, step only while something collides.
    colliding = CountCollidingSamples(result.phi, grid, samples);
    if (colliding > 0) {
      NormalMotionStep(result.phi, speed, gamma_voxels, setup.dt, h, setup.motion);
      ++result.updates;
    }
    if (setup.reinit_every > 0 && pass % setup.reinit_every == 0) {
      Reinitialize(result.phi, all_voxels, 1, h, ReinitSettings(),
                   ReinitCfl(result.phi, h, setup.reinit_fixed_cfl));
      ++result.reinits;
    }
    if (colliding == 0) break;
  }
  result.thesis_iterations = pass;
  result.hit_pass_limit = colliding > 0;
  result.final_area = PointwiseArea(result.phi, h);
  result.area_removed = result.initial_area - result.final_area;
  result.area_stranded = PointwiseAreaInside(result.phi, gamma, h);
  result.island_area = IslandAreaInside(result.phi, gamma, h);
  result.tool_region_cleared = result.area_stranded == 0.0;
  return result;
}

CompensationResult RunCompensation(const CompensationSetup& setup) {
  const GridSpec& grid = setup.grid;
  const double h = grid.h();
  const double eps = setup.eps_factor * h;
  CompensationResult result;
  result.phi = MaterialField(setup.material, grid);
  const std::vector<uint8_t> gamma = ToolMask(setup.tool, grid);
  const VoxelList outside_voxels = MaskVoxels(gamma, false);
  const VoxelList all_voxels = MaskVoxels(std::vector<uint8_t>(gamma.size(), 1), true);

  // Alg. 2 step 1: c = Vol(phi), the pointwise total, once per call.
  result.initial_area = PointwiseArea(result.phi, h);
  const double blowup = setup.blowup_abs_dif > 0 ? setup.blowup_abs_dif : result.initial_area;
  const double field_bound = 1e6 * grid.length;
  std::vector<float> speed(gamma.size(), 0.0f);

  for (int pass = 1; pass <= setup.max_passes; ++pass) {
    const double dif = PointwiseAreaOutside(result.phi, gamma, h) - result.initial_area;
    result.dif_history.push_back(dif);
    if (!FieldIsBounded(result.phi, field_bound) || std::fabs(dif) > blowup) {
      result.diverged = true;
      break;
    }
    if (dif != 0.0) {
      if (setup.form == CompensationForm::kDelta) {
        // phi <- phi + dt dif delta_eps(phi) chi_{Gamma^c} (`dlcon`, code sign).
        for (uint32_t n : outside_voxels) {
          float& v = result.phi.data()[n];
          v = static_cast<float>(v + setup.dt * dif * SmoothedDelta(v, eps));
        }
      } else {
        // phi <- phi + dt dif |grad phi| chi_{Gamma^c}: normal speed F = -dif.
        for (uint32_t n : outside_voxels) speed[n] = static_cast<float>(-dif);
        NormalMotionStep(result.phi, speed, outside_voxels, setup.dt, h, setup.motion);
      }
      ++result.updates;
    }
    if (setup.reinit_every > 0 && pass % setup.reinit_every == 0) {
      Reinitialize(result.phi, all_voxels, 1, h, ReinitSettings(),
                   ReinitCfl(result.phi, h, setup.reinit_fixed_cfl));
      ++result.reinits;
    }
    if (dif == 0.0) {
      result.converged = true;
      break;
    }
  }

  result.passes = static_cast<int>(result.dif_history.size());
  result.final_dif = result.dif_history.empty() ? 0.0 : result.dif_history.back();
  result.final_abs_dif = std::fabs(result.final_dif);
  const size_t window = static_cast<size_t>(std::max(setup.tail_window, 1));
  const size_t first = result.dif_history.size() > window ? result.dif_history.size() - window : 0;
  for (size_t n = first; n < result.dif_history.size(); ++n) {
    result.tail_abs_dif.push_back(std::fabs(result.dif_history[n]));
  }
  if (!result.diverged && result.tail_abs_dif.size() == window) {
    result.stalled = result.tail_abs_dif.front() != 0.0 &&
                     std::all_of(result.tail_abs_dif.begin(), result.tail_abs_dif.end(),
                                 [&](double v) { return v == result.tail_abs_dif.front(); });
    int sign_changes = 0;
    for (size_t n = first + 1; n < result.dif_history.size(); ++n) {
      const int a = Sign(result.dif_history[n - 1]);
      const int b = Sign(result.dif_history[n]);
      if (a != 0 && b != 0 && a != b) ++sign_changes;
    }
    result.oscillating = sign_changes >= 2;
  }
  return result;
}

}  // namespace sculpt::levelset::thesis
