/// @brief PlaceScenes, PickStandbys: least-loaded placement with a deterministic tie-break.
#include "cluster/placement.h"

#include <algorithm>
#include <cstdint>
#include <optional>
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

std::vector<SceneMove> PlanRebalance(const std::vector<MemberRecord>& members,
                                     const std::map<std::string, std::string>& owners,
                                     const std::map<std::string, std::string>& standbys) {
  std::map<std::string, const MemberRecord*> live;
  for (const MemberRecord& m : members) live.emplace(m.name, &m);
  std::map<std::string, std::string> owner;  // scene -> live owner, updated as moves are planned
  std::map<std::string, size_t> count;
  for (const auto& [name, m] : live) count[name] = 0;
  for (const auto& [scene, member] : owners) {
    if (live.count(member) == 0) continue;
    owner[scene] = member;
    ++count[member];
  }
  auto standby_of = [&](const std::string& scene) {
    const auto it = standbys.find(scene);
    return it == standbys.end() ? std::string() : it->second;
  };

  std::vector<SceneMove> plan;
  while (true) {
    // The best move: largest donor, then smallest taker, then a warm copy, then names.
    std::optional<std::tuple<size_t, std::string, size_t, std::string, bool, std::string>> best;
    for (const auto& [scene, from] : owner) {
      for (const auto& [to, m] : live) {
        if (to == from || !m->standby || !Offers(*m, scene) || count[from] < count[to] + 2) {
          continue;
        }
        // Ordered so that the smallest tuple is the preferred move.
        auto key = std::make_tuple(SIZE_MAX - count[from], from, count[to], to,
                                   standby_of(scene) != to, scene);
        if (!best || key < *best) best = std::move(key);
      }
    }
    if (!best) break;
    const std::string& from = std::get<1>(*best);
    const std::string& to = std::get<3>(*best);
    const std::string& scene = std::get<5>(*best);
    plan.push_back({scene, from, to});
    owner[scene] = to;
    --count[from];
    ++count[to];
  }
  return plan;
}

}  // namespace sculpt::server::cluster
