/// @brief Point location in a composite model: bucket grid, subdivision start, Newton.
#include "sculpt/hetero/inverse_map.h"

#include <algorithm>
#include <cmath>

#include "sculpt/hetero/validity.h"

namespace sculpt::hetero {

InverseMap::InverseMap(const CompositeModel& model, InverseMapOptions opt)
    : opt_(opt), materials_(model.materials()) {
  const int n = static_cast<int>(model.cell_count());
  const int s = std::max(opt_.start_subdivisions, 1);
  for (int c = 0; c < n; ++c) {
    patches_.push_back(model.CellPatch(c));
    boxes_.push_back(patches_.back().Bounds());
    std::array<Vec3, 3> frame{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    CanonicalFrame(patches_.back().positions(), &frame);  // a degenerate cell keeps x, y, z
    std::array<std::pair<double, double>, 3> ext;
    for (int a = 0; a < 3; ++a) {
      ext[static_cast<size_t>(a)] = {1e300, -1e300};
      for (const Vec3& p : patches_.back().positions()) {
        const double t = frame[static_cast<size_t>(a)].Dot(p);
        ext[static_cast<size_t>(a)].first = std::min(ext[static_cast<size_t>(a)].first, t);
        ext[static_cast<size_t>(a)].second = std::max(ext[static_cast<size_t>(a)].second, t);
      }
    }
    frames_.push_back(frame);
    extents_.push_back(ext);
    bounds_.Extend(boxes_.back().min);
    bounds_.Extend(boxes_.back().max);
    std::vector<Vec3> st;
    for (int i = 0; i <= s; ++i)
      for (int j = 0; j <= s; ++j)
        for (int k = 0; k <= s; ++k)
          st.push_back(patches_.back().Evaluate(static_cast<double>(i) / s,
                                                static_cast<double>(j) / s,
                                                static_cast<double>(k) / s));
    starts_.push_back(std::move(st));
  }
  if (n == 0) return;
  tol_ = opt_.relative_tolerance * std::max(bounds_.Diagonal(), 1e-300);
  // About one cell per bucket along each axis.
  // About eight buckets per cell: fewer candidates per query.
  const double per_axis = std::max(1.0, 2.0 * std::cbrt(static_cast<double>(n)));
  const Vec3 ext = bounds_.max - bounds_.min;
  const double h = std::max({ext.x, ext.y, ext.z}) / per_axis;
  for (int a = 0; a < 3; ++a) {
    res_[a] = std::clamp(static_cast<int>(std::ceil(ext[a] / std::max(h, 1e-300))), 1, 256);
  }
  cell_size_ = {std::max(ext.x / res_[0], 1e-300), std::max(ext.y / res_[1], 1e-300),
                std::max(ext.z / res_[2], 1e-300)};
  grid_.resize(static_cast<size_t>(res_[0] * res_[1] * res_[2]));
  for (int c = 0; c < n; ++c) {
    const Aabb& b = boxes_[static_cast<size_t>(c)];
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::clamp(static_cast<int>(std::floor((b.min[a] - tol_ - bounds_.min[a]) / cell_size_[a])), 0, res_[a] - 1);
      hi[a] = std::clamp(static_cast<int>(std::floor((b.max[a] + tol_ - bounds_.min[a]) / cell_size_[a])), 0, res_[a] - 1);
    }
    for (int x = lo[0]; x <= hi[0]; ++x)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int z = lo[2]; z <= hi[2]; ++z)
          grid_[static_cast<size_t>((x * res_[1] + y) * res_[2] + z)].push_back(c);
  }
}

std::optional<Location> InverseMap::LocateInCell(int cell, const Vec3& x) const {
  if (!boxes_[static_cast<size_t>(cell)].Contains(x, tol_)) return std::nullopt;
  for (int a = 0; a < 3; ++a) {
    const double t = frames_[static_cast<size_t>(cell)][static_cast<size_t>(a)].Dot(x);
    const auto& e = extents_[static_cast<size_t>(cell)][static_cast<size_t>(a)];
    if (t < e.first - tol_ || t > e.second + tol_) return std::nullopt;
  }
  // Start from the nearest subdivision node.
  const int s = std::max(opt_.start_subdivisions, 1);
  const auto& st = starts_[static_cast<size_t>(cell)];
  size_t best = 0;
  double best_d = 1e300;
  for (size_t i = 0; i < st.size(); ++i) {
    const double d = (st[i] - x).LengthSqr();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  const int bi = static_cast<int>(best) / ((s + 1) * (s + 1));
  const int bj = (static_cast<int>(best) / (s + 1)) % (s + 1);
  const int bk = static_cast<int>(best) % (s + 1);
  return NewtonInCell(cell, x,
                      {static_cast<double>(bi) / s, static_cast<double>(bj) / s,
                       static_cast<double>(bk) / s});
}

std::optional<Location> InverseMap::NewtonInCell(int cell, const Vec3& x, Vec3 start) const {
  const Hyperpatch& h = patches_[static_cast<size_t>(cell)];
  double uvw[3] = {start.x, start.y, start.z};
  bool was_pinned = false;
  for (int it = 0; it < opt_.max_iterations; ++it) {
    const Vec3 r = h.Evaluate(uvw[0], uvw[1], uvw[2]) - x;
    if (r.Length() <= tol_) {
      const double slack = opt_.parameter_slack;
      for (double t : uvw) {
        if (t < -slack || t > 1 + slack) return std::nullopt;
      }
      Location loc;
      loc.cell = cell;
      loc.uvw = {std::clamp(uvw[0], 0.0, 1.0), std::clamp(uvw[1], 0.0, 1.0),
                 std::clamp(uvw[2], 0.0, 1.0)};
      loc.materials = h.Materials(loc.uvw.x, loc.uvw.y, loc.uvw.z);
      loc.iterations = it;
      return loc;
    }
    // Newton step: J Δ = −r, by Cramer's rule on the 3×3 Jacobian columns.
    const auto d = h.Derivatives(uvw[0], uvw[1], uvw[2]);
    const double det = d[0].Dot(d[1].Cross(d[2]));
    if (!(std::abs(det) > 0)) return std::nullopt;
    const Vec3 b = -r;
    const double du = b.Dot(d[1].Cross(d[2])) / det;
    const double dv = d[0].Dot(b.Cross(d[2])) / det;
    const double dw = d[0].Dot(d[1].Cross(b)) / det;
    // Keep iterates near the domain so a far start cannot run off to another sheet.
    uvw[0] = std::clamp(uvw[0] + du, -0.25, 1.25);
    uvw[1] = std::clamp(uvw[1] + dv, -0.25, 1.25);
    uvw[2] = std::clamp(uvw[2] + dw, -0.25, 1.25);
    // Pinned against the clamp twice in a row: the root lies outside this cell.
    const bool pinned = std::abs(std::abs(uvw[0] - 0.5) - 0.75) < 1e-12 ||
                        std::abs(std::abs(uvw[1] - 0.5) - 0.75) < 1e-12 ||
                        std::abs(std::abs(uvw[2] - 0.5) - 0.75) < 1e-12;
    if (pinned && was_pinned) return std::nullopt;
    was_pinned = pinned;
  }
  return std::nullopt;
}

std::optional<Location> InverseMap::Locate(const Vec3& x) const {
  if (!x.IsFinite() || patches_.empty() || !bounds_.Contains(x, tol_)) return std::nullopt;
  int g[3];
  for (int a = 0; a < 3; ++a) {
    g[a] = std::clamp(static_cast<int>(std::floor((x[a] - bounds_.min[a]) / cell_size_[a])), 0,
                      res_[a] - 1);
  }
  for (int c : grid_[static_cast<size_t>((g[0] * res_[1] + g[1]) * res_[2] + g[2])]) {
    if (auto loc = LocateInCell(c, x)) return loc;
  }
  return std::nullopt;
}

std::optional<Location> InverseMap::Locate(const Vec3& x, const Location* hint) const {
  if (hint != nullptr && hint->cell >= 0 && hint->cell < static_cast<int>(patches_.size()) &&
      x.IsFinite() && boxes_[static_cast<size_t>(hint->cell)].Contains(x, tol_)) {
    if (auto loc = NewtonInCell(hint->cell, x, hint->uvw)) {
      const Vec3& t = loc->uvw;
      const double e = 1e-7;
      const bool interior = t.x > e && t.x < 1 - e && t.y > e && t.y < 1 - e && t.z > e &&
                            t.z < 1 - e;
      // Inside a valid model cells overlap only on shared boundaries, so an interior hit is
      // the answer; a boundary hit must go through the lowest-index rule.
      if (interior) return loc;
    }
  }
  return Locate(x);
}

bool InverseMap::MaterialsAt(const Vec3& x, std::span<double> out) const {
  const auto loc = Locate(x);
  if (!loc) return false;
  std::copy(loc->materials.begin(), loc->materials.end(), out.begin());
  return true;
}

}  // namespace sculpt::hetero
