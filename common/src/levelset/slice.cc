/// @brief Slice contours: marching squares on a plane sample of a sculpture's phi.
#include "sculpt/levelset/slice.h"

#include <openvdb/tools/Interpolation.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>

#include "sculpt/core/check.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

struct Segment {
  int64_t a, b;  // edge ids
};

}  // namespace

std::vector<std::vector<PlanePoint>> MarchingSquares(const std::vector<float>& phi, int nx, int ny,
                                                     PlanePoint origin, double step) {
  auto at = [&](int i, int j) { return phi[static_cast<size_t>(j) * nx + i]; };
  // Edge ids: 2 (j nx + i) for the edge from sample (i, j) to (i + 1, j), + 1 for the edge to
  // (i, j + 1). The crossing is where the linear interpolant of phi along the edge is zero.
  auto point = [&](int64_t id) {
    const int64_t s = id / 2;
    const int i = static_cast<int>(s % nx), j = static_cast<int>(s / nx);
    const bool vertical = id % 2 == 1;
    const double a = at(i, j);
    const double b = vertical ? at(i, j + 1) : at(i + 1, j);
    const double t = a != b ? std::clamp(a / (a - b), 0.0, 1.0) : 0.5;
    return PlanePoint{origin.x + (i + (vertical ? 0 : t)) * step,
                      origin.y + (j + (vertical ? t : 0)) * step};
  };
  std::vector<Segment> segs;
  for (int j = 0; j + 1 < ny; ++j) {
    for (int i = 0; i + 1 < nx; ++i) {
      const float v0 = at(i, j), v1 = at(i + 1, j), v2 = at(i + 1, j + 1), v3 = at(i, j + 1);
      const int c = (v0 < 0) | (v1 < 0) << 1 | (v2 < 0) << 2 | (v3 < 0) << 3;
      if (c == 0 || c == 15) continue;
      const int64_t base = 2 * (static_cast<int64_t>(j) * nx + i);
      const int64_t e[4] = {base, 2 * (static_cast<int64_t>(j) * nx + i + 1) + 1,
                            2 * (static_cast<int64_t>(j + 1) * nx + i), base + 1};
      // Corners 0..3 counter-clockwise; edge k runs from corner k to corner k + 1 (mod 4).
      if (c == 5 || c == 10) {
        const bool centre_in = (v0 + v1 + v2 + v3) < 0;
        // Which corners the cuts isolate: those on the centre's other side.
        const bool cut_odd = (c == 5) == centre_in;  // isolate corners 1 and 3
        if (cut_odd) {
          segs.push_back({e[0], e[1]});
          segs.push_back({e[2], e[3]});
        } else {
          segs.push_back({e[3], e[0]});
          segs.push_back({e[1], e[2]});
        }
        continue;
      }
      int64_t found[2] = {0, 0};
      int nf = 0;
      const bool in[4] = {v0 < 0, v1 < 0, v2 < 0, v3 < 0};
      for (int k = 0; k < 4; ++k) {
        if (in[k] != in[(k + 1) % 4]) found[nf++] = e[k];
      }
      segs.push_back({found[0], found[1]});
    }
  }
  // Link segments sharing an edge crossing into polylines: open ends first, then loops.
  std::unordered_map<int64_t, std::vector<uint32_t>> by_edge;
  by_edge.reserve(segs.size() * 2);
  for (uint32_t s = 0; s < segs.size(); ++s) {
    by_edge[segs[s].a].push_back(s);
    by_edge[segs[s].b].push_back(s);
  }
  std::vector<char> used(segs.size(), 0);
  std::vector<std::vector<PlanePoint>> out;
  auto walk = [&](uint32_t s0, int64_t from) {
    std::vector<PlanePoint> line{point(from)};
    uint32_t s = s0;
    int64_t at_edge = from;
    for (;;) {
      used[s] = 1;
      const int64_t next = segs[s].a == at_edge ? segs[s].b : segs[s].a;
      line.push_back(point(next));
      at_edge = next;
      uint32_t follow = UINT32_MAX;
      for (uint32_t t : by_edge[next]) {
        if (!used[t]) follow = t;
      }
      if (follow == UINT32_MAX) break;
      s = follow;
    }
    out.push_back(std::move(line));
  };
  std::vector<int64_t> ends;
  for (const auto& [edge, list] : by_edge) {
    if (list.size() == 1) ends.push_back(edge);
  }
  std::sort(ends.begin(), ends.end());  // the map's order is not deterministic
  for (int64_t edge : ends) {
    const uint32_t s = by_edge[edge][0];
    if (!used[s]) walk(s, edge);
  }
  for (uint32_t s = 0; s < segs.size(); ++s) {
    if (!used[s]) walk(s, segs[s].a);
  }
  return out;
}

StatusOr<std::vector<std::vector<PlanePoint>>> SliceContours(const Sculpture& sculpture,
                                                             const SliceRequest& r) {
  SCULPT_RETURN_IF_ERROR(ValidatePlane("slice", r.plane));
  SCULPT_RETURN_IF_ERROR(CheckRange("slice.step", r.step, 1e-3 * sculpture.voxel_size(), 1e9));
  SCULPT_RETURN_IF_ERROR(CheckRange("slice.half_extent", r.half_extent, r.step,
                                    0.5 * (kMaxSliceSamples - 1) * r.step));
  const int n = static_cast<int>(std::floor(2 * r.half_extent / r.step)) + 1;
  const openvdb::FloatGrid& grid = *sculpture.impl().grid;
  // GridSampler keeps a reference to the accessor: it must outlive the sampler.
  const openvdb::FloatGrid::ConstAccessor acc = grid.getConstAccessor();
  openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor, openvdb::tools::BoxSampler>
      sampler(acc, grid.transform());
  std::vector<float> phi(static_cast<size_t>(n) * n);
  const PlanePoint origin{-r.half_extent, -r.half_extent};
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const Vec3 w = r.plane.At({origin.x + i * r.step, origin.y + j * r.step});
      phi[static_cast<size_t>(j) * n + i] = sampler.wsSample(openvdb::Vec3d(w.x, w.y, w.z));
    }
  }
  // Unordered-map iteration order would make the output order vary between runs: sort the
  // polylines by their first point so equal states give equal bytes.
  auto lines = MarchingSquares(phi, n, n, origin, r.step);
  std::sort(lines.begin(), lines.end(), [](const auto& a, const auto& b) {
    return a.front().y != b.front().y ? a.front().y < b.front().y : a.front().x < b.front().x;
  });
  return lines;
}

}  // namespace sculpt::levelset
