/// @brief SculptureSnapshot: trilinear phi on an owned grid through a per-thread accessor.
#include "sculpt/haptics/sculpture_snapshot.h"

#include <openvdb/openvdb.h>
#include <openvdb/tree/ValueAccessor.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include "levelset/sculpture_grid.h"

namespace sculpt::haptics {
namespace {

using Tree = openvdb::FloatTree;
// Unregistered (IsSafe = false): the tree of a snapshot never changes, so the accessor need not
// be told about topology changes, and constructing one costs no insertion into the tree's
// accessor registry.
using Accessor = openvdb::tree::ValueAccessor<const Tree, /*IsSafe=*/false>;

std::atomic<uint64_t> g_next_id{1};

// The accessor this thread last used, tagged with the id of the snapshot it reads. Ids are
// never reused, so a stale entry (its snapshot freed) is never matched, and it is only
// dereferenced from inside a method of the live snapshot with that id.
struct ThreadAccessor {
  uint64_t id = 0;
  std::optional<Accessor> accessor;
};
thread_local ThreadAccessor t_accessor;
// Initial-exec: the library is loaded with the program (not dlopen'ed), so the counters sit at a
// fixed offset from the thread pointer instead of behind a __tls_get_addr call per lookup.
[[gnu::tls_model("initial-exec")]] thread_local SculptureSnapshot::LookupCounts t_counts;

Accessor& AccessorFor(uint64_t id, const Tree& tree) {
  if (t_accessor.id != id) {
    t_accessor.accessor.emplace(tree);
    t_accessor.id = id;
  }
  return *t_accessor.accessor;
}

// The 8 corners of the cell holding p, and p's fractional position in it.
struct Corners {
  double v[2][2][2];
  openvdb::Coord origin;
  double tx, ty, tz;
};

[[gnu::always_inline]] inline double Interpolate(const double (&v)[2][2][2], double tx, double ty,
                                                 double tz) {
  const double x00 = v[0][0][0] + tx * (v[1][0][0] - v[0][0][0]);
  const double x10 = v[0][1][0] + tx * (v[1][1][0] - v[0][1][0]);
  const double x01 = v[0][0][1] + tx * (v[1][0][1] - v[0][0][1]);
  const double x11 = v[0][1][1] + tx * (v[1][1][1] - v[0][1][1]);
  const double y0 = x00 + ty * (x10 - x00);
  const double y1 = x01 + ty * (x11 - x01);
  return y0 + tz * (y1 - y0);
}

// The cell holding index position u, and u's fractional position in it, without reading values.
Corners Locate(const double (&u)[3]) {
  const double fx = std::floor(u[0]), fy = std::floor(u[1]), fz = std::floor(u[2]);
  Corners c;
  c.tx = u[0] - fx;
  c.ty = u[1] - fy;
  c.tz = u[2] - fz;
  c.origin = openvdb::Coord(static_cast<int>(fx), static_cast<int>(fy), static_cast<int>(fz));
  return c;
}

// `get(coord)` reads one grid value: through the accessor, or from the dense window.
template <typename Get>
void FillCorners(const Get& get, Corners* c) {
  const openvdb::Coord& o = c->origin;
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 2; ++j) {
      for (int i = 0; i < 2; ++i) {
        c->v[i][j][k] = get(o.offsetBy(i, j, k));
      }
    }
  }
}

// Central differences of the trilinear interpolant one voxel either side of p, in index units,
// read as one stencil: p's 8 corners plus the 24 outer corners of the cells one voxel away along
// each axis (32 distinct values and one world-to-index transform, where six separate trilinear
// lookups read 48 values through six transforms). Same value as the six lookups up to rounding,
// so the normal stays continuous across cell faces (the analytic gradient of one cell's
// interpolant does not).
// By linearity, interpolate(hi cell) - interpolate(lo cell) is the interpolation of the corner
// differences: each of p's 8 corners (weight w) adds w (v[+1] - v[-1]) along each axis, so the
// three components share the 8 weights, and each corner's value is read once.
template <typename Get>
openvdb::Vec3d CentralIndexGradient(const Get& get, const Corners& c, const openvdb::Coord& o) {
  const auto& v = c.v;
  const double wx[2] = {1 - c.tx, c.tx}, wy[2] = {1 - c.ty, c.ty}, wz[2] = {1 - c.tz, c.tz};
  double g[3] = {0, 0, 0};
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 2; ++j) {
      const double wjk = wy[j] * wz[k];
      // Along x: the corner on the other side of the cell is v[1 - i], the outer one is read.
      const double x0 = v[1][j][k] - get(o.offsetBy(-1, j, k));
      const double x1 = get(o.offsetBy(2, j, k)) - v[0][j][k];
      g[0] += wjk * (wx[0] * x0 + wx[1] * x1);
    }
  }
  for (int k = 0; k < 2; ++k) {
    for (int i = 0; i < 2; ++i) {
      const double wik = wx[i] * wz[k];
      const double y0 = v[i][1][k] - get(o.offsetBy(i, -1, k));
      const double y1 = get(o.offsetBy(i, 2, k)) - v[i][0][k];
      g[1] += wik * (wy[0] * y0 + wy[1] * y1);
    }
  }
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      const double wij = wx[i] * wy[j];
      const double z0 = v[i][j][1] - get(o.offsetBy(i, j, -1));
      const double z1 = get(o.offsetBy(i, j, 2)) - v[i][j][0];
      g[2] += wij * (wz[0] * z0 + wz[1] * z1);
    }
  }
  return {g[0] / 2, g[1] / 2, g[2] / 2};
}

// The same gradient from p's 8 corners alone, where each corner's central differences were
// worked out when the window was filled: `diff(i, j, k)` points at corner o + (i, j, k)'s
// (v[+1] - v[-1]) along x, y and z. The same sums in the same order as CentralIndexGradient,
// of the same differences, so the same bits.
template <typename Diff>
openvdb::Vec3d CornerIndexGradient(const Diff& diff, const Corners& c) {
  const double wx[2] = {1 - c.tx, c.tx}, wy[2] = {1 - c.ty, c.ty}, wz[2] = {1 - c.tz, c.tz};
  double g[3] = {0, 0, 0};
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 2; ++j) {
      const double wjk = wy[j] * wz[k];
      g[0] += wjk * (wx[0] * diff(0, j, k)[0] + wx[1] * diff(1, j, k)[0]);
    }
  }
  for (int k = 0; k < 2; ++k) {
    for (int i = 0; i < 2; ++i) {
      const double wik = wx[i] * wz[k];
      g[1] += wik * (wy[0] * diff(i, 0, k)[1] + wy[1] * diff(i, 1, k)[1]);
    }
  }
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      const double wij = wx[i] * wy[j];
      g[2] += wij * (wz[0] * diff(i, j, 0)[2] + wz[1] * diff(i, j, 1)[2]);
    }
  }
  return {g[0] / 2, g[1] / 2, g[2] / 2};
}

}  // namespace

SculptureSnapshot::SculptureSnapshot(const levelset::Sculpture& sculpture)
    : SculptureSnapshot(sculpture.Clone()) {}

SculptureSnapshot::SculptureSnapshot(levelset::Sculpture&& sculpture)
    : SculptureSnapshot(std::make_shared<const levelset::Sculpture>(std::move(sculpture))) {}

SculptureSnapshot::SculptureSnapshot(std::shared_ptr<const levelset::Sculpture> sculpture)
    : sculpture_(std::move(sculpture)),
      grid_(&levelset::internal::GridOf(*sculpture_)),
      voxel_size_(sculpture_->voxel_size()),
      id_(g_next_id.fetch_add(1, std::memory_order_relaxed)) {
  const auto& map = *static_cast<const openvdb::FloatGrid*>(grid_)->transform().baseMap();
  // The maps whose applyInverseMap is (p - t) * inv and applyIJT is g * inv (ScaleMap and
  // UniformScaleMap have t = 0, and p - 0 is p).
  openvdb::Vec3d t(0, 0, 0), inv;
  if (const auto* st = dynamic_cast<const openvdb::math::ScaleTranslateMap*>(&map)) {
    t = st->getTranslation();
    inv = st->getInvScale();
    scale_map_ = true;
  } else if (const auto* sc = dynamic_cast<const openvdb::math::ScaleMap*>(&map)) {
    inv = sc->getInvScale();
    scale_map_ = true;
  }
  if (scale_map_) {
    for (int a = 0; a < 3; ++a) {
      translate_[a] = t[a];
      inv_scale_[a] = inv[a];
    }
  }
}

void SculptureSnapshot::ToIndexThroughMap(const Vec3& p, double (&u)[3]) const {
  const auto& grid = *static_cast<const openvdb::FloatGrid*>(grid_);
  const openvdb::Vec3d i = grid.transform().worldToIndex(openvdb::Vec3d(p.x, p.y, p.z));
  u[0] = i.x();
  u[1] = i.y();
  u[2] = i.z();
}

SculptureSnapshot::SculptureSnapshot(std::shared_ptr<const levelset::Sculpture> sculpture,
                                     const Vec3& window_centre, double window_radius,
                                     const SculptureSnapshot* previous)
    : SculptureSnapshot(std::move(sculpture)) {
  if (!window_centre.IsFinite() || !(window_radius > 0) || !std::isfinite(window_radius)) return;
  const auto& grid = *static_cast<const openvdb::FloatGrid*>(grid_);
  const openvdb::Vec3d u =
      grid.transform().worldToIndex(openvdb::Vec3d(window_centre.x, window_centre.y, window_centre.z));
  const double r = std::min(window_radius / voxel_size_, static_cast<double>(kMaxWindowHalf));
  int lo[3], n[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = static_cast<int>(std::floor(u[a] - r));
    n[a] = static_cast<int>(std::ceil(u[a] + r)) - lo[a] + 1;
  }
  window_lo_ = {lo[0], lo[1], lo[2]};
  window_n_ = {n[0], n[1], n[2]};
  window_.resize(static_cast<size_t>(n[0]) * n[1] * n[2]);
  // One accessor walk over the box, x fastest: neighbouring reads share leaf nodes.
  Accessor acc(grid.tree());
  size_t at = 0;
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) {
        window_[at++] = acc.getValue(openvdb::Coord(lo[0] + i, lo[1] + j, lo[2] + k));
      }
    }
  }
  // Each inner node's central differences: the subtraction CentralIndexGradient does, in
  // doubles, of the same two values, so CornerIndexGradient gives its bits. The nodes on the
  // window's faces are never a corner of a stencil InWindow(o, -1, 2) admits and are left
  // unset (not zeroed: the publisher makes one of these per snapshot).
  window_diff_.reset(new double[3 * window_.size()]);
  const ptrdiff_t nx = n[0], nxy = static_cast<ptrdiff_t>(n[0]) * n[1];
  for (int k = 1; k + 1 < n[2]; ++k) {
    for (int j = 1; j + 1 < n[1]; ++j) {
      const ptrdiff_t row = j * nx + k * nxy;
      for (int i = 1; i + 1 < n[0]; ++i) {
        const float* v = &window_[row + i];
        double* d = &window_diff_[3 * (row + i)];
        d[0] = static_cast<double>(v[1]) - static_cast<double>(v[-1]);
        d[1] = static_cast<double>(v[nx]) - static_cast<double>(v[-nx]);
        d[2] = static_cast<double>(v[nxy]) - static_cast<double>(v[-nxy]);
      }
    }
  }
  if (previous == nullptr || previous->window_.empty() || previous->sculpture_ == sculpture_) {
    return;  // nothing to compare (the same sculpture needs no comparison: ChangeSince says 0)
  }
  const auto& prev_grid = *static_cast<const openvdb::FloatGrid*>(previous->grid_);
  // Only an axis-aligned scale (and translation), the same in both, maps the overlap to a
  // world box.
  const auto& map = *grid.transform().baseMap();
  if (!(grid.transform() == prev_grid.transform()) ||
      !(map.isType<openvdb::math::UniformScaleMap>() ||
        map.isType<openvdb::math::UniformScaleTranslateMap>() ||
        map.isType<openvdb::math::ScaleMap>() || map.isType<openvdb::math::ScaleTranslateMap>())) {
    return;
  }
  const int plo[3] = {previous->window_lo_.x, previous->window_lo_.y, previous->window_lo_.z};
  const int pn[3] = {previous->window_n_.x, previous->window_n_.y, previous->window_n_.z};
  int olo[3], ohi[3];  // the overlap, inclusive
  for (int a = 0; a < 3; ++a) {
    olo[a] = std::max(lo[a], plo[a]);
    ohi[a] = std::min(lo[a] + n[a], plo[a] + pn[a]) - 1;
    if (ohi[a] - olo[a] < 1) return;  // no whole cell in common
  }
  float bound = 0;
  for (int k = olo[2]; k <= ohi[2]; ++k) {
    for (int j = olo[1]; j <= ohi[1]; ++j) {
      const float* mine = &window_[(olo[0] - lo[0]) + static_cast<size_t>(j - lo[1]) * n[0] +
                                   static_cast<size_t>(k - lo[2]) * n[0] * n[1]];
      const float* theirs =
          &previous->window_[(olo[0] - plo[0]) + static_cast<size_t>(j - plo[1]) * pn[0] +
                             static_cast<size_t>(k - plo[2]) * pn[0] * pn[1]];
      for (int i = 0; i <= ohi[0] - olo[0]; ++i) {
        bound = std::max(bound, std::abs(mine[i] - theirs[i]));
      }
    }
  }
  // A point's 8 corners lie in the overlap while its index position is in [olo, ohi); a
  // hundredth of a voxel inside that, so the world-to-index round-off cannot cross it.
  const openvdb::Vec3d wlo = grid.transform().indexToWorld(
      openvdb::Vec3d(olo[0] + 0.01, olo[1] + 0.01, olo[2] + 0.01));
  const openvdb::Vec3d whi = grid.transform().indexToWorld(
      openvdb::Vec3d(ohi[0] - 0.01, ohi[1] - 0.01, ohi[2] - 0.01));
  change_base_id_ = previous->id_;
  change_bound_ = bound;
  change_lo_ = {std::min(wlo.x(), whi.x()), std::min(wlo.y(), whi.y()), std::min(wlo.z(), whi.z())};
  change_hi_ = {std::max(wlo.x(), whi.x()), std::max(wlo.y(), whi.y()), std::max(wlo.z(), whi.z())};
}

bool SculptureSnapshot::ChangeSince(const SdfSampler& previous, double* bound, Vec3* lo,
                                    Vec3* hi) const {
  const auto* p = dynamic_cast<const SculptureSnapshot*>(&previous);
  if (p == nullptr) return false;
  if (p->sculpture_ == sculpture_) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    *bound = 0;
    *lo = {-kInf, -kInf, -kInf};
    *hi = {kInf, kInf, kInf};
    return true;
  }
  if (change_base_id_ == 0 || p->id_ != change_base_id_) return false;
  *bound = change_bound_;
  *lo = change_lo_;
  *hi = change_hi_;
  return true;
}

SculptureSnapshot::~SculptureSnapshot() = default;

SculptureSnapshot::LookupCounts SculptureSnapshot::ThreadLookupCounts() { return t_counts; }

namespace {

// Reads the dense window around one cell: `base` is the cell's value, and a coordinate is an
// offset from the cell (the caller checked that every one read lies inside). The offsets of a
// stencil are constants, so each read is one load at a fixed distance from `base`.
struct WindowGet {
  const float* base;
  ptrdiff_t nx, nxy;
  double operator()(const openvdb::Coord& d) const {
    return base[d.x() + d.y() * nx + d.z() * nxy];
  }
};

}  // namespace

double SculptureSnapshot::Phi(const Vec3& p) const {
  double u[3];
  ToIndex(p, u);
  Corners c = Locate(u);
  const int o[3] = {c.origin.x(), c.origin.y(), c.origin.z()};
  if (InWindow(o, 0, 1)) {
    c.origin = openvdb::Coord(0, 0, 0);  // offsets from WindowAt(o)
    FillCorners(
        WindowGet{WindowAt(o), window_n_.x, static_cast<ptrdiff_t>(window_n_.x) * window_n_.y}, &c);
    ++t_counts.window_phi;
  } else {
    const auto& grid = *static_cast<const openvdb::FloatGrid*>(grid_);
    Accessor& acc = AccessorFor(id_, grid.tree());
    FillCorners([&acc](const openvdb::Coord& ijk) { return acc.getValue(ijk); }, &c);
    ++t_counts.tree_phi;
  }
  return Interpolate(c.v, c.tx, c.ty, c.tz);
}

void SculptureSnapshot::PhiAndGradient(const Vec3& p, double* phi, Vec3* gradient) const {
  const auto& grid = *static_cast<const openvdb::FloatGrid*>(grid_);
  double u[3];
  ToIndex(p, u);
  Corners c = Locate(u);
  const int o[3] = {c.origin.x(), c.origin.y(), c.origin.z()};
  openvdb::Vec3d gi;
  if (InWindow(o, -1, 2)) {
    const ptrdiff_t nx = window_n_.x, nxy = nx * window_n_.y;
    const float* base = WindowAt(o);
    c.origin = openvdb::Coord(0, 0, 0);
    FillCorners(WindowGet{base, nx, nxy}, &c);
    // The corners' differences were worked out with the window: 8 reads, not 24 more values.
    const double* diff = window_diff_.get() + 3 * (base - window_.data());
    gi = CornerIndexGradient(
        [diff, nx, nxy](int i, int j, int k) { return diff + 3 * (i + j * nx + k * nxy); }, c);
    ++t_counts.window_stencil;
  } else {
    Accessor& acc = AccessorFor(id_, grid.tree());
    const auto get = [&acc](const openvdb::Coord& ijk) { return acc.getValue(ijk); };
    FillCorners(get, &c);
    gi = CentralIndexGradient(get, c, c.origin);
    ++t_counts.tree_stencil;
  }
  *phi = Interpolate(c.v, c.tx, c.ty, c.tz);
  // World gradient: the index gradient through the inverse transpose of the index-to-world map
  // (for the uniform scale of a level set, divided by the voxel size).
  if (scale_map_) {
    *gradient = {gi.x() * inv_scale_[0], gi.y() * inv_scale_[1], gi.z() * inv_scale_[2]};
    return;
  }
  const openvdb::Vec3d gw = grid.transform().baseMap()->applyIJT(gi);
  *gradient = {gw.x(), gw.y(), gw.z()};
}

Vec3 SculptureSnapshot::Gradient(const Vec3& p) const {
  double phi;
  Vec3 g;
  PhiAndGradient(p, &phi, &g);
  return g;
}

}  // namespace sculpt::haptics
