/// @brief What members keep in etcd (JSON values): a member's addresses and load, a scene's owner
/// and its epoch; the key layout under the cluster prefix.
#ifndef SCULPT_SERVER_CLUSTER_RECORDS_H_
#define SCULPT_SERVER_CLUSTER_RECORDS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/core/status.h"

namespace sculpt::server::cluster {

/// `members/<name>`, under the member's lease: refreshed while it lives, gone with its lease.
struct MemberRecord {
  std::string name;
  std::string tcp;                  // HOST:PORT clients are sent to
  std::string http;                 // HOST:PORT of the HTTP port, empty when off
  std::vector<std::string> offers;  // scenes this member can host (its configured scene)
  std::vector<std::string> owns;    // scenes it owns now
  uint32_t sessions = 0;            // joined sessions
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

std::string EncodeMember(const MemberRecord& m);
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
  /// The scene of an owner or epoch key and which of the two it is ("owner", "epoch"); false for
  /// another key.
  bool ParseSceneKey(const std::string& key, std::string* scene, std::string* kind) const;
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_RECORDS_H_
