/// @brief `sculpt cluster status`, `move` and `rebalance`: the subcommands' options, the etcd
/// reads and the reports.
#include "cluster_cmd.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "cluster/etcd_client.h"
#include "cluster/placement.h"
#include "cluster/records.h"

namespace sculpt::client {
namespace {

using nlohmann::json;
namespace cluster = sculpt::server::cluster;

struct SceneView {
  std::optional<cluster::OwnerRecord> owner;
  std::optional<cluster::EpochRecord> epoch;
  std::optional<std::string> standby;  // the standby key's value, raw
  std::optional<cluster::MoveRecord> move;
  int64_t move_create_revision = 0;
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
    } else if (kind == "move") {
      auto mv = cluster::DecodeMove(kv.value);
      if (mv.ok()) {
        s.move = *mv;
        s.move_create_revision = kv.create_revision;
      } else {
        s.unreadable.push_back("move: " + mv.status().ToString());
      }
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
  if (s.move) return "moving to " + s.move->member;
  if (s.owner) return "owned";
  if (s.epoch) return "no owner (last: " + s.epoch->member + ")";
  return "no owner";
}

const cluster::MemberRecord* MemberNamed(const ClusterView& v, const std::string& name) {
  for (const cluster::MemberRecord& m : v.members) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

// How far the scene's standby is behind its owner, in edits, from the two members' records
// (each as of its last refresh, every TTL/4; a member hosting several scenes lists each in its
// `owning` and `following`): nullopt when either is missing or the standby's copy is still
// loading.
std::optional<uint64_t> StandbyLag(const ClusterView& v, const std::string& name,
                                   const SceneView& s) {
  if (!s.owner || !s.standby) return std::nullopt;
  const cluster::MemberRecord* owner = MemberNamed(v, s.owner->member);
  const cluster::MemberRecord* standby = MemberNamed(v, StandbyMember(*s.standby));
  const cluster::SceneProgress* owned = owner ? owner->Owning(name) : nullptr;
  const cluster::SceneProgress* copy = standby ? standby->Following(name) : nullptr;
  if (!owned || !copy) return std::nullopt;
  return owned->seq > copy->seq ? owned->seq - copy->seq : 0;
}

// StateOf, and whether the owner's synchronous acks of this scene have fallen back to async.
std::string FullStateOf(const ClusterView& v, const std::string& name, const SceneView& s) {
  std::string state = StateOf(s);
  const cluster::MemberRecord* owner = s.owner ? MemberNamed(v, s.owner->member) : nullptr;
  const cluster::SceneProgress* owned = owner ? owner->Owning(name) : nullptr;
  if (owned && owned->acks_async) state += ", acks async (the standby is not confirming)";
  const cluster::MemberRecord* standby =
      s.standby ? MemberNamed(v, StandbyMember(*s.standby)) : nullptr;
  const cluster::SceneProgress* copy = standby ? standby->Following(name) : nullptr;
  if (copy && copy->divergences > 0) {
    state += ", the standby's copy diverged " + std::to_string(copy->divergences) + " time" +
             (copy->divergences == 1 ? "" : "s") + " (loaded anew; see both members' logs)";
  }
  return state;
}

void PrintTable(const ClusterView& v, const ClusterStatusOptions& o) {
  std::printf("cluster %s at %s: %zu member%s, %zu scene%s\n", o.prefix.c_str(),
              Join(o.etcd).c_str(), v.members.size(), v.members.size() == 1 ? "" : "s",
              v.scenes.size(), v.scenes.size() == 1 ? "" : "s");
  std::printf("\nmembers:\n%-16s  %-21s  %-21s  %8s  %-24s  %s\n", "name", "tcp", "http",
              "sessions", "owns", "follows");
  for (const cluster::MemberRecord& m : v.members) {
    std::vector<std::string> follows;
    for (const cluster::SceneProgress& p : m.following) follows.push_back(p.scene);
    std::printf("%-16s  %-21s  %-21s  %8u  %-24s  %s\n", m.name.c_str(), m.tcp.c_str(),
                m.http.empty() ? "-" : m.http.c_str(), m.sessions, Join(m.owns).c_str(),
                Join(follows).c_str());
  }
  for (const std::string& u : v.unreadable_members) std::printf("unreadable %s\n", u.c_str());
  std::printf("\nscenes:\n%-16s  %-16s  %6s  %-16s  %8s  %s\n", "scene", "owner", "epoch",
              "standby", "lag", "state");
  for (const auto& [name, s] : v.scenes) {
    const std::optional<uint64_t> lag = StandbyLag(v, name, s);
    std::printf("%-16s  %-16s  %6llu  %-16s  %8s  %s\n", name.c_str(),
                s.owner ? s.owner->member.c_str() : "-",
                static_cast<unsigned long long>(EpochOf(s)),
                s.standby ? StandbyMember(*s.standby).c_str() : "-",
                lag ? std::to_string(*lag).c_str() : "-", FullStateOf(v, name, s).c_str());
    for (const std::string& u : s.unreadable) std::printf("  unreadable %s\n", u.c_str());
  }
}

// A member's `following` / `owning` list as JSON.
json Progress(const std::vector<cluster::SceneProgress>& list, bool owner) {
  json out = json::array();
  for (const cluster::SceneProgress& p : list) {
    json j = {{"scene", p.scene}, {"seq", p.seq}};
    if (owner) j["acks_async"] = p.acks_async;
    if (!owner) j["divergences"] = p.divergences;
    out.push_back(std::move(j));
  }
  return out;
}

json ToJson(const ClusterView& v, const ClusterStatusOptions& o) {
  json members = json::array();
  for (const cluster::MemberRecord& m : v.members) {
    members.push_back({{"name", m.name},
                       {"tcp", m.tcp},
                       {"http", m.http},
                       {"offers", m.offers},
                       {"owns", m.owns},
                       {"sessions", m.sessions},
                       {"follows", m.follows},
                       {"follow_seq", m.follow_seq},
                       {"scene_seq", m.scene_seq},
                       {"acks_async", m.acks_async},
                       {"following", Progress(m.following, false)},
                       {"owning", Progress(m.owning, true)}});
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
              {"state", FullStateOf(v, name, s)},
              {"standby_lag", StandbyLag(v, name, s) ? json(*StandbyLag(v, name, s)) : json()},
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

// --etcd-ca, --etcd-cert and --etcd-key on `cmd`.
void AddEtcdTlsFlags(CLI::App* cmd, EtcdTlsFlags& f) {
  cmd->add_option("--etcd-ca", f.ca_file,
                  "PEM CA certificates etcd's certificate must chain to (https:// endpoints; "
                  "default: the system's store)")
      ->check(CLI::ExistingFile);
  CLI::Option* cert = cmd->add_option("--etcd-cert", f.cert_file,
                                      "PEM client certificate for an etcd with --client-cert-auth")
                          ->check(CLI::ExistingFile);
  CLI::Option* key =
      cmd->add_option("--etcd-key", f.key_file, "The unencrypted PEM key of --etcd-cert")
          ->check(CLI::ExistingFile);
  cert->needs(key);
  key->needs(cert);
}

StatusOr<std::unique_ptr<cluster::EtcdClient>> MakeEtcdClient(const std::vector<std::string>& etcd,
                                                              std::chrono::milliseconds timeout,
                                                              const EtcdTlsFlags& tls) {
  return cluster::EtcdClient::Create({etcd, timeout, tls.ca_file, tls.cert_file, tls.key_file});
}

// The error of a command that could not read the cluster's keys, with the check to try.
void LogUnreadable(const char* command, const std::string& prefix,
                   const std::vector<std::string>& etcd, const Status& status) {
  spdlog::error(
      "cluster {}: cannot read {} from etcd at {}: {} (is etcd running? try `etcdctl "
      "--endpoints {} endpoint health`)",
      command, prefix, Join(etcd), status.ToString(), Join(etcd));
}

}  // namespace

ClusterCommands AddClusterCommand(CLI::App& app, ClusterStatusOptions& o, ClusterMoveOptions& mo,
                                  ClusterRebalanceOptions& ro) {
  CLI::App* cluster_cmd = app.add_subcommand(
      "cluster", "Inspect a sculptd cluster (members and scenes in etcd) or move a scene");
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
                   "etcd endpoint http://HOST:PORT or https://HOST:PORT (repeatable, or "
                   "comma-separated)")
      ->required()
      ->delimiter(',');
  status->add_option("--prefix", o.prefix, "The cluster's key prefix (cluster.prefix)")
      ->capture_default_str();
  status->add_option("--timeout", o.timeout_s, "Seconds to wait for each etcd endpoint")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  status->add_flag("--json", o.json, "Print the status as JSON");
  AddEtcdTlsFlags(status, o.etcd_tls);

  CLI::App* move = cluster_cmd->add_subcommand(
      "move",
      "Move a scene to another member: the member becomes the scene's standby, catches up, and "
      "takes the scene over as in a failover (epoch + 1); no data is copied by hand");
  move->footer(
      "Writes <prefix>scenes/<scene>/move for the owner, which names MEMBER its standby, stops "
      "acknowledging once MEMBER's copy has caught up, and releases the scene when the copy holds "
      "its last edit; MEMBER then restarts on its copy and owns the scene at the next epoch. "
      "Clients reconnect and resend as after a failover. Exit status: 0 when etcd names MEMBER "
      "the owner, 1 when etcd did not answer, the owner refused the move or the timeout passed "
      "(the request is then removed and the old owner keeps the scene), 2 for a refused scene, "
      "member or option.");
  move->add_option("scene", mo.scene, "The scene to move")->required();
  move->add_option("member", mo.member, "The member that takes it over")->required();
  move->add_option("--etcd", mo.etcd,
                   "etcd endpoint http://HOST:PORT or https://HOST:PORT (repeatable, or "
                   "comma-separated)")
      ->required()
      ->delimiter(',');
  move->add_option("--prefix", mo.prefix, "The cluster's key prefix (cluster.prefix)")
      ->capture_default_str();
  move->add_option("--timeout-ms", mo.timeout_ms, "Milliseconds to wait for the move")
      ->check(CLI::Range(int64_t{100}, int64_t{3600000}))
      ->capture_default_str();
  AddEtcdTlsFlags(move, mo.etcd_tls);

  CLI::App* rebalance = cluster_cmd->add_subcommand(
      "rebalance",
      "Even out the scenes the live members own: plan the moves, print them, and make them one "
      "after another as `cluster move` does");
  rebalance->footer(
      "Placement spreads scenes only when they are first placed, so a member that joins later "
      "owns nothing until scenes are moved to it. The plan moves a scene from the member owning "
      "most to a member owning at least two fewer that offers it and may follow (cluster.standby), "
      "preferring the scene whose standby that member already is, until no such pair is left. "
      "Each move is a standby promotion: the taking member restarts on its copy, and clients "
      "reconnect and resend as after a failover. Exit status: 0 when the plan is printed "
      "(--dry-run) or every move is done (also when none is needed), 1 when etcd did not answer, "
      "a move is already under way or a move failed (the moves before it stand), 2 for a bad "
      "option.");
  rebalance
      ->add_option("--etcd", ro.etcd,
                   "etcd endpoint http://HOST:PORT or https://HOST:PORT (repeatable, or "
                   "comma-separated)")
      ->required()
      ->delimiter(',');
  rebalance->add_option("--prefix", ro.prefix, "The cluster's key prefix (cluster.prefix)")
      ->capture_default_str();
  rebalance->add_flag("--dry-run", ro.dry_run, "Print the plan and move nothing");
  rebalance->add_option("--timeout-ms", ro.timeout_ms, "Milliseconds to wait for each move")
      ->check(CLI::Range(int64_t{100}, int64_t{3600000}))
      ->capture_default_str();
  AddEtcdTlsFlags(rebalance, ro.etcd_tls);
  return {status, move, rebalance};
}

int RunClusterStatus(const ClusterStatusOptions& o) {
  auto client = MakeEtcdClient(
      o.etcd, std::chrono::milliseconds(static_cast<int64_t>(o.timeout_s * 1000)), o.etcd_tls);
  if (!client.ok()) {
    spdlog::error("cluster status: {}", client.status().ToString());
    return 2;
  }
  const cluster::Keys keys{o.prefix};
  auto kvs = (*client)->Sync((*client)->GetPrefix(o.prefix));
  if (!kvs.ok()) {
    LogUnreadable("status", o.prefix, o.etcd, kvs.status());
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

namespace {

using Clock = std::chrono::steady_clock;

// The members that could take `scene` from `owner`: live, offering it, allowed to follow.
std::vector<std::string> Takers(const ClusterView& v, const std::string& scene,
                                const std::string& owner) {
  std::vector<std::string> out;
  for (const cluster::MemberRecord& m : v.members) {
    if (m.name != owner && m.standby &&
        std::find(m.offers.begin(), m.offers.end(), scene) != m.offers.end()) {
      out.push_back(m.name);
    }
  }
  return out;
}

// Why `o.member` cannot take `o.scene` now, or empty when it can.
std::string Refusal(const ClusterView& v, const ClusterMoveOptions& o) {
  std::vector<std::string> scenes;
  for (const auto& [name, s] : v.scenes) scenes.push_back(name);
  const auto it = v.scenes.find(o.scene);
  if (it == v.scenes.end()) {
    return "scene \"" + o.scene + "\" is not in the cluster at " + o.prefix +
           " (scenes: " + Join(scenes) + ")";
  }
  const SceneView& s = it->second;
  if (!s.owner) {
    return "scene " + o.scene + " has no live owner now" +
           (s.epoch
                ? " (last: " + s.epoch->member + ", epoch " + std::to_string(s.epoch->epoch) + ")"
                : std::string()) +
           ": a move needs a live owner; wait for its takeover and try again";
  }
  const std::string takers = Join(Takers(v, o.scene, s.owner->member));
  if (o.member == s.owner->member) {
    return "member " + o.member + " already owns scene " + o.scene + " (epoch " +
           std::to_string(s.owner->epoch) +
           "): nothing to move (members that can take it: " + takers + ")";
  }
  const auto m = std::find_if(v.members.begin(), v.members.end(),
                              [&](const cluster::MemberRecord& r) { return r.name == o.member; });
  if (m == v.members.end()) {
    return "member \"" + o.member + "\" is not a live member of the cluster (members that can " +
           "take scene " + o.scene + ": " + takers + ")";
  }
  if (std::find(m->offers.begin(), m->offers.end(), o.scene) == m->offers.end()) {
    return "member " + o.member + " does not offer scene " + o.scene + " (it offers " +
           Join(m->offers) + "; members that can take it: " + takers + ")";
  }
  if (!m->standby) {
    return "member " + o.member + " may not follow a scene (its cluster.standby is false; " +
           "members that can take scene " + o.scene + ": " + takers + ")";
  }
  if (s.move && s.move->epoch == s.owner->epoch) {
    return "a move of scene " + o.scene + " to member " + s.move->member +
           " is already under way (key " + cluster::Keys{o.prefix}.Move(o.scene) +
           "); wait for it, or remove that key";
  }
  return "";
}

// Where the move stands, as one line (empty key: nothing new to say).
std::pair<std::string, std::string> Progress(const ClusterView& v, const ClusterMoveOptions& o) {
  const auto it = v.scenes.find(o.scene);
  if (it == v.scenes.end()) return {"gone", "the scene's keys are gone"};
  const SceneView& s = it->second;
  const auto m = std::find_if(v.members.begin(), v.members.end(),
                              [&](const cluster::MemberRecord& r) { return r.name == o.member; });
  if (!s.owner) {
    if (s.move && s.move->released) {
      return {"released", "the owner released the scene; member " + o.member +
                              " takes it over from its copy (it restarts on it)"};
    }
    return {"no-owner", "the scene has no owner now"};
  }
  if (!s.standby || StandbyMember(*s.standby) != o.member) {
    return {"naming", "waiting for owner " + s.owner->member + " to name member " + o.member +
                          " its standby"};
  }
  const cluster::SceneProgress* copy =
      m == v.members.end() ? nullptr : m->Following(o.scene);
  if (!copy) return {"loading", "member " + o.member + " is the standby and loads its copy"};
  return {"following", "member " + o.member + " follows; its copy holds seq " +
                           std::to_string(copy->seq) + " (the owner stops acknowledging " +
                           "once it has caught up)"};
}

}  // namespace

int RunClusterMove(const ClusterMoveOptions& o) {
  const auto start = Clock::now();
  const auto deadline = start + std::chrono::milliseconds(o.timeout_ms);
  auto client = MakeEtcdClient(
      o.etcd, std::chrono::milliseconds(std::clamp<int64_t>(o.timeout_ms, 100, 2000)), o.etcd_tls);
  if (!client.ok()) {
    spdlog::error("cluster move: {}", client.status().ToString());
    return 2;
  }
  cluster::EtcdClient& etcd = **client;
  const cluster::Keys keys{o.prefix};
  auto read = [&]() -> StatusOr<ClusterView> {
    auto kvs = etcd.Sync(etcd.GetPrefix(o.prefix));
    if (!kvs.ok()) return kvs.status();
    return Sort(*kvs, keys);
  };
  auto first = read();
  if (!first.ok()) {
    LogUnreadable("move", o.prefix, o.etcd, first.status());
    return 1;
  }
  if (const std::string why = Refusal(*first, o); !why.empty()) {
    spdlog::error("cluster move: {}", why);
    return 2;
  }
  const cluster::OwnerRecord from = *first->scenes.at(o.scene).owner;
  const std::string key = keys.Move(o.scene);
  const auto put = etcd.Sync(etcd.Put({key, cluster::EncodeMove({o.member, from.epoch}), 0}));
  auto written = put.ok() ? etcd.Sync(etcd.Get(key))
                          : StatusOr<std::optional<cluster::KeyValue>>(put.status());
  if (!written.ok() || !written->has_value()) {
    spdlog::error("cluster move: cannot write {}: {}", key,
                  written.ok() ? "it was removed at once" : written.status().ToString());
    return 1;
  }
  const int64_t created = (*written)->create_revision;
  std::printf("moving scene %s from member %s (epoch %llu) to member %s (request %s)\n",
              o.scene.c_str(), from.member.c_str(), static_cast<unsigned long long>(from.epoch),
              o.member.c_str(), key.c_str());
  std::fflush(stdout);
  std::string phase, last = "no answer from etcd yet";
  while (Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto v = read();
    if (!v.ok()) {
      last = "etcd did not answer: " + v.status().ToString();
      continue;
    }
    const auto it = v->scenes.find(o.scene);
    const SceneView* s = it != v->scenes.end() ? &it->second : nullptr;
    if (s && s->owner && s->owner->member == o.member && s->owner->epoch > from.epoch) {
      std::printf("member %s owns scene %s at epoch %llu: moved in %.2f s\n", o.member.c_str(),
                  o.scene.c_str(), static_cast<unsigned long long>(s->owner->epoch),
                  std::chrono::duration<double>(Clock::now() - start).count());
      return 0;
    }
    if (!s || !s->move || s->move->member != o.member || s->move->epoch != from.epoch) {
      spdlog::error(
          "cluster move: the request to move scene {} to member {} was removed before {} took it "
          "over: the owner refused it or another move replaced it (member {}'s log says why: "
          "\"cluster: move request of scene {} ... removed\")",
          o.scene, o.member, o.member, from.member, o.scene);
      return 1;
    }
    const auto [now_phase, line] = Progress(*v, o);
    last = line;
    if (now_phase != phase) {
      phase = now_phase;
      std::printf("  %.2f s: %s\n", std::chrono::duration<double>(Clock::now() - start).count(),
                  line.c_str());
      std::fflush(stdout);
    }
  }
  // Only our request (a later one is another operator's).
  cluster::TxnRequest txn;
  txn.compares = {{key, cluster::Compare::Target::kCreateRevision, created}};
  txn.success_deletes = {key};
  const auto removed = etcd.Sync(etcd.Txn(std::move(txn)));
  spdlog::error(
      "cluster move: member {} did not take scene {} over within --timeout-ms={} (last: "
      "{}); {}: member {} keeps the scene or takes it back",
      o.member, o.scene, o.timeout_ms, last,
      removed.ok() ? "the move request was removed"
                   : "the move request could not be removed (" + removed.status().ToString() +
                         "; remove " + key + " by hand)",
      from.member);
  return 1;
}

int RunClusterRebalance(const ClusterRebalanceOptions& o) {
  auto client = MakeEtcdClient(
      o.etcd, std::chrono::milliseconds(std::clamp<int64_t>(o.timeout_ms, 100, 2000)), o.etcd_tls);
  if (!client.ok()) {
    spdlog::error("cluster rebalance: {}", client.status().ToString());
    return 2;
  }
  cluster::EtcdClient& etcd = **client;
  auto kvs = etcd.Sync(etcd.GetPrefix(o.prefix));
  if (!kvs.ok()) {
    LogUnreadable("rebalance", o.prefix, o.etcd, kvs.status());
    return 1;
  }
  const ClusterView view = Sort(*kvs, cluster::Keys{o.prefix});
  std::map<std::string, std::string> owners, standbys;
  std::vector<std::string> unowned;
  for (const auto& [name, s] : view.scenes) {
    if (s.move && s.owner && s.move->epoch == s.owner->epoch) {
      spdlog::error(
          "cluster rebalance: a move of scene {} to member {} is under way (key {}): wait for it, "
          "or remove that key, and run the rebalance again",
          name, s.move->member, cluster::Keys{o.prefix}.Move(name));
      return 1;
    }
    if (s.owner) {
      owners[name] = s.owner->member;
    } else {
      unowned.push_back(name);
    }
    if (s.standby) standbys[name] = StandbyMember(*s.standby);
  }
  std::map<std::string, size_t> owned;
  for (const cluster::MemberRecord& m : view.members) owned[m.name] = 0;
  for (const auto& [scene, member] : owners) {
    if (owned.count(member) != 0) ++owned[member];
  }
  std::string counts;
  for (const auto& [member, n] : owned) {
    counts += (counts.empty() ? "" : ", ") + member + " " + std::to_string(n);
  }
  std::printf("cluster %s: %zu live member%s (scenes owned: %s)\n", o.prefix.c_str(),
              view.members.size(), view.members.size() == 1 ? "" : "s",
              counts.empty() ? "-" : counts.c_str());
  if (!unowned.empty()) {
    std::printf("not moved: scene%s without a live owner now: %s\n",
                unowned.size() == 1 ? "" : "s", Join(unowned).c_str());
  }
  const std::vector<cluster::SceneMove> plan =
      cluster::PlanRebalance(view.members, owners, standbys);
  if (plan.empty()) {
    std::printf("balanced: no member owns two scenes more than a member that could take one\n");
    return 0;
  }
  std::printf("plan: %zu move%s\n", plan.size(), plan.size() == 1 ? "" : "s");
  for (const cluster::SceneMove& m : plan) {
    const auto st = standbys.find(m.scene);
    std::printf("  %s: %s -> %s%s\n", m.scene.c_str(), m.from.c_str(), m.to.c_str(),
                st != standbys.end() && st->second == m.to ? " (its standby)" : "");
  }
  std::fflush(stdout);
  if (o.dry_run) return 0;

  const auto start = Clock::now();
  for (size_t i = 0; i < plan.size(); ++i) {
    std::printf("move %zu of %zu:\n", i + 1, plan.size());
    std::fflush(stdout);
    ClusterMoveOptions mo;
    mo.etcd = o.etcd;
    mo.etcd_tls = o.etcd_tls;
    mo.prefix = o.prefix;
    mo.scene = plan[i].scene;
    mo.member = plan[i].to;
    mo.timeout_ms = o.timeout_ms;
    if (const int code = RunClusterMove(mo); code != 0) {
      spdlog::error("cluster rebalance: move {} of {} (scene {} to member {}) failed; {} done, "
                    "{} not made",
                    i + 1, plan.size(), plan[i].scene, plan[i].to, i, plan.size() - i - 1);
      return 1;
    }
  }
  std::printf("rebalanced: %zu move%s in %.2f s\n", plan.size(), plan.size() == 1 ? "" : "s",
              std::chrono::duration<double>(Clock::now() - start).count());
  return 0;
}

}  // namespace sculpt::client
