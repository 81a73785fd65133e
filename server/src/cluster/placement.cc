/// @brief PickMember: least-loaded placement with a deterministic tie-break.
#include "cluster/placement.h"

#include <algorithm>
#include <tuple>

namespace sculpt::server::cluster {

std::optional<std::string> PickMember(const std::vector<MemberRecord>& members,
                                      const std::string& scene) {
  const MemberRecord* best = nullptr;
  auto load = [](const MemberRecord& m) {
    return std::make_tuple(m.owns.size(), m.sessions, std::cref(m.name));
  };
  for (const MemberRecord& m : members) {
    if (std::find(m.offers.begin(), m.offers.end(), scene) == m.offers.end()) continue;
    if (!best || load(m) < load(*best)) best = &m;
  }
  if (!best) return std::nullopt;
  return best->name;
}

}  // namespace sculpt::server::cluster
