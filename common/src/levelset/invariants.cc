/// @brief Invariant checks over leaves of a sculpture (band, gradient, thin features) and over the
/// whole grid.
#include "sculpt/levelset/invariants.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

using openvdb::Coord;

}  // namespace

double ThinMaterialThickness(float v, float a, float b, double length) {
  if (!(v < 0.f) || !(a >= 0.f) || !(b >= 0.f)) return std::numeric_limits<double>::infinity();
  // Two estimates, each exact for a flat sheet crossed at right angles: the crossings placed by
  // linear interpolation (too thin where the segment grazes a curved surface: phi is quadratic
  // along a tangent), and the distances read as distances, 2 length - a - b (too thick where
  // the segment crosses the sheet obliquely). The material is thin only if both say so.
  const double d = -static_cast<double>(v);
  const double interpolated = length * (d / (d + a) + d / (d + b));
  const double by_distance = 2 * length - static_cast<double>(a) - b;
  return std::max(interpolated, by_distance);
}

std::string BandReport::ToString() const {
  char buf[768];
  std::snprintf(buf, sizeof buf,
                "voxels %llu, interface %llu, interface near band edge %llu, |grad| outside "
                "[0.5,1.5] %llu of %llu (range %.3g..%.3g, worst at %d,%d,%d), thin material %llu "
                "(at %d,%d,%d), thin gaps %llu",
                static_cast<unsigned long long>(voxels),
                static_cast<unsigned long long>(interface_voxels),
                static_cast<unsigned long long>(interface_near_band_edge),
                static_cast<unsigned long long>(gradient_outside),
                static_cast<unsigned long long>(gradient_checked), min_gradient, max_gradient,
                worst_gradient_at.x, worst_gradient_at.y, worst_gradient_at.z,
                static_cast<unsigned long long>(thin_material), thin_material_at.x,
                thin_material_at.y, thin_material_at.z, static_cast<unsigned long long>(thin_gaps));
  return buf;
}

BandReport CheckBand(const Sculpture& sculpture, const std::vector<Int3>& leaf_origins) {
  BandReport r;
  const auto& grid = *sculpture.impl().grid;
  const float bg = grid.background();
  const double dx = sculpture.voxel_size();
  auto acc = grid.getConstAccessor();
  for (const Int3& o : leaf_origins) {
    for (int z = o.z; z < o.z + 8; ++z) {
      for (int y = o.y; y < o.y + 8; ++y) {
        for (int x = o.x; x < o.x + 8; ++x) {
          const Coord c(x, y, z);
          const float v = acc.getValue(c);
          ++r.voxels;
          const bool inside = v < 0.f;
          bool interface = false;
          for (int a = 0; a < 3; ++a) {
            Coord m = c, p = c;
            m[a] -= 1;
            p[a] += 1;
            const float vm = acc.getValue(m), vp = acc.getValue(p);
            interface = interface || (vm < 0.f) != inside || (vp < 0.f) != inside;
            if (!inside && vm < 0.f && vp < 0.f) ++r.thin_gaps;
          }
          bool thin = false;
          for (int dz = -1; dz <= 1 && inside && !thin; ++dz) {
            for (int dy = -1; dy <= 1 && !thin; ++dy) {
              for (int dxi = -1; dxi <= 1 && !thin; ++dxi) {
                if (dz * 9 + dy * 3 + dxi <= 0) continue;  // each direction once
                const float a = acc.getValue(Coord(x + dxi, y + dy, z + dz));
                const float b = acc.getValue(Coord(x - dxi, y - dy, z - dz));
                const double len = dx * std::sqrt(double(dxi * dxi + dy * dy + dz * dz));
                thin = ThinMaterialThickness(v, a, b, len) < dx;
              }
            }
          }
          if (thin && r.thin_material++ == 0) r.thin_material_at = {x, y, z};
          if (interface) {
            ++r.interface_voxels;
            bool near_edge = false;
            for (int dz = -1; dz <= 1 && !near_edge; ++dz) {
              for (int dy = -1; dy <= 1 && !near_edge; ++dy) {
                for (int dxi = -1; dxi <= 1 && !near_edge; ++dxi) {
                  near_edge = !acc.isValueOn(Coord(x + dxi, y + dy, z + dz));
                }
              }
            }
            if (near_edge) ++r.interface_near_band_edge;
          }
          if (!acc.isValueOn(c) || !(std::abs(v) < bg - dx)) continue;
          double g = 0;
          for (int dz = -1; dz <= 1; ++dz) {
            for (int dy = -1; dy <= 1; ++dy) {
              for (int dxi = -1; dxi <= 1; ++dxi) {
                if (!dz && !dy && !dxi) continue;
                const double len = dx * std::sqrt(double(dxi * dxi + dy * dy + dz * dz));
                const float w = acc.getValue(Coord(x + dxi, y + dy, z + dz));
                g = std::max(g, std::abs(static_cast<double>(w) - v) / len);
              }
            }
          }
          ++r.gradient_checked;
          r.min_gradient = std::min(r.min_gradient, g);
          r.max_gradient = std::max(r.max_gradient, g);
          if (g < 0.5 || g > 1.5) ++r.gradient_outside;
          if (std::abs(g - 1) > std::abs(r.worst_gradient - 1)) {
            r.worst_gradient = g;
            r.worst_gradient_at = {x, y, z};
          }
        }
      }
    }
  }
  return r;
}

BandReport CheckWholeBand(const Sculpture& sculpture) {
  std::vector<Int3> leaves;
  for (auto it = sculpture.impl().grid->tree().cbeginLeaf(); it; ++it) {
    const Coord o = it->origin();
    leaves.push_back({o.x(), o.y(), o.z()});
  }
  return CheckBand(sculpture, leaves);
}

}  // namespace sculpt::levelset
