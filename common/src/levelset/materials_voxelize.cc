/// @brief VoxelizeModel: a composite hyperpatch model into the SDF (boundary mesh ->
/// meshToLevelSet -> CSG union) and into the fraction grids (inverse map at voxel centres),
/// seed 001 §10.3.
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <tuple>
#include <unordered_map>

#include "materials_internal.h"
#include "sculpt/core/check.h"
#include "sculpt/hetero/boundary.h"
#include "sculpt/hetero/inverse_map.h"
#include "sculpt/hetero/material.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/voxelize_model.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

using openvdb::Coord;
using openvdb::FloatGrid;
using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

uint64_t VoxelKey(const Coord& c) {
  const uint64_t x = static_cast<uint64_t>(c.x() + (1 << 20)) & 0x1FFFFF;
  const uint64_t y = static_cast<uint64_t>(c.y() + (1 << 20)) & 0x1FFFFF;
  const uint64_t z = static_cast<uint64_t>(c.z() + (1 << 20)) & 0x1FFFFF;
  return x | (y << 21) | (z << 42);
}

bool CoordLess(const Coord& a, const Coord& b) {
  return std::make_tuple(a.z(), a.y(), a.x()) < std::make_tuple(b.z(), b.y(), b.x());
}

}  // namespace

StatusOr<VoxelizeResult> VoxelizeModel(Sculpture& sculpture, const hetero::CompositeModel& model,
                                       const VoxelizeOptions& options) {
  SCULPT_RETURN_IF_ERROR(CheckRange("tessellation", options.tessellation, 1, 64));
  if (model.cell_count() == 0) return FailedPrecondition("model has no cells");
  Sculpture::Impl& impl = sculpture.impl();
  const int n = model.materials();
  if (!impl.fractions.empty() && MaterialCount(sculpture) != n) {
    return Outside("model.materials", std::to_string(n),
                   std::string("{") + std::to_string(MaterialCount(sculpture)) +
                       "} (the sculpture's declared materials)");
  }
  VoxelizeResult res;

  // 1. The closed outward boundary of the external faces (§10.3 steps 1-4).
  auto t0 = Clock::now();
  auto mesh = hetero::ExternalBoundaryMesh(model, options.tessellation);
  if (!mesh.ok()) return mesh.status();
  if (mesh->open_edges > 0) {
    return Outside("model boundary has open_edges", std::to_string(mesh->open_edges),
                   "[0, 0] (cracks between partly shared faces)",
                   Status::Code::kFailedPrecondition);
  }
  std::vector<openvdb::Vec3s> points;
  points.reserve(mesh->vertices.size());
  for (const Vec3& v : mesh->vertices) {
    if (!v.IsFinite()) return InvalidArgument("model boundary vertex is not finite");
    points.emplace_back(static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z));
  }
  std::vector<openvdb::Vec3I> tris;
  tris.reserve(mesh->triangles.size());
  for (const auto& t : mesh->triangles) tris.emplace_back(t[0], t[1], t[2]);
  res.boundary_triangles = tris.size();
  res.mesh_ms = MsSince(t0);

  // Declare the model's materials before anything changes, so a bad declaration leaves the
  // sculpture as it was.
  if (impl.fractions.empty()) {
    std::vector<MaterialDecl> decls;
    for (const auto& m : model.material_info()) decls.push_back({m.name, m.colour});
    SCULPT_RETURN_IF_ERROR(SetMaterials(sculpture, decls));
  }

  // 2. The model's SDF on the sculpture's grid (§10.3 step 4), unioned in: min(phi, phi_model).
  t0 = Clock::now();
  const double dx = impl.dx();
  const float bg = impl.background();
  const std::vector<openvdb::Vec4I> quads;
  FloatGrid::Ptr shape = openvdb::tools::meshToLevelSet<FloatGrid>(
      impl.grid->transform(), points, tris, quads, static_cast<float>(bg / dx));
  FloatGrid& grid = *impl.grid;
  const double volume_before = impl.volume;
  // Which voxels the model owns for materials: inside it or within two voxels outside, where
  // its surface is the nearer one (decided on the SDF before the union).
  const float tau = static_cast<float>(2.0 * dx);
  std::vector<Coord> owned;
  std::vector<openvdb::CoordBBox> owned_tiles;
  {
    auto acc = grid.getAccessor();
    std::vector<Int3> leaves;
    for (auto it = shape->tree().cbeginValueAll(); it; ++it) {
      const float v = *it;
      if (it.isVoxelValue()) {
        const Coord c = it.getCoord();
        const float old = acc.getValue(c);
        if (v < tau && v <= old) owned.push_back(c);
        if (!(v < old)) continue;
        if (v <= -bg) {
          acc.setValueOff(c, -bg);
        } else {
          acc.setValueOn(c, std::min(v, bg));
        }
        ++res.sdf_changed_voxels;
        leaves.push_back({c.x() & ~7, c.y() & ~7, c.z() & ~7});
      } else if (v < 0) {
        openvdb::CoordBBox bb;
        it.getBoundingBox(bb);
        owned_tiles.push_back(bb);
        grid.tree().fill(bb, -bg, false);
        res.sdf_changed_voxels += bb.volume();
        for (int z = bb.min().z(); z <= bb.max().z(); z += 8)
          for (int y = bb.min().y(); y <= bb.max().y(); y += 8)
            for (int x = bb.min().x(); x <= bb.max().x(); x += 8) leaves.push_back({x, y, z});
      }
    }
    openvdb::tools::pruneLevelSet(grid.tree());
    std::sort(leaves.begin(), leaves.end(), [](const Int3& a, const Int3& b) {
      return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x);
    });
    leaves.erase(std::unique(leaves.begin(), leaves.end()), leaves.end());
    res.dirty_leaves = std::move(leaves);
  }
  impl.bounds = grid.evalActiveVoxelBoundingBox();
  impl.volume = sculpture.ComputeVolume();
  res.volume_added = impl.volume - volume_before;
  impl.reference_volume += res.volume_added;
  res.sdf_ms = MsSince(t0);

  // 3. Materials at voxel centres by the inverse map (§10.3 step 5), each voxel hinted with its
  //    predecessor's location; ties on shared faces go to the lowest cell (the map's rule).
  t0 = Clock::now();
  for (const auto& bb : owned_tiles) {
    for (int z = bb.min().z(); z <= bb.max().z(); ++z)
      for (int y = bb.min().y(); y <= bb.max().y(); ++y)
        for (int x = bb.min().x(); x <= bb.max().x(); ++x) owned.emplace_back(x, y, z);
  }
  std::sort(owned.begin(), owned.end(), CoordLess);
  owned.erase(std::unique(owned.begin(), owned.end()), owned.end());
  const hetero::InverseMap map(model);
  std::vector<FloatGrid::Accessor> acc;
  for (auto& g : impl.fractions) acc.push_back(g->getAccessor());
  const size_t nm = static_cast<size_t>(n);
  std::vector<double> a(nm);
  std::vector<float> stored(nm);
  std::unordered_map<uint64_t, size_t> pending;  // unlocated voxel -> index in `missing`
  std::vector<Coord> missing;
  std::optional<hetero::Location> prev;
  for (const Coord& c : owned) {
    const Vec3 p{c.x() * dx, c.y() * dx, c.z() * dx};
    const auto loc = map.Locate(p, prev ? &*prev : nullptr);
    if (!loc) {
      pending.emplace(VoxelKey(c), missing.size());
      missing.push_back(c);
      continue;
    }
    prev = loc;
    std::copy(loc->materials.begin(), loc->materials.end(), a.begin());
    internal::ToSimplexFloat(a, stored);
    for (size_t m = 0; m < nm; ++m) acc[m].setValueOn(c, stored[m]);
    ++res.located_voxels;
  }
  // Voxels the map missed (outside the exact cells but inside the tessellation, or in the outer
  // band) copy a located 6-neighbour, in rounds, so a copy never comes from a voxel filled in
  // the same round (order independent); the first neighbour in a fixed order wins.
  const Coord nb[6] = {Coord(-1, 0, 0), Coord(1, 0, 0),  Coord(0, -1, 0),
                       Coord(0, 1, 0),  Coord(0, 0, -1), Coord(0, 0, 1)};
  std::vector<uint8_t> done(missing.size(), 0);
  const int rounds = static_cast<int>(std::lround(bg / dx)) + 4;
  for (int round = 0; round < rounds; ++round) {
    std::vector<std::pair<size_t, Coord>> copies;
    for (size_t i = 0; i < missing.size(); ++i) {
      if (done[i]) continue;
      for (const Coord& o : nb) {
        const Coord q = missing[i] + o;
        auto it = pending.find(VoxelKey(q));
        const bool unfilled = it != pending.end() && !done[it->second];
        if (unfilled) continue;
        // Located, or filled in an earlier round, or not owned by the model at all: only the
        // first two are sources.
        const bool owned_voxel = std::binary_search(owned.begin(), owned.end(), q, CoordLess);
        if (!owned_voxel) continue;
        copies.push_back({i, q});
        break;
      }
    }
    if (copies.empty()) break;
    std::vector<float> values(copies.size() * nm);
    for (size_t k = 0; k < copies.size(); ++k) {
      for (size_t m = 0; m < nm; ++m) values[k * nm + m] = acc[m].getValue(copies[k].second);
    }
    for (size_t k = 0; k < copies.size(); ++k) {
      for (size_t m = 0; m < nm; ++m)
        acc[m].setValueOn(missing[copies[k].first], values[k * nm + m]);
      done[copies[k].first] = 1;
      ++res.filled_voxels;
    }
  }
  res.unreached_voxels = missing.size() - res.filled_voxels;
  // Uniform regions (a cell of one material) collapse into tiles.
  for (auto& g : impl.fractions) openvdb::tools::prune(g->tree());
  res.materials_ms = MsSince(t0);
  return res;
}

}  // namespace sculpt::levelset
