/// @brief Shapes and mesh checks shared by the mesh unit tests.
#ifndef SCULPT_TESTS_UNIT_MESH_MESH_TEST_UTIL_H_
#define SCULPT_TESTS_UNIT_MESH_MESH_TEST_UTIL_H_

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <map>
#include <utility>
#include <vector>

#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::mesh::testing {

inline levelset::Sculpture Sphere(double radius_voxels) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 3;
  o.name = "ball";
  auto s = levelset::Sculpture::MakeSphere(o, {0.3, -0.2, 0.1}, radius_voxels);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move(s).value();
}

/// A sphere with a box corner cut away: creases and flat faces crossing chunk seams.
inline levelset::Sculpture CutSphere(double radius_voxels) {
  levelset::Sculpture s = Sphere(radius_voxels);
  levelset::EditRequest cut;
  cut.kind = levelset::EditKind::kSubtract;
  const double h = 0.5 * radius_voxels;
  cut.tool = levelset::ToolShape::Box({h + 3.7, h + 2.2, h + 1.3}, {h, h, h});
  levelset::EditSettings settings;
  settings.compensation = levelset::CompensationRegion::kNone;
  auto r = levelset::ApplyEdit(s, cut, settings);
  EXPECT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->changed);
  return s;
}

using Triangle = std::array<float, 9>;

/// The mesh's triangles as position triples, sorted: equal for meshes with the same faces
/// whatever their vertex numbering.
inline std::vector<Triangle> SortedTriangles(const TriangleMesh& m) {
  std::vector<Triangle> out(m.face_count());
  for (size_t f = 0; f < m.face_count(); ++f) {
    for (int c = 0; c < 3; ++c) {
      for (int a = 0; a < 3; ++a) out[f][3 * c + a] = m.positions[3 * m.indices[3 * f + c] + a];
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// Appends `part` to `all` with its vertices renumbered.
inline void Append(const TriangleMesh& part, TriangleMesh* all) {
  const uint32_t base = static_cast<uint32_t>(all->vertex_count());
  all->positions.insert(all->positions.end(), part.positions.begin(), part.positions.end());
  for (uint32_t i : part.indices) all->indices.push_back(base + i);
}

struct Closure {
  size_t vertices = 0;          // after welding
  size_t edges = 0;
  size_t edges_not_two = 0;     // edges used by other than exactly two faces
  size_t degenerate_faces = 0;  // faces with a repeated welded vertex
};

/// Welds vertices by exact position and counts the faces on every undirected edge.
inline Closure CheckClosed(const TriangleMesh& m) {
  std::map<std::array<float, 3>, uint32_t> ids;
  std::vector<uint32_t> weld(m.vertex_count());
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    const std::array<float, 3> p{m.positions[3 * v], m.positions[3 * v + 1],
                                 m.positions[3 * v + 2]};
    weld[v] = ids.emplace(p, static_cast<uint32_t>(ids.size())).first->second;
  }
  Closure c;
  c.vertices = ids.size();
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (size_t f = 0; f < m.face_count(); ++f) {
    const uint32_t a = weld[m.indices[3 * f]], b = weld[m.indices[3 * f + 1]],
                   d = weld[m.indices[3 * f + 2]];
    if (a == b || b == d || a == d) ++c.degenerate_faces;
    for (auto [u, w] : {std::pair{a, b}, std::pair{b, d}, std::pair{d, a}}) {
      ++edges[{std::min(u, w), std::max(u, w)}];
    }
  }
  c.edges = edges.size();
  for (const auto& [e, n] : edges) c.edges_not_two += n != 2;
  return c;
}

}  // namespace sculpt::mesh::testing

#endif  // SCULPT_TESTS_UNIT_MESH_MESH_TEST_UTIL_H_
