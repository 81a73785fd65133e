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

/// One step of a rebalance: `scene` goes from its owner `from` to member `to`.
struct SceneMove {
  std::string scene;
  std::string from;
  std::string to;
  bool operator==(const SceneMove&) const = default;
};

/// The moves that even out how many scenes the live `members` own (`sculpt cluster rebalance`).
/// `owners` maps each scene with a live owner to that member, `standbys` each scene to the member
/// its standby key names. While some member owns at least two scenes more than a member that
/// could take one of them (another live member offering the scene with `standby` set), one scene
/// moves: from the member owning most (then the smallest name), to the taker owning fewest (then
/// the smallest name), preferring the scene whose standby that taker already is (its copy is
/// warm), then the scene's name. Each move lowers the sum of squared counts, so the plan ends;
/// it depends only on its inputs, never on their order. Scenes whose owner is not in `members`
/// stay where they are and count for nobody.
std::vector<SceneMove> PlanRebalance(const std::vector<MemberRecord>& members,
                                     const std::map<std::string, std::string>& owners,
                                     const std::map<std::string, std::string>& standbys);

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_PLACEMENT_H_
