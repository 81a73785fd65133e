/// @brief The replication requests off the wire (issue 4: Subscribe, SetInterest) and the viewer
/// mesh subscription (ViewerSubscribe), decoded into domain requests. The checks that need the object (it exists, the interest box's extent
/// in voxels, have_seq against the server's sequence) are the scene's.
#ifndef SCULPT_CODEC_REPLICA_MESSAGES_H_
#define SCULPT_CODEC_REPLICA_MESSAGES_H_

#include <cstdint>
#include <optional>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"

namespace sculpt::v1 {
class Subscribe;
class SetInterest;
class ViewerSubscribe;
class DivergenceReport;
class ReplicaProgress;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// How a replica is kept current (values as on the wire).
enum class ReplicaMode : uint8_t {
  kReplay = 1,     // EditBroadcast: the logged edits, replayed by the same kernel
  kLeafDelta = 2,  // LeafDelta after every edit: the changed leaves' values
};

/// A world box (from the wire's floats), both corners finite; max >= min is the scene's check.
struct InterestBox {
  Vec3 min;
  Vec3 max;
};

/// A validated Subscribe.
struct ReplicaSubscription {
  std::string object;
  ReplicaMode mode = ReplicaMode::kReplay;
  std::optional<InterestBox> interest;  // unset: the whole object
  uint64_t have_seq = 0;
};

/// A validated SetInterest.
struct InterestChange {
  std::string object;
  std::optional<InterestBox> interest;  // unset: the whole object
};

/// A validated ViewerSubscribe.
struct ViewerSubscription {
  std::string object;
  /// At most this many mesh updates a second, in [0.1, 120]; 0: the server's default.
  double max_rate_hz = 0;
};

/// A replica's report that its hash of an edit's leaves differed from the server's.
struct Divergence {
  std::string object;  // as the replica sent it (a name for the log, not looked up)
  uint64_t global_seq = 0;
  uint64_t expected_hash = 0;
  uint64_t actual_hash = 0;
};

/// Cluster mode: a standby's word on how far its copy of `object` is durable.
struct ReplicaProgress {
  std::string object;
  uint64_t durable_seq = 0;
};

/// Checks a Subscribe: mode REPLAY or LEAF_DELTA, a set interest box's corners finite.
/// InvalidArgument "Subscribe.<field>=<value> outside <range>" (or "... is not finite").
StatusOr<ReplicaSubscription> DecodeSubscribe(const v1::Subscribe& request);
/// Checks a SetInterest: a set interest box's corners finite. InvalidArgument naming the field.
StatusOr<InterestChange> DecodeSetInterest(const v1::SetInterest& request);
/// Checks a ViewerSubscribe: max_rate_hz 0 or finite in [0.1, 120]. InvalidArgument
/// "ViewerSubscribe.max_rate_hz=<value> outside [0.1, 120] (0: the server's default)".
StatusOr<ViewerSubscription> DecodeViewerSubscribe(const v1::ViewerSubscribe& request);
/// A DivergenceReport's fields (every value is acceptable: it is only counted and logged).
Divergence DecodeDivergenceReport(const v1::DivergenceReport& report);
/// Checks a ReplicaProgress's form: InvalidArgument "ReplicaProgress.object= outside 1 to 256
/// bytes" or "ReplicaProgress.durable_seq=0 outside [1, 2^64 - 1]". Whether the object exists,
/// the sequence was reached and the sender is the standby is the server's check.
StatusOr<ReplicaProgress> DecodeReplicaProgress(const v1::ReplicaProgress& progress);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_REPLICA_MESSAGES_H_
