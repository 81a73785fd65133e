/// @brief `sculpt cluster status`: a cluster's members (addresses, load, owned scenes) and scenes
/// (owner, epoch, standby), read from etcd (issue 17).
#ifndef SCULPT_CLIENT_CLUSTER_CMD_H_
#define SCULPT_CLIENT_CLUSTER_CMD_H_

#include <string>
#include <vector>

namespace CLI {
class App;
}  // namespace CLI

namespace sculpt::client {

struct ClusterStatusOptions {
  std::vector<std::string> etcd;   // http://HOST:PORT, tried in turn
  std::string prefix = "sculpt/";  // cluster.prefix of the members
  double timeout_s = 2;            // per etcd endpoint
  bool json = false;
};

/// Adds the `cluster` subcommand with its `status` subcommand, storing into `options` (which
/// must outlive parsing); returns `status`.
CLI::App* AddClusterCommand(CLI::App& app, ClusterStatusOptions& options);

/// Reads every key under the prefix in one etcd range (one revision: a consistent picture) and
/// prints members and scenes (a table, or JSON with --json). Returns the exit code: 0 when
/// printed (also for an empty cluster), 1 when no etcd endpoint answered or etcd refused the
/// read, 2 for a malformed --etcd URL. A value that does not decode (another version's
/// member, a forged key) is shown as unreadable, not trusted.
int RunClusterStatus(const ClusterStatusOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_CLUSTER_CMD_H_
