/// @brief Mesh topology counts: edges by the faces around them, pieces by union-find.
#include "sculpt/mesh/mesh_stats.h"

#include <algorithm>
#include <array>
#include <map>
#include <numeric>
#include <utility>
#include <vector>

namespace sculpt::mesh {
namespace {

double FaceVolume(const TriangleMesh& m, size_t f) {
  const float* a = &m.positions[3 * m.indices[3 * f]];
  const float* b = &m.positions[3 * m.indices[3 * f + 1]];
  const float* c = &m.positions[3 * m.indices[3 * f + 2]];
  const double cx = double(b[1]) * c[2] - double(b[2]) * c[1];
  const double cy = double(b[2]) * c[0] - double(b[0]) * c[2];
  const double cz = double(b[0]) * c[1] - double(b[1]) * c[0];
  return (a[0] * cx + a[1] * cy + a[2] * cz) / 6.0;
}

class UnionFind {
 public:
  explicit UnionFind(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  uint32_t Find(uint32_t v) {
    while (parent_[v] != v) v = parent_[v] = parent_[parent_[v]];
    return v;
  }
  void Join(uint32_t a, uint32_t b) { parent_[Find(a)] = Find(b); }

 private:
  std::vector<uint32_t> parent_;
};

}  // namespace

double SignedVolume(const TriangleMesh& mesh) {
  double v = 0.0;
  for (size_t f = 0; f < mesh.face_count(); ++f) v += FaceVolume(mesh, f);
  return v;
}

MeshTopology ComputeTopology(const TriangleMesh& mesh) {
  MeshTopology t;
  const size_t nv = mesh.vertex_count();
  // One record per directed half-edge: (low, high, direction) so both halves of an edge meet.
  struct HalfEdge {
    uint32_t lo, hi;
    bool forward;  // lo -> hi in the face's order
    uint32_t face;
  };
  std::vector<HalfEdge> halves;
  halves.reserve(mesh.indices.size());
  std::vector<char> used(nv, 0);
  UnionFind pieces(mesh.face_count());
  std::vector<uint32_t> faces;
  for (size_t f = 0; f < mesh.face_count(); ++f) {
    const uint32_t* v = &mesh.indices[3 * f];
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) continue;
    ++t.faces;
    faces.push_back(static_cast<uint32_t>(f));
    t.signed_volume += FaceVolume(mesh, f);
    for (int c = 0; c < 3; ++c) {
      const uint32_t a = v[c], b = v[(c + 1) % 3];
      used[a] = 1;
      halves.push_back({std::min(a, b), std::max(a, b), a < b, static_cast<uint32_t>(f)});
    }
  }
  t.vertices = static_cast<size_t>(std::count(used.begin(), used.end(), 1));
  std::sort(halves.begin(), halves.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.lo != y.lo ? x.lo < y.lo : x.hi < y.hi;
  });
  // Each edge is a run of equal (lo, hi) half-edges; `starts` holds where each run begins.
  std::vector<size_t> starts;
  for (size_t i = 0; i < halves.size(); ++i) {
    if (i == 0 || halves[i].lo != halves[i - 1].lo || halves[i].hi != halves[i - 1].hi) {
      starts.push_back(i);
    }
  }
  starts.push_back(halves.size());
  t.edges = starts.size() - 1;
  for (size_t e = 0; e + 1 < starts.size(); ++e) {
    const size_t i = starts[e], n = starts[e + 1] - starts[e];
    if (n == 1) ++t.boundary_edges;
    if (n > 2) ++t.non_manifold_edges;
    if (n == 2 && halves[i].forward == halves[i + 1].forward) ++t.inconsistent_edges;
    for (size_t k = 1; k < n; ++k) pieces.Join(halves[i].face, halves[i + k].face);
  }
  // Components by faces; Euler characteristic per component for the genus.
  std::map<uint32_t, std::array<int64_t, 3>> per;  // root -> V, E, F
  for (uint32_t f : faces) per[pieces.Find(f)][2] += 1;
  for (size_t e = 0; e + 1 < starts.size(); ++e) per[pieces.Find(halves[starts[e]].face)][1] += 1;
  std::vector<uint32_t> vertex_root(nv, UINT32_MAX);
  for (uint32_t f : faces) {
    for (int c = 0; c < 3; ++c) vertex_root[mesh.indices[3 * f + c]] = pieces.Find(f);
  }
  for (uint32_t r : vertex_root) {
    if (r != UINT32_MAX) per[r][0] += 1;
  }
  t.components = per.size();
  t.euler = static_cast<int64_t>(t.vertices) - static_cast<int64_t>(t.edges) +
            static_cast<int64_t>(t.faces);
  if (t.closed_manifold()) {
    int64_t genus = 0;
    for (const auto& [root, c] : per) genus += (2 - (c[0] - c[1] + c[2])) / 2;
    t.genus = genus;
  }
  return t;
}

TriangleMesh WeldByPosition(const TriangleMesh& mesh) {
  TriangleMesh out;
  std::map<std::array<float, 3>, uint32_t> index;
  std::vector<uint32_t> remap(mesh.vertex_count());
  const bool colours = mesh.colours.size() == mesh.positions.size();
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    const std::array<float, 3> p{mesh.positions[3 * v], mesh.positions[3 * v + 1],
                                 mesh.positions[3 * v + 2]};
    auto [it, inserted] = index.emplace(p, static_cast<uint32_t>(out.vertex_count()));
    if (inserted) {
      out.positions.insert(out.positions.end(), p.begin(), p.end());
      if (colours) {
        out.colours.insert(out.colours.end(), mesh.colours.begin() + 3 * v,
                           mesh.colours.begin() + 3 * v + 3);
      }
    }
    remap[v] = it->second;
  }
  out.indices.reserve(mesh.indices.size());
  for (uint32_t i : mesh.indices) out.indices.push_back(remap[i]);
  return out;
}

}  // namespace sculpt::mesh
