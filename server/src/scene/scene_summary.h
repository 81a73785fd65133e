/// @brief What the scene tells clients about itself (its objects, skins, effects and limits) as
/// domain values. The session turns it into the wire's SceneInfo (net/wire_info.h).
#ifndef SCULPT_SERVER_SCENE_SCENE_SUMMARY_H_
#define SCULPT_SERVER_SCENE_SCENE_SUMMARY_H_

#include <cstdint>
#include <string>
#include <vector>

#include "config/server_config.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/tool.h"

namespace sculpt::server {

/// One object as of the last applied edit.
struct ObjectSummary {
  std::string name;
  double voxel_size = 0;
  uint32_t half_width = 0;
  levelset::Aabb bounds;  // world units
  double volume = 0;
  double reference_volume = 0;
  uint64_t state_hash = 0;  // set for a late joiner's copy only (0: not taken)
};

/// One ball skin's plane (its contours: ContourSubscribe.skin).
struct SkinSummary {
  std::string name;
  Vec3 origin, u, v;
};

/// The scene as of the last applied edit.
struct SceneSummary {
  std::string scene;
  uint64_t global_seq = 0;   // the last applied edit
  double min_tool_size = 0;  // world units
  double max_tool_size = 0;
  double max_speed = 0;
  levelset::EditSettings edit_settings;
  uint32_t replica_halo_voxels = 0;  // a subscription holds its interest box dilated by this
  EffectsConfig effects;
  std::vector<levelset::MaterialDecl> materials;  // empty: no material grids
  std::vector<ObjectSummary> objects;
  std::vector<SkinSummary> skins;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_SCENE_SUMMARY_H_
