/// @file edit_operators.cc
/// @brief The operators of the edit kinds, one function each, run on the edit's block: the press
/// (seed 000 eq. 5.1), CSG add and subtract, smoothing by curvature flow, and inflate and deflate
/// as a weighted normal offset.
#include <algorithm>
#include <cmath>
#include <limits>

#include "edit_block.h"
#include "edit_passes.h"
#include "sculpt/levelset/fast_march.h"

namespace sculpt::levelset::internal {
namespace {

// Operators read a request's own field only inside its tool, at its rim (2 voxels, within the
// band's half-width of at least 3) and, for CSG, within the band: a distance beyond the band
// clamps to the same value as +max, so nothing beyond bg of the tool needs evaluating.
double CsgFieldMargin(const Block& b) { return std::max(static_cast<double>(b.bg), 2 * b.dx); }

// The tool's region Gamma: voxels inside the tool.
VoxelList Gamma(const Block& b) {
  return b.SelectNear(0.0, [](size_t, float t) { return t < 0.f; });
}

// Seed 000 eq. 5.1 with the digest's sign: phi_t = v |grad phi| chi_Gamma, i.e. F = -v. Runs
// whole steps of the stroke interval, each in CFL substeps, until no voxel of Gamma holds
// material (the whole region is checked, not only the tool's boundary samples, which left
// islands in the thesis: digest claim 9).
bool Press(Block& b, const EditRequest& req, bool batch, const EditSettings& s, double scale,
           std::vector<float>& speed, EditResult& res) {
  const double dx = b.dx;
  const VoxelList gamma = Gamma(b);
  if (req.speed <= 0 || !GammaHoldsMaterial(b, gamma)) return false;
  speed.assign(b.phi.size(), 0.f);
  for (uint32_t idx : gamma) speed[idx] = static_cast<float>(-req.speed);
  // The press runs until Gamma is empty, so its result does not depend on the speed; a stroke
  // slower than a quarter of a CFL substep per interval is run at that floor, which bounds the
  // work of any request.
  const double step_motion = std::max(req.speed * req.dt, 0.25 * s.cfl * dx);
  const int sub = std::max(1, static_cast<int>(std::ceil(step_motion / (s.cfl * dx) - 1e-9)));
  const double dt_sub = step_motion / (sub * req.speed);
  // The front needs at most the tool's diameter plus the band to leave Gamma.
  const double max_motion = 2 * scale + 2 * b.bg + 2 * dx;
  // (A very slow tool stalls by the test below long before this cap.)
  const int max_steps = static_cast<int>(std::min(1e6, std::ceil(max_motion / step_motion))) + 1;
  bool empty = false;
  std::vector<float> prev;
  prev.reserve(gamma.size());
  for (int step = 0; step < max_steps && !empty; ++step) {
    ++res.steps;
    float max_change = 0;
    for (int i = 0; i < sub; ++i) {
      prev.clear();
      for (uint32_t idx : gamma) prev.push_back(b.phi.data()[idx]);
      NormalMotionStep(b.phi, speed, gamma, dt_sub, dx, s.motion);
      ++res.substeps;
      for (size_t g = 0; g < gamma.size(); ++g) {
        max_change = std::max(max_change, std::abs(b.phi.data()[gamma[g]] - prev[g]));
      }
      if (!GammaHoldsMaterial(b, gamma)) {
        empty = true;
        break;
      }
    }
    if (!empty && max_change < 1e-6f * static_cast<float>(dx)) break;  // stalled
  }
  if (!GammaHoldsMaterial(b, gamma)) {
    // The flow stops at the border of Gamma and leaves the level sets piled up against it
    // (seed 000 §5 item 8): voxels just outside still hold their distance to the old surface.
    // Give them their distance to the new one, the tool's imprint (the thesis's own CSG remedy,
    // §6.2), so the dent sits where the tool was.
    const VoxelList rim =
        b.SelectNear(2 * dx, [&](size_t, float t) { return t >= 0.f && t <= 2 * dx; });
    for (uint32_t idx : rim) b.phi.data()[idx] = std::max(b.phi.data()[idx], -b.tool_sdf[idx]);
    return true;
  }
  // No interface reaches the material left in Gamma (a tool wholly inside the band-clamped
  // interior has zero gradient everywhere): finish with the CSG difference, which is where the
  // flow would have converged.
  res.press_fallback_csg = true;
  if (batch) LoadRequestField(b, req.tool, CsgFieldMargin(b));
  const VoxelList all = b.Select([](size_t, float) { return true; });
  for (uint32_t idx : all) {
    b.phi.data()[idx] = std::max(b.phi.data()[idx], std::min(b.bg, -b.tool_sdf[idx]));
  }
  return true;
}

// Union (add) or difference (subtract) with the tool, its distance clamped to the band.
bool Csg(Block& b, bool add) {
  const VoxelList all = b.Select([](size_t, float) { return true; });
  for (uint32_t idx : all) {
    const float t = std::clamp(b.tool_sdf[idx], -b.bg, b.bg);
    float& v = b.phi.data()[idx];
    v = add ? std::min(v, t) : std::max(v, -t);
  }
  return true;
}

// Mean-curvature flow inside the tool, weighted by a 2-voxel ramp from its surface, for a time
// of `amount` squared voxels.
bool Smooth(Block& b, const EditRequest& req, EditResult& res) {
  const double dx = b.dx;
  std::vector<float> w(b.phi.size(), 0.f);
  const VoxelList region = Gamma(b);
  for (uint32_t idx : region) {
    w[idx] = std::clamp(static_cast<float>(-b.tool_sdf[idx] / (2 * dx)), 0.f, 1.f);
  }
  const double dt = 0.9 * dx * dx / 6.0;
  const int n = std::max(1, static_cast<int>(std::ceil(req.amount * dx * dx / dt - 1e-9)));
  for (int i = 0; i < n && req.amount > 0; ++i) {
    CurvatureFlowStep(b.phi, w, region, dt, dx);
    ++res.substeps;
  }
  return req.amount > 0;
}

// Grows the band of the block's field out to `limit` (world units) by fast marching from the
// voxels inside it, so that an offset by up to limit - background still finds distances where
// the band had clamped them (an inflate or deflate by more than the band's half-width would
// otherwise read a flat +-background and move nothing there). Only voxels off the band within
// two voxels of the tool take part (the offset reads no others) and take their distance; the
// band itself is kept as it is.
void ExtendBand(Block& b, double limit) {
  std::vector<MarchState> state(b.phi.size(), MarchState::kKnown);
  const auto& data = b.phi.data();
  const double near_tool = 2 * b.dx;
  for (size_t idx = 0; idx < data.size(); ++idx) {
    if (std::abs(data[idx]) < b.bg) continue;
    state[idx] = b.tool_sdf[idx] < near_tool ? MarchState::kFree : MarchState::kIgnored;
  }
  MarchDistance(b.phi, state, b.dx, limit);
}

// A normal offset of a signed distance field by a is phi - a (|grad phi| = 1): done in one pass,
// weighted by the tool's 2-voxel ramp, on a field whose band was first grown to reach the offset
// surface. (Moving the front by normal speed instead needed a substep per half voxel and ran
// the interface out of the band beyond the band's half-width.)
bool Offset(Block& b, const EditRequest& req, EditResult& res) {
  if (req.amount <= 0) return false;
  const VoxelList gamma = Gamma(b);
  ExtendBand(b, req.amount + b.bg + b.dx);
  const double sign = req.kind == EditKind::kInflate ? 1.0 : -1.0;
  for (uint32_t idx : gamma) {
    const double w = std::clamp(-b.tool_sdf[idx] / (2 * b.dx), 0.0, 1.0);
    b.phi.data()[idx] = static_cast<float>(b.phi.data()[idx] - sign * req.amount * w);
  }
  ++res.substeps;
  return true;
}

}  // namespace

bool ApplyOperator(Block& b, const EditRequest& req, bool batch, const EditSettings& s,
                   double scale, OperatorScratch& scratch, EditResult& res) {
  // A press reads its own field only inside the tool and at its rim unless it falls back to
  // CSG, which loads the band's width then.
  if (batch)
    LoadRequestField(b, req.tool, req.kind == EditKind::kPress ? 2 * b.dx : CsgFieldMargin(b));
  switch (req.kind) {
    case EditKind::kPress:
      return Press(b, req, batch, s, scale, scratch.speed, res);
    case EditKind::kAdd:
      return Csg(b, true);
    case EditKind::kSubtract:
      return Csg(b, false);
    case EditKind::kSmooth:
      return Smooth(b, req, res);
    case EditKind::kInflate:
    case EditKind::kDeflate:
      return Offset(b, req, res);
  }
  return false;
}

}  // namespace sculpt::levelset::internal
