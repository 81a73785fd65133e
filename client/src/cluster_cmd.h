/// @brief `sculpt cluster status`: a cluster's members (addresses, load, owned scenes) and scenes
/// (owner, epoch, standby), read from etcd; `cluster move` and `cluster rebalance`, which move
/// scenes between members (issue 17).
#ifndef SCULPT_CLIENT_CLUSTER_CMD_H_
#define SCULPT_CLIENT_CLUSTER_CMD_H_

#include <cstdint>
#include <string>
#include <vector>

namespace CLI {
class App;
}  // namespace CLI

namespace sculpt::client {

/// TLS to etcd (https:// endpoints): --etcd-ca, --etcd-cert, --etcd-key, as the members'
/// cluster.etcd_ca_file, etcd_cert_file and etcd_key_file.
struct EtcdTlsFlags {
  std::string ca_file;  // empty: the system's CA store
  std::string cert_file;
  std::string key_file;
};

struct ClusterStatusOptions {
  std::vector<std::string> etcd;  // http://HOST:PORT or https://HOST:PORT, tried in turn
  EtcdTlsFlags etcd_tls;
  std::string prefix = "sculpt/";  // cluster.prefix of the members
  double timeout_s = 2;            // per etcd endpoint
  bool json = false;
};

struct ClusterMoveOptions {
  std::vector<std::string> etcd;
  EtcdTlsFlags etcd_tls;
  std::string prefix = "sculpt/";
  std::string scene;
  std::string member;
  int64_t timeout_ms = 30000;  // for the whole move
};

struct ClusterRebalanceOptions {
  std::vector<std::string> etcd;
  EtcdTlsFlags etcd_tls;
  std::string prefix = "sculpt/";
  bool dry_run = false;
  int64_t timeout_ms = 30000;  // for each move
};

struct ClusterCommands {
  CLI::App* status = nullptr;
  CLI::App* move = nullptr;
  CLI::App* rebalance = nullptr;
};

/// Adds the `cluster` subcommand with its `status`, `move` and `rebalance` subcommands, storing
/// into the options (which must outlive parsing).
ClusterCommands AddClusterCommand(CLI::App& app, ClusterStatusOptions& status,
                                  ClusterMoveOptions& move, ClusterRebalanceOptions& rebalance);

/// Reads every key under the prefix in one etcd range (one revision: a consistent picture) and
/// prints members and scenes (a table, or JSON with --json). Returns the exit code: 0 when
/// printed (also for an empty cluster), 1 when no etcd endpoint answered or etcd refused the
/// read, 2 for a malformed --etcd URL. A value that does not decode (another version's
/// member, a forged key) is shown as unreadable, not trusted.
int RunClusterStatus(const ClusterStatusOptions& options);

/// `sculpt cluster move SCENE MEMBER` (docs/cluster.md "Moving a scene"): checks that the scene
/// has a live owner and that MEMBER is another live member offering the scene and able to
/// follow, writes `<prefix>scenes/<scene>/move` (the member and the owner's epoch) and waits,
/// printing progress, until etcd names MEMBER the owner at a higher epoch. Returns 0 then; 2 for
/// a refused scene or member (the message names the value and what is allowed) or a malformed
/// URL; 1 when etcd does not answer, the owner removed the request, or the timeout passed (the
/// request is then removed, and the old owner keeps or takes back the scene).
int RunClusterMove(const ClusterMoveOptions& options);

/// `sculpt cluster rebalance` (docs/cluster.md "Rebalancing"): reads the cluster once, plans the
/// moves that even out the scenes each live member owns (server::cluster::PlanRebalance) and
/// prints them; without --dry-run it then makes them one after another, each as `cluster move`
/// does, and stops at the first that fails. Returns 0 when the plan is printed (--dry-run) or
/// every move is done (also when none was needed); 1 when etcd does not answer, a move of a
/// scene is already under way, or a move fails (the moves before it stand); 2 for a malformed URL.
int RunClusterRebalance(const ClusterRebalanceOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_CLUSTER_CMD_H_
