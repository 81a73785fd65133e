/// @brief Sweeps of a closed planar outline into a sculpture as a CSG add or subtract edit.
#include "sculpt/levelset/sweep.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "sculpt/core/check.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

constexpr double kUnitTolerance = 1e-6;

std::string Point3(const Vec3& p) {
  return "(" + FormatNumber(p.x) + ", " + FormatNumber(p.y) + ", " + FormatNumber(p.z) + ")";
}

// Distance from p to the segment ab.
double SegmentDistance(const PlanePoint& p, const PlanePoint& a, const PlanePoint& b) {
  const double ex = b.x - a.x, ey = b.y - a.y;
  const double wx = p.x - a.x, wy = p.y - a.y;
  const double ll = ex * ex + ey * ey;
  const double t = ll > 0 ? std::clamp((wx * ex + wy * ey) / ll, 0.0, 1.0) : 0.0;
  const double dx = wx - t * ex, dy = wy - t * ey;
  return std::sqrt(dx * dx + dy * dy);
}

// The world box the swept solid occupies (without the band).
Aabb SolidBounds(const SweepRequest& r) {
  const SweepPlane& pl = r.plane;
  Aabb b{{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
          std::numeric_limits<double>::max()},
         {std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest(),
          std::numeric_limits<double>::lowest()}};
  auto grow = [&b](const Vec3& p) {
    b.min = {std::min(b.min.x, p.x), std::min(b.min.y, p.y), std::min(b.min.z, p.z)};
    b.max = {std::max(b.max.x, p.x), std::max(b.max.y, p.y), std::max(b.max.z, p.z)};
  };
  if (r.mode == SweepRequest::Mode::kExtrude) {
    const Vec3 n = pl.u.Cross(pl.v) * r.depth;
    for (const PlanePoint& p : r.outline) {
      grow(pl.At(p));
      grow(pl.At(p) + n);
    }
    return b;
  }
  // Revolve: the cylinder around the axis that holds the outline.
  const PlanePoint d = r.axis_dir;
  double amin = std::numeric_limits<double>::max(), amax = std::numeric_limits<double>::lowest();
  double rad = 0;
  for (const PlanePoint& p : r.outline) {
    const double wx = p.x - r.axis_point.x, wy = p.y - r.axis_point.y;
    const double a = wx * d.x + wy * d.y;
    amin = std::min(amin, a);
    amax = std::max(amax, a);
    rad = std::max(rad, std::abs(wx * d.y - wy * d.x));
  }
  const Vec3 axis = pl.u * d.x + pl.v * d.y;
  const Vec3 a0 = pl.At(r.axis_point) + axis * amin;
  const Vec3 a1 = pl.At(r.axis_point) + axis * amax;
  const Vec3 ext{rad * std::sqrt(std::max(0.0, 1 - axis.x * axis.x)),
                 rad * std::sqrt(std::max(0.0, 1 - axis.y * axis.y)),
                 rad * std::sqrt(std::max(0.0, 1 - axis.z * axis.z))};
  grow(a0 - ext);
  grow(a0 + ext);
  grow(a1 - ext);
  grow(a1 + ext);
  return b;
}

internal::IndexBox SweepBox(const Sculpture::Impl& impl, const SweepRequest& r) {
  const double bg = impl.background();
  const Aabb s = SolidBounds(r);
  const Vec3 pad{bg, bg, bg};
  return internal::WorldToIndexBox(s.min - pad, s.max + pad, impl.dx(), 1);
}

// The outline's 2D signed distance on a raster, |d| exact up to `cap` and `cap` beyond it.
// Inside by even-odd scanlines (one pass over the edges per row); the distance only to the
// segments a bucket of side `cap` lists, so the cost follows the outline's length, not
// pixels x segments.
class OutlineRaster {
 public:
  OutlineRaster(const std::vector<PlanePoint>& poly, double h, double cap) : h_(h), cap_(cap) {
    double x0 = std::numeric_limits<double>::max(), y0 = x0;
    double x1 = std::numeric_limits<double>::lowest(), y1 = x1;
    for (const PlanePoint& p : poly) {
      x0 = std::min(x0, p.x);
      y0 = std::min(y0, p.y);
      x1 = std::max(x1, p.x);
      y1 = std::max(y1, p.y);
    }
    const double m = cap + 2 * h;
    ox_ = x0 - m;
    oy_ = y0 - m;
    nx_ = static_cast<int>(std::ceil((x1 - x0 + 2 * m) / h)) + 1;
    ny_ = static_cast<int>(std::ceil((y1 - y0 + 2 * m) / h)) + 1;
    d_.assign(static_cast<size_t>(nx_) * ny_, static_cast<float>(cap));
    const size_t n = poly.size();
    // Buckets of segments near each cell.
    const double cell = std::max(cap, 4 * h);
    bx_ = static_cast<int>(std::ceil(nx_ * h / cell)) + 1;
    by_ = static_cast<int>(std::ceil(ny_ * h / cell)) + 1;
    std::vector<std::vector<uint32_t>> buckets(static_cast<size_t>(bx_) * by_);
    for (size_t i = 0; i < n; ++i) {
      const PlanePoint& a = poly[i];
      const PlanePoint& b = poly[(i + 1) % n];
      const int i0 = std::max(0, static_cast<int>((std::min(a.x, b.x) - cap - ox_) / cell));
      const int i1 = std::min(bx_ - 1, static_cast<int>((std::max(a.x, b.x) + cap - ox_) / cell));
      const int j0 = std::max(0, static_cast<int>((std::min(a.y, b.y) - cap - oy_) / cell));
      const int j1 = std::min(by_ - 1, static_cast<int>((std::max(a.y, b.y) + cap - oy_) / cell));
      for (int j = j0; j <= j1; ++j) {
        for (int k = i0; k <= i1; ++k) buckets[static_cast<size_t>(j) * bx_ + k].push_back(i);
      }
    }
    std::vector<double> xs;
    for (int j = 0; j < ny_; ++j) {
      const double y = oy_ + j * h;
      xs.clear();
      for (size_t i = 0; i < n; ++i) {
        const PlanePoint& a = poly[i];
        const PlanePoint& b = poly[(i + 1) % n];
        if ((a.y > y) != (b.y > y)) xs.push_back(a.x + (y - a.y) / (b.y - a.y) * (b.x - a.x));
      }
      std::sort(xs.begin(), xs.end());
      size_t next = 0;
      bool inside = false;
      for (int i = 0; i < nx_; ++i) {
        const double x = ox_ + i * h;
        while (next < xs.size() && xs[next] <= x) {
          inside = !inside;
          ++next;
        }
        const int bi = std::min(bx_ - 1, static_cast<int>((x - ox_) / cell));
        const int bj = std::min(by_ - 1, static_cast<int>((y - oy_) / cell));
        double best = cap;
        for (uint32_t s : buckets[static_cast<size_t>(bj) * bx_ + bi]) {
          best = std::min(best, SegmentDistance({x, y}, poly[s], poly[(s + 1) % n]));
        }
        d_[static_cast<size_t>(j) * nx_ + i] = static_cast<float>(inside ? -best : best);
      }
    }
  }

  // Bilinear in the raster; `cap` (outside) beyond it, where every point is at least cap away.
  double Sample(double x, double y) const {
    const double fx = (x - ox_) / h_, fy = (y - oy_) / h_;
    if (!(fx >= 0 && fy >= 0 && fx < nx_ - 1 && fy < ny_ - 1)) return cap_;
    const int i = static_cast<int>(fx), j = static_cast<int>(fy);
    const double tx = fx - i, ty = fy - j;
    const float* r0 = &d_[static_cast<size_t>(j) * nx_ + i];
    const float* r1 = r0 + nx_;
    return (1 - ty) * ((1 - tx) * r0[0] + tx * r0[1]) + ty * ((1 - tx) * r1[0] + tx * r1[1]);
  }

 private:
  double h_, cap_;
  double ox_ = 0, oy_ = 0;
  int nx_ = 0, ny_ = 0, bx_ = 0, by_ = 0;
  std::vector<float> d_;
};

}  // namespace

Status ValidatePlane(const std::string& field, const SweepPlane& pl) {
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint(field + ".origin", pl.origin));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint(field + ".u", pl.u));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint(field + ".v", pl.v));
  for (const auto& [name, a] : {std::pair<const char*, Vec3>{"u", pl.u}, {"v", pl.v}}) {
    const double l = a.Length();
    if (std::abs(l - 1) > kUnitTolerance) {
      return Outside(
          field + "." + name, Point3(a),
          std::string("unit vectors (length ") + FormatNumber(l) + ", within 1e-6 of 1)");
    }
  }
  const double d = pl.u.Dot(pl.v);
  if (std::abs(d) > kUnitTolerance) {
    return Outside(
        field + ".v", Point3(pl.v),
        std::string("vectors orthogonal to u (u.v=") + FormatNumber(d) + ", |u.v| <= 1e-6)");
  }
  return Status::Ok();
}

double PolygonSignedDistance(const std::vector<PlanePoint>& poly, const PlanePoint& p) {
  const size_t n = poly.size();
  double best = std::numeric_limits<double>::max();
  bool inside = false;
  for (size_t i = 0; i < n; ++i) {
    const PlanePoint& a = poly[i];
    const PlanePoint& b = poly[(i + 1) % n];
    best = std::min(best, SegmentDistance(p, a, b));
    if ((a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x)) {
      inside = !inside;
    }
  }
  return inside ? -best : best;
}

Status ValidateSweep(const Sculpture& sculpture, const SweepRequest& r) {
  SCULPT_RETURN_IF_ERROR(ValidatePlane("sweep.plane", r.plane));
  if (r.outline.size() < 3 || r.outline.size() > kMaxSweepOutlinePoints) {
    return Outside("sweep.outline.size", std::to_string(r.outline.size()),
                   std::string("[3, ") + std::to_string(kMaxSweepOutlinePoints) + "]");
  }
  for (size_t i = 0; i < r.outline.size(); ++i) {
    const PlanePoint& p = r.outline[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
      return NotFinite(std::string("sweep.outline[") + std::to_string(i) + "]",
                       std::string("(") + FormatNumber(p.x) + ", " + FormatNumber(p.y) + ")");
    }
  }
  const double dx = sculpture.voxel_size();
  const double limit = kMaxPrimitiveVoxels * dx;
  if (r.mode == SweepRequest::Mode::kExtrude) {
    SCULPT_RETURN_IF_ERROR(CheckRange("sweep.depth", r.depth, dx, limit));
  } else {
    SCULPT_RETURN_IF_ERROR(CheckRange("sweep.axis_point.x", r.axis_point.x, -limit, limit));
    SCULPT_RETURN_IF_ERROR(CheckRange("sweep.axis_point.y", r.axis_point.y, -limit, limit));
    const double l = std::hypot(r.axis_dir.x, r.axis_dir.y);
    if (!std::isfinite(l) || std::abs(l - 1) > kUnitTolerance) {
      return Outside(
          "sweep.axis_dir",
          std::string("(") + FormatNumber(r.axis_dir.x) + ", " + FormatNumber(r.axis_dir.y) + ")",
          "unit vectors");
    }
  }
  const Aabb s = SolidBounds(r);
  const Vec3 size = s.max - s.min;
  const double voxels = (size.x / dx + 2 * sculpture.half_width() + 3) *
                        (size.y / dx + 2 * sculpture.half_width() + 3) *
                        (size.z / dx + 2 * sculpture.half_width() + 3);
  if (!(voxels <= kMaxSweepBlockVoxels)) {
    return Outside("sweep.block", FormatNumber(voxels) + " voxels",
                   std::string("[0, ") + FormatNumber(kMaxSweepBlockVoxels) +
                       "] (the swept solid " + Point3(size) +
                       " world units is too large for one edit)");
  }
  return Status::Ok();
}

StatusOr<EditResult> ApplySweep(Sculpture& sculpture, const SweepRequest& r) {
  SCULPT_RETURN_IF_ERROR(ValidateSweep(sculpture, r));
  const auto t0 = std::chrono::steady_clock::now();
  Sculpture::Impl& impl = sculpture.impl();
  const double dx = impl.dx();
  const float bg = impl.background();
  const internal::IndexBox box = SweepBox(impl, r);
  const DenseField before = internal::ExtractDense(*impl.grid, box);
  DenseField phi = before;
  // Half-voxel raster: bilinear error of a distance stays far below a voxel.
  const OutlineRaster raster(r.outline, 0.5 * dx, bg + 2 * dx);
  const SweepPlane& pl = r.plane;
  const Vec3 n = pl.u.Cross(pl.v);
  const Vec3 axis = pl.u * r.axis_dir.x + pl.v * r.axis_dir.y;
  const Vec3 axis0 = pl.At(r.axis_point);
  const PlanePoint perp{-r.axis_dir.y, r.axis_dir.x};
  const Int3 d = phi.dims();
  for (int k = 0; k < d.z; ++k) {
    for (int j = 0; j < d.y; ++j) {
      for (int i = 0; i < d.x; ++i) {
        const Vec3 p{(box.min.x + i) * dx, (box.min.y + j) * dx, (box.min.z + k) * dx};
        double sd;
        if (r.mode == SweepRequest::Mode::kExtrude) {
          const Vec3 q = p - pl.origin;
          const double d2 = raster.Sample(q.Dot(pl.u), q.Dot(pl.v));
          const double h = q.Dot(n);
          const double dh = std::abs(h - 0.5 * r.depth) - 0.5 * r.depth;
          // Distance to the prism: the 2D distance and the slab's, combined outside both.
          sd = (d2 > 0 || dh > 0) ? std::hypot(std::max(d2, 0.0), std::max(dh, 0.0))
                                  : std::max(d2, dh);
        } else {
          // The meridian half-plane through p holds p's nearest point of a solid of
          // revolution; the outline may straddle the axis, so both half-planes count.
          const Vec3 q = p - axis0;
          const double a = q.Dot(axis);
          const double rho = (q - axis * a).Length();
          const double x = r.axis_point.x + r.axis_dir.x * a, y = r.axis_point.y + r.axis_dir.y * a;
          sd = std::min(raster.Sample(x + perp.x * rho, y + perp.y * rho),
                        raster.Sample(x - perp.x * rho, y - perp.y * rho));
        }
        const float t = static_cast<float>(std::clamp(sd, -static_cast<double>(bg),
                                                      static_cast<double>(bg)));
        float& v = phi.at(i, j, k);
        v = r.add ? std::min(v, t) : std::max(v, -t);
      }
    }
  }
  EditResult res;
  res.volume_before = impl.volume;
  const double change =
      (internal::DenseInsideSum(phi, dx) - internal::DenseInsideSum(before, dx)) * dx * dx * dx;
  internal::WriteBackResult wb = internal::WriteBack(*impl.grid, before, phi, 0);
  if (wb.changed_voxels > 0) {
    impl.bounds.expand(openvdb::CoordBBox(openvdb::Coord(box.min.x, box.min.y, box.min.z),
                                          openvdb::Coord(box.max.x, box.max.y, box.max.z)));
  }
  impl.volume += change;
  impl.reference_volume += change;  // material added or removed on purpose
  res.volume_change = change;
  res.changed = wb.changed_voxels > 0;
  res.changed_voxels = wb.changed_voxels;
  res.dirty_leaves = std::move(wb.dirty_leaves);
  res.volume_after = impl.volume;
  res.reference_volume = impl.reference_volume;
  res.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

EditFootprint SweepFootprintOf(const Sculpture& sculpture, const SweepRequest& request) {
  const internal::IndexBox box = SweepBox(sculpture.impl(), request);
  EditFootprint f;
  f.min = box.min;
  f.max = box.max;
  return f;
}

}  // namespace sculpt::levelset
