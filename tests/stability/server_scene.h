/// @brief The default scene's clay and edit settings (deploy/scene.toml) for the stability tests,
/// which do not link the server: what server::EditSettingsFor makes of that file.
#ifndef SCULPT_TESTS_STABILITY_SERVER_SCENE_H_
#define SCULPT_TESTS_STABILITY_SERVER_SCENE_H_

#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset::testing {

inline constexpr double kSphereRadius = 24.0;  // the default scene's clay, world units

/// Voxel 0.5, half-width 6, object "clay".
inline SculptureOptions ServerOpts() {
  SculptureOptions o;
  o.voxel_size = 0.5;
  o.half_width = 6;
  o.name = "clay";
  return o;
}

/// Shell compensation, remove_small islands below 8 units^3, tool sizes 0.5..16, speeds up to
/// 2000, amounts up to 8 (in voxels of 0.5).
inline EditSettings ServerSettings() {
  EditSettings e;
  e.compensation = CompensationRegion::kShell;
  e.islands = IslandPolicy::kRemoveSmall;
  e.min_island_volume = 8.0;
  e.min_tool_voxels = 0.5 / 0.5;
  e.max_tool_voxels = 16.0 / 0.5;
  e.max_speed_voxels = 2000.0 / 0.5;
  e.max_amount_voxels = 8.0 / 0.5;
  return e;
}

}  // namespace sculpt::levelset::testing

#endif  // SCULPT_TESTS_STABILITY_SERVER_SCENE_H_
