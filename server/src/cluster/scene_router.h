/// @brief SceneRouter: where a JoinScene for a scene should be served (here, another member, or
/// nowhere right now); the session asks it before joining.
#ifndef SCULPT_SERVER_CLUSTER_SCENE_ROUTER_H_
#define SCULPT_SERVER_CLUSTER_SCENE_ROUTER_H_

#include <cstdint>
#include <string>
#include <vector>

namespace sculpt::server::cluster {

/// The answer for one scene name.
struct Route {
  enum class Kind {
    kUnknown,      // the cluster knows no such scene: the session answers as a single process
    kLocal,        // this member owns it: join here
    kRedirect,     // another member owns it: `member`, `tcp`, `http`, `epoch` name it
    kUnavailable,  // known, but nobody may serve it now: `reason` says why
  };
  Kind kind = Kind::kUnknown;
  std::string scene;  // the name asked for ("" resolved to this member's scene)
  std::string member;
  std::string tcp;   // HOST:PORT
  std::string http;  // HOST:PORT; empty when the owner has no HTTP port
  uint64_t epoch = 0;
  std::string reason;
  /// kLocal: the member this owner named the scene's standby (empty: none named yet); only its
  /// session may report the copy's durability (ReplicaProgress).
  std::string standby;
};

/// A live member's addresses as its etcd record gives them (SceneInfo.cluster_members).
struct MemberAddress {
  std::string name;
  std::string tcp;   // HOST:PORT
  std::string http;  // HOST:PORT; empty when it has no HTTP port
};

/// Answers from what the member last read from etcd, without waiting on the network: sessions
/// call it on their strand. Thread safety: RouteScene from any thread.
class SceneRouter {
 public:
  virtual ~SceneRouter() = default;
  /// `scene` empty: this member's configured scene.
  virtual Route RouteScene(const std::string& scene) const = 0;
  /// The live members as last read (this member included), in the order read; empty when none
  /// were read. From any thread.
  virtual std::vector<MemberAddress> LiveMembers() const { return {}; }
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_SCENE_ROUTER_H_
