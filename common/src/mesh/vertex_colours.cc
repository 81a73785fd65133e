/// @brief ColourVertices: ColourAtWorld at every vertex of a mesh.
#include "sculpt/mesh/vertex_colours.h"

#include <algorithm>

#include "sculpt/levelset/materials.h"

namespace sculpt::mesh {

Status ColourVertices(const levelset::Sculpture& sculpture, TriangleMesh* mesh) {
  mesh->colours.clear();
  if (levelset::MaterialCount(sculpture) == 0) return Status::Ok();
  const size_t nv = mesh->vertex_count();
  std::vector<float> colours(3 * nv);
  for (size_t v = 0; v < nv; ++v) {
    const Vec3 p{mesh->positions[3 * v], mesh->positions[3 * v + 1], mesh->positions[3 * v + 2]};
    auto rgb = levelset::ColourAtWorld(sculpture, p);
    if (!rgb.ok()) return rgb.status();
    // A convex combination of colours in [0, 1]; the clamp only removes float rounding.
    for (int c = 0; c < 3; ++c)
      colours[3 * v + c] = std::clamp(static_cast<float>((*rgb)[c]), 0.f, 1.f);
  }
  mesh->colours = std::move(colours);
  return Status::Ok();
}

}  // namespace sculpt::mesh
