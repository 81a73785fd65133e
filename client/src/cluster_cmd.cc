/// @brief `sculpt cluster status`: the subcommand's options, the etcd read and the report.
#include "cluster_cmd.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "cluster/etcd_client.h"
#include "cluster/records.h"

namespace sculpt::client {
namespace {

using nlohmann::json;
namespace cluster = sculpt::server::cluster;

struct SceneView {
  std::optional<cluster::OwnerRecord> owner;
  std::optional<cluster::EpochRecord> epoch;
  std::optional<std::string> standby;  // the standby key's value, raw
  std::vector<std::string> unreadable;
};

struct ClusterView {
  std::vector<cluster::MemberRecord> members;
  std::vector<std::string> unreadable_members;  // key: reason
  std::map<std::string, SceneView> scenes;
};

// The standby's member name: the value's "member" field when it is a JSON object with one (the
// layout the standby work writes), else the value itself.
std::string StandbyMember(const std::string& value) {
  const json j = json::parse(value, nullptr, /*allow_exceptions=*/false);
  if (j.is_object() && j.contains("member") && j["member"].is_string()) {
    return j["member"].get<std::string>();
  }
  if (j.is_string()) return j.get<std::string>();
  return value;
}

ClusterView Sort(const std::vector<cluster::KeyValue>& kvs, const cluster::Keys& keys) {
  ClusterView view;
  const std::string members = keys.Members();
  const std::string scenes = keys.Scenes();
  for (const cluster::KeyValue& kv : kvs) {
    if (kv.key.rfind(members, 0) == 0) {
      auto m = cluster::DecodeMember(kv.value);
      if (m.ok()) {
        view.members.push_back(*m);
      } else {
        view.unreadable_members.push_back(kv.key + ": " + m.status().ToString());
      }
      continue;
    }
    if (kv.key.rfind(scenes, 0) != 0) continue;
    const size_t slash = kv.key.rfind('/');
    if (slash <= scenes.size()) continue;
    const std::string scene = kv.key.substr(scenes.size(), slash - scenes.size());
    const std::string kind = kv.key.substr(slash + 1);
    SceneView& s = view.scenes[scene];
    if (kind == "owner") {
      auto o = cluster::DecodeOwner(kv.value);
      if (o.ok()) {
        s.owner = *o;
      } else {
        s.unreadable.push_back("owner: " + o.status().ToString());
      }
    } else if (kind == "epoch") {
      auto e = cluster::DecodeEpoch(kv.value);
      if (e.ok()) {
        s.epoch = *e;
      } else {
        s.unreadable.push_back("epoch: " + e.status().ToString());
      }
    } else if (kind == "standby") {
      s.standby = kv.value;
    }
  }
  return view;
}

std::string Join(const std::vector<std::string>& v) {
  std::string out;
  for (const std::string& s : v) out += (out.empty() ? "" : ",") + s;
  return out.empty() ? "-" : out;
}

uint64_t EpochOf(const SceneView& s) {
  if (s.owner) return s.owner->epoch;
  return s.epoch ? s.epoch->epoch : 0;
}

std::string StateOf(const SceneView& s) {
  if (s.owner) return "owned";
  if (s.epoch) return "no owner (last: " + s.epoch->member + ")";
  return "no owner";
}

void PrintTable(const ClusterView& v, const ClusterStatusOptions& o) {
  std::printf("cluster %s at %s: %zu member%s, %zu scene%s\n", o.prefix.c_str(),
              Join(o.etcd).c_str(), v.members.size(), v.members.size() == 1 ? "" : "s",
              v.scenes.size(), v.scenes.size() == 1 ? "" : "s");
  std::printf("\nmembers:\n%-16s  %-21s  %-21s  %8s  %s\n", "name", "tcp", "http", "sessions",
              "owns");
  for (const cluster::MemberRecord& m : v.members) {
    std::printf("%-16s  %-21s  %-21s  %8u  %s\n", m.name.c_str(), m.tcp.c_str(),
                m.http.empty() ? "-" : m.http.c_str(), m.sessions, Join(m.owns).c_str());
  }
  for (const std::string& u : v.unreadable_members) std::printf("unreadable %s\n", u.c_str());
  std::printf("\nscenes:\n%-16s  %-16s  %6s  %-16s  %s\n", "scene", "owner", "epoch", "standby",
              "state");
  for (const auto& [name, s] : v.scenes) {
    std::printf("%-16s  %-16s  %6llu  %-16s  %s\n", name.c_str(),
                s.owner ? s.owner->member.c_str() : "-",
                static_cast<unsigned long long>(EpochOf(s)),
                s.standby ? StandbyMember(*s.standby).c_str() : "-", StateOf(s).c_str());
    for (const std::string& u : s.unreadable) std::printf("  unreadable %s\n", u.c_str());
  }
}

json ToJson(const ClusterView& v, const ClusterStatusOptions& o) {
  json members = json::array();
  for (const cluster::MemberRecord& m : v.members) {
    members.push_back({{"name", m.name},
                       {"tcp", m.tcp},
                       {"http", m.http},
                       {"offers", m.offers},
                       {"owns", m.owns},
                       {"sessions", m.sessions}});
  }
  json scenes = json::array();
  for (const auto& [name, s] : v.scenes) {
    json j = {{"scene", name},
              {"owner", s.owner ? json(s.owner->member) : json()},
              {"owner_tcp", s.owner ? json(s.owner->tcp) : json()},
              {"owner_http", s.owner ? json(s.owner->http) : json()},
              {"epoch", EpochOf(s)},
              {"last_owner", s.epoch ? json(s.epoch->member) : json()},
              {"standby", s.standby ? json(StandbyMember(*s.standby)) : json()},
              {"state", StateOf(s)},
              {"unreadable", s.unreadable}};
    if (s.standby) {
      const json raw = json::parse(*s.standby, nullptr, /*allow_exceptions=*/false);
      j["standby_record"] = raw.is_discarded() ? json(*s.standby) : raw;
    }
    scenes.push_back(std::move(j));
  }
  return {{"etcd", o.etcd},
          {"prefix", o.prefix},
          {"members", members},
          {"unreadable_members", v.unreadable_members},
          {"scenes", scenes}};
}

}  // namespace

CLI::App* AddClusterCommand(CLI::App& app, ClusterStatusOptions& o) {
  CLI::App* cluster_cmd =
      app.add_subcommand("cluster", "Inspect a sculptd cluster (members and scenes in etcd)");
  cluster_cmd->require_subcommand(1);
  CLI::App* status = cluster_cmd->add_subcommand(
      "status",
      "List the members (addresses, sessions, owned scenes) and the scenes (owner, "
      "epoch, standby) of a cluster, as etcd holds them now");
  status->footer(
      "Reads every key under the prefix in one etcd range (one revision, so members and owners "
      "agree). A member is listed while its lease lives; a scene whose owner's lease expired "
      "shows 'no owner' with its last owner. The standby column shows the "
      "<prefix>scenes/<scene>/standby key when a member holds one. Exit status: 0 when listed, 1 "
      "when etcd did not answer, 2 for bad options.");
  status
      ->add_option("--etcd", o.etcd,
                   "etcd endpoint http://HOST:PORT (repeatable, or comma-separated)")
      ->required()
      ->delimiter(',');
  status->add_option("--prefix", o.prefix, "The cluster's key prefix (cluster.prefix)")
      ->capture_default_str();
  status->add_option("--timeout", o.timeout_s, "Seconds to wait for each etcd endpoint")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  status->add_flag("--json", o.json, "Print the status as JSON");
  return status;
}

int RunClusterStatus(const ClusterStatusOptions& o) {
  auto client = cluster::EtcdClient::Create(
      {o.etcd, std::chrono::milliseconds(static_cast<int64_t>(o.timeout_s * 1000))});
  if (!client.ok()) {
    spdlog::error("cluster status: {}", client.status().ToString());
    return 2;
  }
  const cluster::Keys keys{o.prefix};
  auto kvs = (*client)->Sync((*client)->GetPrefix(o.prefix));
  if (!kvs.ok()) {
    spdlog::error(
        "cluster status: cannot read {} from etcd at {}: {} (is etcd running? try `etcdctl "
        "--endpoints {} endpoint health`)",
        o.prefix, Join(o.etcd), kvs.status().ToString(), Join(o.etcd));
    return 1;
  }
  const ClusterView view = Sort(*kvs, keys);
  if (o.json) {
    std::printf("%s\n", ToJson(view, o).dump(2).c_str());
  } else {
    PrintTable(view, o);
  }
  return 0;
}

}  // namespace sculpt::client
