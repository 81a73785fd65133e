/// @brief ClusterAgent::WriteMetrics: the cluster's figures on /metrics.
#include <string>

#include "cluster/cluster_agent.h"
#include "net/metrics.h"

namespace sculpt::server::cluster {

void ClusterAgent::WriteMetrics(MetricsWriter& w, uint64_t scene_seq) const {
  const auto [st, members] = ReadTable();
  const MetricLabels self = {{"member", config_.member}, {"scene", scene_}};
  w.Gauge("sculpt_cluster_owned_epoch",
          "The epoch at which this member owns its scene and may acknowledge it; 0 when it "
          "does not (another member owns it, or the lease ran out)",
          static_cast<double>(owned_epoch()), self);
  w.Gauge("sculpt_cluster_scene_epoch",
          "The newest epoch of this member's scene in etcd, whoever holds it",
          st.epoch ? static_cast<double>(st.epoch->epoch) : 0.0, {{"scene", scene_}});
  w.Gauge("sculpt_cluster_scene_owned",
          "1 when etcd names a live owner of this member's scene (any member), else 0",
          st.owner ? 1.0 : 0.0, {{"scene", scene_}});
  w.Gauge("sculpt_cluster_live_members",
          "Members with a live lease, as this member last read them from etcd",
          static_cast<double>(members.size()));
  // The owner's view of its standby: the sequence the standby's copy holds durably, as the
  // standby last published it (every lease_ttl_ms / 4), and how far that is behind this scene.
  if (owned_epoch() != 0 && st.standby) {
    for (const MemberRecord& m : members) {
      if (m.name != st.standby->member) continue;
      const MetricLabels standby = {{"scene", scene_}, {"standby", m.name}};
      w.Gauge("sculpt_cluster_standby_durable_seq",
              "The last sequence of this scene the standby's copy holds durably",
              static_cast<double>(m.follow_seq), standby);
      w.Gauge("sculpt_cluster_standby_lag_edits",
              "Edits of this scene not yet durable in the standby's copy (its published "
              "progress, up to lease_ttl_ms / 4 old)",
              scene_seq > m.follow_seq ? static_cast<double>(scene_seq - m.follow_seq) : 0.0,
              standby);
    }
  }
  // As a standby: how far this member's copy of another owner's scene is durable.
  w.Gauge("sculpt_cluster_follow_seq",
          "As a standby: the last sequence durable in this member's copy of the scene it "
          "follows (0 until it has followed one)",
          static_cast<double>(follow_seq_.load()), {{"member", config_.member}});
  w.Counter("sculpt_cluster_etcd_failures_total",
            "Lease keep-alives and cluster reads etcd did not answer",
            static_cast<double>(etcd_failures_.load()), {{"member", config_.member}});
  w.Counter("sculpt_cluster_ownership_losses_total",
            "Times this member stopped owning its scene (lease expired, or its owner key gone)",
            static_cast<double>(ownership_losses_.load()), {{"member", config_.member}});
  w.Counter("sculpt_cluster_stale_epoch_refusals_total",
            "As a standby: edit broadcasts and leaf deltas refused because their epoch was not "
            "that of the owner etcd names (each ends the follow)",
            static_cast<double>(stale_epoch_refusals_->load()), {{"member", config_.member}});
}

}  // namespace sculpt::server::cluster
