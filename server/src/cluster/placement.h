/// @brief Placement: which live member a scene without an owner goes to, and which member an
/// owner names its scenes' standby.
#ifndef SCULPT_SERVER_CLUSTER_PLACEMENT_H_
#define SCULPT_SERVER_CLUSTER_PLACEMENT_H_

#include <map>
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

/// Placement of several never-owned scenes at once: the scenes are taken in name order (each
/// once), and each goes to the member PickMember would choose if every scene placed before it in
/// this pass were already among its picked member's owned scenes. So new scenes spread (6 over 3
/// idle members: 2 each) instead of all going to the member least loaded before the pass, and
/// the result depends only on the records, not on the order of `members` or `scenes`: every
/// member computes the same picks. A scene no member offers is left out.
std::map<std::string, std::string> PlaceScenes(const std::vector<MemberRecord>& members,
                                               const std::vector<std::string>& scenes);

/// An owner's choice of standbys for `scenes` among `candidates` (the other live members that may
/// follow): for each scene in name order, the candidate offering it with the fewest owned plus
/// followed scenes (counting the picks made earlier in this pass), then fewest sessions, then the
/// smallest name. Only the owner computes it, so it needs no agreement; it spreads the copies.
std::map<std::string, std::string> PickStandbys(const std::vector<MemberRecord>& candidates,
                                                const std::vector<std::string>& scenes);

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_PLACEMENT_H_
