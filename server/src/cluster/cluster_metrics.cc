/// @brief ClusterAgent::WriteMetrics: the cluster's figures on /metrics.
#include <string>

#include "cluster/cluster_agent.h"
#include "net/metrics.h"

namespace sculpt::server::cluster {

void ClusterAgent::WriteMetrics(MetricsWriter& w) const {
  std::vector<MemberRecord> members;
  std::vector<SceneState> states;
  {
    std::lock_guard<std::mutex> lock(mu_);
    members = members_;
    for (const auto& slot : slots_) {
      const auto it = scenes_.find(slot->hosted.name);
      states.push_back(it != scenes_.end() ? it->second : SceneState{});
    }
  }
  // Family by family (the text format keeps a family's samples together), a sample per scene.
  for (const auto& slot : slots_) {
    w.Gauge("sculpt_cluster_owned_epoch",
            "The epoch at which this member owns the scene and may acknowledge it; 0 when it "
            "does not (another member owns it, or the lease ran out)",
            static_cast<double>(owned_epoch(slot->hosted.name)),
            {{"member", config_.member}, {"scene", slot->hosted.name}});
  }
  for (size_t i = 0; i < slots_.size(); ++i) {
    w.Gauge("sculpt_cluster_scene_epoch",
            "The newest epoch of a scene this member hosts in etcd, whoever holds it",
            states[i].epoch ? static_cast<double>(states[i].epoch->epoch) : 0.0,
            {{"scene", slots_[i]->hosted.name}});
  }
  for (size_t i = 0; i < slots_.size(); ++i) {
    w.Gauge("sculpt_cluster_scene_owned",
            "1 when etcd names a live owner of a scene this member hosts (any member), else 0",
            states[i].owner ? 1.0 : 0.0, {{"scene", slots_[i]->hosted.name}});
  }
  // The owner's view of its standbys: the sequence each standby's copy holds durably, as the
  // standby last published it (every lease_ttl_ms / 4), and how far that is behind the scene.
  struct Lag {
    MetricLabels labels;
    uint64_t durable = 0;
    uint64_t behind = 0;
  };
  std::vector<Lag> lags;
  for (size_t i = 0; i < slots_.size(); ++i) {
    const Slot& slot = *slots_[i];
    const SceneState& st = states[i];
    if (owned_epoch(slot.hosted.name) == 0 || !st.standby) continue;
    const uint64_t scene_seq = slot.hosted.seq ? slot.hosted.seq() : 0;
    for (const MemberRecord& m : members) {
      if (m.name != st.standby->member) continue;
      const SceneProgress* copy = m.Following(slot.hosted.name);
      const uint64_t durable = copy ? copy->seq : 0;
      lags.push_back({{{"scene", slot.hosted.name}, {"standby", m.name}},
                      durable,
                      scene_seq > durable ? scene_seq - durable : 0});
    }
  }
  for (const Lag& l : lags) {
    w.Gauge("sculpt_cluster_standby_durable_seq",
            "The last sequence of this scene the standby's copy holds durably",
            static_cast<double>(l.durable), l.labels);
  }
  for (const Lag& l : lags) {
    w.Gauge("sculpt_cluster_standby_lag_edits",
            "Edits of this scene not yet durable in the standby's copy (its published "
            "progress, up to lease_ttl_ms / 4 old)",
            static_cast<double>(l.behind), l.labels);
  }
  // As a standby: how far this member's copy of each scene (owned by another member) is
  // durable.
  for (const auto& slot : slots_) {
    w.Gauge("sculpt_cluster_follow_seq",
            "As a standby: the last sequence durable in this member's copy of the scene (0 "
            "until it has followed it)",
            static_cast<double>(slot->follow_seq.load()),
            {{"member", config_.member}, {"scene", slot->hosted.name}});
  }
  w.Gauge("sculpt_cluster_live_members",
          "Members with a live lease, as this member last read them from etcd",
          static_cast<double>(members.size()));
  w.Counter("sculpt_cluster_etcd_failures_total",
            "Lease keep-alives and cluster reads etcd did not answer",
            static_cast<double>(etcd_failures_.load()), {{"member", config_.member}});
  w.Counter("sculpt_cluster_ownership_losses_total",
            "Times this member stopped owning a scene (lease expired, or its owner key gone)",
            static_cast<double>(ownership_losses_.load()), {{"member", config_.member}});
  w.Counter("sculpt_cluster_stale_epoch_refusals_total",
            "As a standby: edit broadcasts and leaf deltas refused because their epoch was not "
            "that of the owner etcd names (each ends the follow)",
            static_cast<double>(stale_epoch_refusals_->load()), {{"member", config_.member}});
  w.Counter("sculpt_cluster_standby_divergences_total",
            "As a standby: replayed edits whose leaves hash differed from the owner's (each "
            "reported to the owner, and the copy's object loaded anew)",
            static_cast<double>(standby_divergences_->load()), {{"member", config_.member}});
}

}  // namespace sculpt::server::cluster
