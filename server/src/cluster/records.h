/// @brief What members keep in etcd (JSON values): a member's addresses and load, a scene's owner
/// and its epoch; the key layout under the cluster prefix.
#ifndef SCULPT_SERVER_CLUSTER_RECORDS_H_
#define SCULPT_SERVER_CLUSTER_RECORDS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/core/status.h"

namespace sculpt::server::cluster {

/// One scene's progress in a member record: as standby, how far its copy is durable; as owner,
/// its last applied sequence and whether its synchronous acks fell back to async.
struct SceneProgress {
  std::string scene;
  uint64_t seq = 0;
  bool acks_async = false;  // owner only
  /// Standby only: times this member's copy of the scene diverged from the owner (a replayed
  /// edit's leaves hash differed) and was loaded anew, in its current follow.
  uint64_t divergences = 0;
};

/// `members/<name>`, under the member's lease: refreshed while it lives, gone with its lease.
struct MemberRecord {
  std::string name;
  std::string tcp;                  // HOST:PORT clients are sent to
  std::string http;                 // HOST:PORT of the HTTP port, empty when off
  std::vector<std::string> offers;  // scenes this member can host (every scene it hosts)
  std::vector<std::string> owns;    // scenes it owns now
  uint32_t sessions = 0;            // joined sessions
  bool standby = true;              // may follow another owner's scene (cluster.standby)
  // The first entry of `following` and of `owning` again, under the names members of one scene
  // each wrote (older readers read these). Decoding a record without the lists fills the lists
  // from them.
  std::string follows = {};  // the first scene it follows as standby now, empty when none
  uint64_t follow_seq = 0;   // the last sequence of it logged durably in its standby copy
  uint64_t scene_seq = 0;    // the last sequence of the first scene it owns, 0 when none
  bool acks_async = false;   // that scene is sync and has fallen back to async
  /// Every scene it follows as standby (`seq`: durable in its copy), and every scene it owns
  /// (`seq`: last applied; a standby's lag is this minus its `following` seq), in its order.
  std::vector<SceneProgress> following = {};
  std::vector<SceneProgress> owning = {};

  /// Its entry for `scene` in `following` / `owning`; null when it has none.
  const SceneProgress* Following(const std::string& scene) const;
  const SceneProgress* Owning(const std::string& scene) const;
};

/// `scenes/<scene>/owner`, under the owner's lease.
struct OwnerRecord {
  std::string member;
  std::string tcp;
  std::string http;
  uint64_t epoch = 0;
};

/// `scenes/<scene>/epoch`, without a lease: the newest epoch and who held it, so an epoch never
/// repeats and a scene whose owner died is not silently taken by a member without its data.
struct EpochRecord {
  uint64_t epoch = 0;
  std::string member;
};

/// `scenes/<scene>/standby`, without a lease (it must outlive a dead owner): the member the
/// owner chose to follow its edit stream, and the owner's epoch when it chose. Only the owner
/// writes it; the member it names may take the scene over once the owner's key is gone.
struct StandbyRecord {
  std::string member;
  uint64_t epoch = 0;
};

/// `scenes/<scene>/move`, without a lease: an operator's request (`sculpt cluster move`) that the
/// owner at `epoch` hand the scene to `member` by naming it standby and releasing the scene once
/// its copy holds every sequence. The owner rewrites it with `released` when it has deleted its
/// owner key: from then on only `member` (promoting its copy) or a removal of the request by the
/// operator ends the wait, and the old owner does not take the scene back meanwhile.
struct MoveRecord {
  std::string member;
  uint64_t epoch = 0;
  bool released = false;
};

std::string EncodeMember(const MemberRecord& m);
std::string EncodeMove(const MoveRecord& m);
StatusOr<MoveRecord> DecodeMove(const std::string& json);
std::string EncodeStandby(const StandbyRecord& s);
StatusOr<StandbyRecord> DecodeStandby(const std::string& json);
std::string EncodeOwner(const OwnerRecord& o);
std::string EncodeEpoch(const EpochRecord& e);
/// Values written by other members are checked before use: InvalidArgument naming the field
/// for a value that is not JSON, lacks a field, or has one of the wrong type or size.
StatusOr<MemberRecord> DecodeMember(const std::string& json);
StatusOr<OwnerRecord> DecodeOwner(const std::string& json);
StatusOr<EpochRecord> DecodeEpoch(const std::string& json);

/// The keys, under `prefix` (cluster.prefix).
struct Keys {
  std::string prefix;
  std::string Members() const { return prefix + "members/"; }
  std::string Member(const std::string& name) const { return Members() + name; }
  std::string Scenes() const { return prefix + "scenes/"; }
  std::string Owner(const std::string& scene) const { return Scenes() + scene + "/owner"; }
  std::string Epoch(const std::string& scene) const { return Scenes() + scene + "/epoch"; }
  std::string Standby(const std::string& scene) const { return Scenes() + scene + "/standby"; }
  std::string Move(const std::string& scene) const { return Scenes() + scene + "/move"; }
  /// The scene of an owner, epoch, standby or move key and which it is ("owner", "epoch",
  /// "standby", "move");
  /// false for another key.
  bool ParseSceneKey(const std::string& key, std::string* scene, std::string* kind) const;
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_RECORDS_H_
