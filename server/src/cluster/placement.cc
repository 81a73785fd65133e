/// @brief PlaceScenes, PickStandbys: least-loaded placement with a deterministic tie-break.
#include "cluster/placement.h"

#include <algorithm>
#include <set>
#include <tuple>

namespace sculpt::server::cluster {
namespace {

bool Offers(const MemberRecord& m, const std::string& scene) {
  return std::find(m.offers.begin(), m.offers.end(), scene) != m.offers.end();
}

// For each scene in name order, the member offering it with the smallest (base load + picks
// earlier in this pass, sessions, name); each pick adds one to its member's load.
template <typename BaseLoad>
std::map<std::string, std::string> Spread(const std::vector<MemberRecord>& members,
                                          const std::vector<std::string>& scenes,
                                          BaseLoad base) {
  const std::set<std::string> ordered(scenes.begin(), scenes.end());
  std::map<std::string, size_t> added;
  std::map<std::string, std::string> picks;
  for (const std::string& scene : ordered) {
    const MemberRecord* best = nullptr;
    auto load = [&](const MemberRecord& m) {
      const auto it = added.find(m.name);
      return std::make_tuple(base(m) + (it == added.end() ? 0 : it->second), m.sessions,
                             std::cref(m.name));
    };
    for (const MemberRecord& m : members) {
      if (!Offers(m, scene)) continue;
      if (!best || load(m) < load(*best)) best = &m;
    }
    if (!best) continue;
    picks[scene] = best->name;
    ++added[best->name];
  }
  return picks;
}

}  // namespace

std::optional<std::string> PickMember(const std::vector<MemberRecord>& members,
                                      const std::string& scene) {
  const auto picks = PlaceScenes(members, {scene});
  const auto it = picks.find(scene);
  if (it == picks.end()) return std::nullopt;
  return it->second;
}

std::map<std::string, std::string> PlaceScenes(const std::vector<MemberRecord>& members,
                                               const std::vector<std::string>& scenes) {
  return Spread(members, scenes, [](const MemberRecord& m) { return m.owns.size(); });
}

std::map<std::string, std::string> PickStandbys(const std::vector<MemberRecord>& candidates,
                                                const std::vector<std::string>& scenes) {
  return Spread(candidates, scenes,
                [](const MemberRecord& m) { return m.owns.size() + m.following.size(); });
}

}  // namespace sculpt::server::cluster
