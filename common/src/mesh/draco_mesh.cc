/// @brief TriangleMesh <-> draco::Mesh.
#include "mesh/draco_mesh.h"

#include <draco/attributes/geometry_attribute.h>
#include <draco/attributes/point_attribute.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace sculpt::mesh::internal {

StatusOr<std::unique_ptr<draco::Mesh>> ToDracoMesh(const TriangleMesh& mesh) {
  if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0) {
    return InvalidArgument("TriangleMesh sizes positions=" + std::to_string(mesh.positions.size()) +
                           " indices=" + std::to_string(mesh.indices.size()) +
                           " are not multiples of 3");
  }
  const uint32_t nv = static_cast<uint32_t>(mesh.vertex_count());
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    if (mesh.indices[i] >= nv) {
      return Outside(std::string("TriangleMesh.indices[") + std::to_string(i) + "]",
                     std::to_string(mesh.indices[i]),
                     std::string("[0, ") + std::to_string(nv) + ")");
    }
  }
  if (!mesh.colours.empty() && mesh.colours.size() != mesh.positions.size()) {
    return Outside("TriangleMesh.colours.size", std::to_string(mesh.colours.size()),
                   std::string("{0, ") + std::to_string(mesh.positions.size()) +
                       "} (none, or r, g, b per vertex)");
  }
  for (size_t i = 0; i < mesh.colours.size(); ++i) {
    const float c = mesh.colours[i];
    if (!(c >= 0.f && c <= 1.f)) {
      return Outside(std::string("TriangleMesh.colours[") + std::to_string(i) + "]",
                     std::to_string(c), "[0, 1]");
    }
  }
  auto out = std::make_unique<draco::Mesh>();
  out->set_num_points(nv);
  draco::GeometryAttribute pos;
  pos.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false,
           sizeof(float) * 3, 0);
  const int att_id = out->AddAttribute(pos, /*identity_mapping=*/true, nv);
  draco::PointAttribute* att = out->attribute(att_id);
  for (uint32_t v = 0; v < nv; ++v) {
    att->SetAttributeValue(draco::AttributeValueIndex(v), &mesh.positions[3 * v]);
  }
  if (!mesh.colours.empty()) {
    // 8 bits a channel, normalised (what a screen shows, and glTF's COLOR_0 unsigned byte form,
    // which stays in [0, 1] where a quantised float may not).
    draco::GeometryAttribute col;
    col.Init(draco::GeometryAttribute::COLOR, nullptr, 3, draco::DT_UINT8, /*normalized=*/true,
             3, 0);
    const int col_id = out->AddAttribute(col, /*identity_mapping=*/true, nv);
    draco::PointAttribute* ca = out->attribute(col_id);
    for (uint32_t v = 0; v < nv; ++v) {
      uint8_t rgb[3];
      for (int c = 0; c < 3; ++c) {
        rgb[c] = static_cast<uint8_t>(std::lround(mesh.colours[3 * v + c] * 255.0f));
      }
      ca->SetAttributeValue(draco::AttributeValueIndex(v), rgb);
    }
  }
  const size_t nf = mesh.face_count();
  out->SetNumFaces(nf);
  for (size_t f = 0; f < nf; ++f) {
    draco::Mesh::Face face;
    for (int c = 0; c < 3; ++c) face[c] = draco::PointIndex(mesh.indices[3 * f + c]);
    out->SetFace(draco::FaceIndex(static_cast<uint32_t>(f)), face);
  }
  return out;
}

StatusOr<TriangleMesh> FromDracoMesh(const draco::Mesh& mesh) {
  const draco::PointAttribute* att = mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (att == nullptr || att->num_components() != 3) {
    return InvalidArgument("Draco mesh has no 3-component POSITION attribute");
  }
  TriangleMesh out;
  const uint32_t np = mesh.num_points();
  out.positions.resize(3 * static_cast<size_t>(np));
  for (uint32_t p = 0; p < np; ++p) {
    if (!att->ConvertValue<float, 3>(att->mapped_index(draco::PointIndex(p)),
                                     &out.positions[3 * static_cast<size_t>(p)])) {
      return InvalidArgument("Draco POSITION value of point " + std::to_string(p) +
                             " is not convertible to float");
    }
  }
  if (const draco::PointAttribute* col = mesh.GetNamedAttribute(draco::GeometryAttribute::COLOR);
      col != nullptr && col->num_components() >= 3) {
    out.colours.resize(3 * static_cast<size_t>(np));
    float rgba[4] = {0, 0, 0, 1};
    for (uint32_t p = 0; p < np; ++p) {
      const draco::AttributeValueIndex i = col->mapped_index(draco::PointIndex(p));
      const bool ok = col->num_components() == 3 ? col->ConvertValue<float, 3>(i, rgba)
                                                 : col->ConvertValue<float, 4>(i, rgba);
      if (!ok) {
        return InvalidArgument("Draco COLOR value of point " + std::to_string(p) +
                               " is not convertible to float");
      }
      // Quantisation may land a hair outside [0, 1]; what comes off the wire is kept in range.
      for (int c = 0; c < 3; ++c) {
        out.colours[3 * p + c] = std::isfinite(rgba[c]) ? std::clamp(rgba[c], 0.f, 1.f) : 0.f;
      }
    }
  }
  out.indices.reserve(3 * static_cast<size_t>(mesh.num_faces()));
  for (draco::FaceIndex f(0); f < mesh.num_faces(); ++f) {
    const draco::Mesh::Face& face = mesh.face(f);
    for (int c = 0; c < 3; ++c) {
      if (face[c].value() >= np) {
        return Outside(
            std::string("Draco face ") + std::to_string(f.value()) + " corner " + std::to_string(c),
            std::to_string(face[c].value()), std::string("[0, ") + std::to_string(np) + ")");
      }
      out.indices.push_back(face[c].value());
    }
  }
  return out;
}

}  // namespace sculpt::mesh::internal
