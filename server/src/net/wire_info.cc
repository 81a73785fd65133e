/// @brief SceneSummary to sculpt.v1.SceneInfo.
#include "net/wire_info.h"

#include "sculpt/codec/settings.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

v1::SceneInfo ToWireSceneInfo(const SceneSummary& s) {
  v1::SceneInfo info;
  info.set_scene(s.scene);
  info.set_global_seq(s.global_seq);
  info.set_min_tool_size(static_cast<float>(s.min_tool_size));
  info.set_max_tool_size(static_cast<float>(s.max_tool_size));
  info.set_max_speed(static_cast<float>(s.max_speed));
  *info.mutable_edit_settings() = codec::SettingsToProto(s.edit_settings);
  info.set_replica_halo_voxels(s.replica_halo_voxels);
  v1::Effects* e = info.mutable_effects();
  e->set_volume_preservation(s.effects.volume_preservation);
  e->set_smoothing(s.effects.smoothing);
  e->set_islands(s.effects.islands);
  e->set_min_island_volume(s.effects.min_island_volume);
  e->set_contours(s.effects.contours);
  e->set_band_repair(s.effects.band_repair);
  for (const levelset::MaterialDecl& m : s.materials) {
    e->add_materials(m.name);
    for (double c : m.colour) e->add_material_colours(static_cast<float>(c));
  }
  for (const ObjectSummary& o : s.objects) {
    v1::ObjectInfo* w = info.add_objects();
    w->set_name(o.name);
    w->set_voxel_size(o.voxel_size);
    w->set_half_width(o.half_width);
    *w->mutable_bounds_min() = codec::ToProto(o.bounds.min);
    *w->mutable_bounds_max() = codec::ToProto(o.bounds.max);
    w->set_volume(o.volume);
    w->set_reference_volume(o.reference_volume);
    w->set_state_hash(o.state_hash);
  }
  for (const SkinSummary& k : s.skins) {
    v1::SkinInfo* m = info.add_skins();
    m->set_name(k.name);
    *m->mutable_origin() = codec::ToProto(k.origin);
    *m->mutable_u() = codec::ToProto(k.u);
    *m->mutable_v() = codec::ToProto(k.v);
  }
  return info;
}

void SetWireClusterMembers(const std::vector<cluster::MemberAddress>& members,
                           v1::SceneInfo* info) {
  info->clear_cluster_members();
  for (const cluster::MemberAddress& m : members) {
    if (static_cast<size_t>(info->cluster_members_size()) >= kMaxWireClusterMembers) break;
    v1::ClusterMember* w = info->add_cluster_members();
    w->set_name(m.name);
    w->set_tcp_address(m.tcp);
    w->set_http_address(m.http);
  }
}

}  // namespace sculpt::server
