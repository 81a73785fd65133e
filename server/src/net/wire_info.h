/// @brief The scene's summary on the wire: SceneSummary (scene/scene_summary.h) to the
/// sculpt.v1.SceneInfo a joiner gets.
#ifndef SCULPT_SERVER_NET_WIRE_INFO_H_
#define SCULPT_SERVER_NET_WIRE_INFO_H_

#include <vector>

#include "cluster/scene_router.h"
#include "scene/scene_summary.h"

namespace sculpt::v1 {
class SceneInfo;
}  // namespace sculpt::v1

namespace sculpt::server {

/// The wire form (numbers the wire carries as float are rounded to float). Does not fail.
v1::SceneInfo ToWireSceneInfo(const SceneSummary& summary);

/// SceneInfo.cluster_members from the members a router read (cluster mode; nothing otherwise):
/// at most kMaxWireClusterMembers, in the order given.
inline constexpr size_t kMaxWireClusterMembers = 64;
void SetWireClusterMembers(const std::vector<cluster::MemberAddress>& members,
                           v1::SceneInfo* info);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_WIRE_INFO_H_
