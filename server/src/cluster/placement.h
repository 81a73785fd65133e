/// @brief Placement: which live member a scene without an owner goes to.
#ifndef SCULPT_SERVER_CLUSTER_PLACEMENT_H_
#define SCULPT_SERVER_CLUSTER_PLACEMENT_H_

#include <optional>
#include <string>
#include <vector>

#include "cluster/records.h"

namespace sculpt::server::cluster {

/// The least-loaded member among `members` that offers `scene`: fewest owned scenes, then
/// fewest sessions, then the smallest name (so every member computing it from the same records
/// picks the same one). nullopt when no member offers the scene.
std::optional<std::string> PickMember(const std::vector<MemberRecord>& members,
                                      const std::string& scene);

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_PLACEMENT_H_
