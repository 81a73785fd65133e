/// @brief EditSettings <-> EditSettingsMsg.
#include "sculpt/codec/settings.h"

#include <string>

namespace sculpt::codec {
namespace {

Status EnumIn(const char* field, uint32_t v, uint32_t lo, uint32_t hi) {
  if (v < lo || v > hi) {
    return Outside(std::string("EditSettingsMsg.") + field, std::to_string(v),
                   std::string("[") + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return Status::Ok();
}

}  // namespace

v1::EditSettingsMsg SettingsToProto(const levelset::EditSettings& s) {
  v1::EditSettingsMsg m;
  m.set_spatial(static_cast<uint32_t>(s.motion.spatial));
  m.set_temporal(static_cast<uint32_t>(s.motion.temporal));
  m.set_boundary(static_cast<uint32_t>(s.motion.boundary));
  m.set_cfl(s.cfl);
  m.set_compensation(static_cast<uint32_t>(s.compensation));
  m.set_compensation_method(static_cast<uint32_t>(s.compensation_method));
  m.set_shell_radii(s.shell_radii);
  m.set_compensation_tolerance_voxels(s.compensation_tolerance_voxels);
  m.set_max_compensation_iterations(static_cast<uint32_t>(s.max_compensation_iterations));
  m.set_gradient_descent_dt(s.gradient_descent_dt);
  m.set_reinit_eikonal_threshold(s.reinit_eikonal_threshold);
  m.set_reinit_every_k(static_cast<uint32_t>(s.reinit_every_k));
  m.set_reinit_iterations(static_cast<uint32_t>(s.reinit_iterations));
  m.set_reinit_spatial(static_cast<uint32_t>(s.reinit_spatial));
  m.set_islands(static_cast<uint32_t>(s.islands));
  m.set_min_island_volume(s.min_island_volume);
  m.set_min_tool_voxels(s.min_tool_voxels);
  m.set_max_tool_voxels(s.max_tool_voxels);
  m.set_max_speed_voxels(s.max_speed_voxels);
  m.set_max_amount_voxels(s.max_amount_voxels);
  m.set_repair_band_every_edit(s.repair_band_every_edit);
  return m;
}

StatusOr<levelset::ValidEditSettings> SettingsFromProto(const v1::EditSettingsMsg& m) {
  using namespace levelset;
  SCULPT_RETURN_IF_ERROR(EnumIn("spatial", m.spatial(), 0, 2));
  SCULPT_RETURN_IF_ERROR(EnumIn("temporal", m.temporal(), 1, 3));
  SCULPT_RETURN_IF_ERROR(EnumIn("boundary", m.boundary(), 0, 1));
  SCULPT_RETURN_IF_ERROR(EnumIn("compensation", m.compensation(), 0, 2));
  SCULPT_RETURN_IF_ERROR(EnumIn("compensation_method", m.compensation_method(), 0, 2));
  SCULPT_RETURN_IF_ERROR(EnumIn("reinit_spatial", m.reinit_spatial(), 0, 2));
  SCULPT_RETURN_IF_ERROR(EnumIn("islands", m.islands(), 0, 1));
  SCULPT_RETURN_IF_ERROR(EnumIn("max_compensation_iterations", m.max_compensation_iterations(), 0, 1000));
  SCULPT_RETURN_IF_ERROR(EnumIn("reinit_every_k", m.reinit_every_k(), 0, 1000000));
  SCULPT_RETURN_IF_ERROR(EnumIn("reinit_iterations", m.reinit_iterations(), 0, 1000));
  EditSettings s;
  s.motion.spatial = static_cast<SpatialScheme>(m.spatial());
  s.motion.temporal = static_cast<TemporalScheme>(m.temporal());
  s.motion.boundary = static_cast<Boundary>(m.boundary());
  s.cfl = m.cfl();
  s.compensation = static_cast<CompensationRegion>(m.compensation());
  s.compensation_method = static_cast<CompensationMethod>(m.compensation_method());
  s.shell_radii = m.shell_radii();
  s.compensation_tolerance_voxels = m.compensation_tolerance_voxels();
  s.max_compensation_iterations = static_cast<int>(m.max_compensation_iterations());
  s.gradient_descent_dt = m.gradient_descent_dt();
  s.reinit_eikonal_threshold = m.reinit_eikonal_threshold();
  s.reinit_every_k = static_cast<int>(m.reinit_every_k());
  s.reinit_iterations = static_cast<int>(m.reinit_iterations());
  s.reinit_spatial = static_cast<SpatialScheme>(m.reinit_spatial());
  s.islands = static_cast<IslandPolicy>(m.islands());
  s.min_island_volume = m.min_island_volume();
  s.min_tool_voxels = m.min_tool_voxels();
  s.max_tool_voxels = m.max_tool_voxels();
  s.max_speed_voxels = m.max_speed_voxels();
  s.max_amount_voxels = m.max_amount_voxels();
  s.repair_band_every_edit = m.repair_band_every_edit();
  return levelset::ValidEditSettings::Validate(s);
}

}  // namespace sculpt::codec
