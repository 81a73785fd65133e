// The empty sculpture a replica starts from (sculpt/codec/replica_sculpture.h).
#include "sculpt/codec/replica_sculpture.h"

#include <string>
#include <vector>

#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {

StatusOr<levelset::Sculpture> EmptyReplicaSculpture(const v1::SceneInfo& info,
                                                    const v1::ObjectInfo& object) {
  levelset::SculptureOptions so;
  so.voxel_size = object.voxel_size();
  so.half_width = static_cast<int>(object.half_width());
  so.name = object.name();
  auto empty = levelset::MakeEmptySculpture(so);
  if (!empty.ok()) return empty.status();
  const v1::Effects& fx = info.effects();
  if (fx.materials_size() > 0) {
    std::vector<levelset::MaterialDecl> materials;
    const bool coloured = fx.material_colours_size() == 3 * fx.materials_size();
    for (int m = 0; m < fx.materials_size(); ++m) {
      levelset::MaterialDecl d;
      d.name = fx.materials(m);
      if (coloured) {
        for (int c = 0; c < 3; ++c) d.colour[c] = fx.material_colours(3 * m + c);
      }
      materials.push_back(std::move(d));
    }
    if (const Status st = levelset::SetMaterials(*empty, materials); !st.ok()) {
      return InvalidArgument("SceneInfo.effects.materials: " + st.message());
    }
  }
  return empty;
}

}  // namespace sculpt::codec
