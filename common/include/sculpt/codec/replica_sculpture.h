/// @brief The empty sculpture a replica starts from, made from the scene's SceneInfo: shared by
/// the client library's Replica and a cluster standby, which follow a scene the same way.
#ifndef SCULPT_CODEC_REPLICA_SCULPTURE_H_
#define SCULPT_CODEC_REPLICA_SCULPTURE_H_

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::v1 {
class SceneInfo;
class ObjectInfo;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// The empty sculpture a replica of `object` (one of `info`'s objects) starts from: its voxel
/// size, band and name, with the scene's materials declared (a scene with materials sends leaf
/// records with fractions, SLR2, which only a replica that declared the same materials
/// accepts). InvalidArgument naming `SceneInfo.effects.materials` when they cannot be declared.
StatusOr<levelset::Sculpture> EmptyReplicaSculpture(const v1::SceneInfo& info,
                                                    const v1::ObjectInfo& object);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_REPLICA_SCULPTURE_H_
