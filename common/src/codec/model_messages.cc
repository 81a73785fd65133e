/// @brief Decoding of ModelIntent off the wire and of the ModelIntent a ModelRecord embeds.
#include "sculpt/codec/model_messages.h"

#include <cmath>
#include <string>

#include "sculpt/core/check.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

constexpr size_t kMaxNameBytes = 64;

Status CheckComponent(const std::string& field, double v) {
  if (!std::isfinite(v) || std::fabs(v) > hetero::kMaxDisplacement) {
    return Outside(field, FormatNumber(v),
                   std::string("finite [") + FormatNumber(-hetero::kMaxDisplacement) + ", " +
                       FormatNumber(hetero::kMaxDisplacement) + "]");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<ModelEdit> DecodeModelIntent(const v1::ModelIntent& m) {
  if (m.object().empty() || m.object().size() > kMaxNameBytes) {
    return Outside("ModelIntent.object", m.object(), "names of 1..64 bytes");
  }
  if (m.offset_size() != 3) {
    return Outside("ModelIntent.offset size", std::to_string(m.offset_size()), "{3}");
  }
  for (int a = 0; a < 3; ++a) {
    if (m.offset(a) < -1 || m.offset(a) > 1) {
      return Outside(std::string("ModelIntent.offset[") + std::to_string(a) + "]",
                     std::to_string(m.offset(a)), "[-1, 1]");
    }
  }
  SCULPT_RETURN_IF_ERROR(CheckComponent("ModelIntent.displacement_x", m.displacement_x()));
  SCULPT_RETURN_IF_ERROR(CheckComponent("ModelIntent.displacement_y", m.displacement_y()));
  SCULPT_RETURN_IF_ERROR(CheckComponent("ModelIntent.displacement_z", m.displacement_z()));
  if (m.cell() < -1) {
    return Outside("ModelIntent.cell", std::to_string(m.cell()), "-1 (none) or a cell index >= 0");
  }
  return ModelEditFromRecord(m);
}

ModelEdit ModelEditFromRecord(const v1::ModelIntent& m) {
  ModelEdit out;
  out.client_seq = m.client_seq();
  out.object = m.object();
  hetero::EditIntent& i = out.intent;
  i.corner = m.corner();
  for (int a = 0; a < 3 && a < m.offset_size(); ++a) i.offset[static_cast<size_t>(a)] = m.offset(a);
  i.displacement = {m.displacement_x(), m.displacement_y(), m.displacement_z()};
  i.cell = m.cell();
  if (m.set_flags()) i.set_flags = hetero::CornerFlags{m.geometry_c1(), m.material_c1()};
  return out;
}

v1::ModelIntent EncodeModelIntent(const ModelEdit& e) {
  v1::ModelIntent m;
  m.set_client_seq(e.client_seq);
  m.set_object(e.object);
  const hetero::EditIntent& i = e.intent;
  m.set_corner(i.corner);
  for (int o : i.offset) m.add_offset(o);
  m.set_displacement_x(i.displacement.x);
  m.set_displacement_y(i.displacement.y);
  m.set_displacement_z(i.displacement.z);
  m.set_cell(i.cell);
  if (i.set_flags) {
    m.set_set_flags(true);
    m.set_geometry_c1(i.set_flags->geometry_c1);
    m.set_material_c1(i.set_flags->material_c1);
  }
  return m;
}

}  // namespace sculpt::codec
