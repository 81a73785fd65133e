/// @brief The pieces of an object's mesh as a viewer sees them, for the stability tests: the
/// outer surface, specks and sealed air pockets, each with its signed volume.
#ifndef SCULPT_TESTS_STABILITY_MESH_PIECES_H_
#define SCULPT_TESTS_STABILITY_MESH_PIECES_H_

#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/mesh_stats.h"

namespace sculpt::levelset::testing {

// The mesh's face-connected pieces, each with its signed volume: the outer surface encloses a
// positive volume, a sealed air pocket is an inward-wound shell (negative), a speck positive.
struct Pieces {
  int outer = 0;           // positive pieces of at least `large` volume
  int specks = 0;          // positive pieces below it
  int voids = 0;           // negative pieces
  int small_voids = 0;     // negative pieces whose |volume| is below `large`
  double void_volume = 0;  // their total |volume|
  double speck_volume = 0;
  int64_t genus = -1;
  size_t components = 0;
  mesh::MeshTopology topology;  // of the whole mesh
  std::string ToString() const {
    return std::to_string(components) + " components (" + std::to_string(outer) + " outer, " +
           std::to_string(specks) + " specks of " + std::to_string(speck_volume) + " units^3, " +
           std::to_string(voids) + " voids of " + std::to_string(void_volume) +
           " units^3), genus " + std::to_string(genus);
  }
};

inline Pieces CountPieces(const Sculpture& s, double large) {
  const mesh::TriangleMesh m = mesh::MeshWhole(s);
  const mesh::MeshTopology t = mesh::ComputeTopology(m);
  // Faces sharing a vertex index are in one piece (the mesher welds its vertices).
  std::vector<uint32_t> parent(m.vertex_count());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (size_t f = 0; f < m.face_count(); ++f) {
    const uint32_t a = find(m.indices[3 * f]);
    for (int c = 1; c < 3; ++c) {
      const uint32_t b = find(m.indices[3 * f + c]);
      if (a != b) parent[b] = a;
    }
  }
  std::vector<double> vol(m.vertex_count(), 0.0);
  std::vector<uint8_t> used(m.vertex_count(), 0);
  for (size_t f = 0; f < m.face_count(); ++f) {
    const float* p[3];
    for (int c = 0; c < 3; ++c) p[c] = &m.positions[3 * m.indices[3 * f + c]];
    const double cx =
        static_cast<double>(p[1][1]) * p[2][2] - static_cast<double>(p[1][2]) * p[2][1];
    const double cy =
        static_cast<double>(p[1][2]) * p[2][0] - static_cast<double>(p[1][0]) * p[2][2];
    const double cz =
        static_cast<double>(p[1][0]) * p[2][1] - static_cast<double>(p[1][1]) * p[2][0];
    const uint32_t r = find(m.indices[3 * f]);
    vol[r] += (p[0][0] * cx + p[0][1] * cy + p[0][2] * cz) / 6.0;
    used[r] = 1;
  }
  Pieces out;
  out.genus = t.genus;
  out.components = t.components;
  out.topology = t;
  for (size_t v = 0; v < vol.size(); ++v) {
    if (!used[v]) continue;
    if (vol[v] < 0) {
      ++out.voids;
      out.void_volume += -vol[v];
      if (-vol[v] < large) ++out.small_voids;
    } else if (vol[v] < large) {
      ++out.specks;
      out.speck_volume += vol[v];
    } else {
      ++out.outer;
    }
  }
  return out;
}

}  // namespace sculpt::levelset::testing

#endif  // SCULPT_TESTS_STABILITY_MESH_PIECES_H_
