/// @brief ReplicaSink: where a session's replication and mesh frames go from the scene.
#ifndef SCULPT_SERVER_SCENE_REPLICA_SINK_H_
#define SCULPT_SERVER_SCENE_REPLICA_SINK_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace sculpt::server {

/// Where a subscription's messages go: `send` takes one length-prefixed ServerMessage frame
/// (shared by every session that gets the same bytes), may be called from the compute thread,
/// and must only post.
struct ReplicaSink {
  uint64_t session_id = 0;
  uint64_t client_id = 0;
  bool standby = false;  // cluster mode: the session of the scene's named standby
  std::function<void(std::shared_ptr<const std::string>)> send;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_REPLICA_SINK_H_
