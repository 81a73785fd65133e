/// @brief ResendAllowance: which edits of a reconnecting client pass the rate limits without
/// tokens (its declared resends and its resends of what the scene had committed).
#ifndef SCULPT_SERVER_NET_RESEND_ALLOWANCE_H_
#define SCULPT_SERVER_NET_RESEND_ALLOWANCE_H_

#include <array>
#include <cstdint>
#include <string>

#include "config/server_config.h"
#include "scene/commit.h"
#include "sculpt/core/status.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

/// A client that reconnects (to a restarted server, or to a new owner after a failover) resends
/// every request it has not seen answered, seconds of edits at once. Charged like new edits, a
/// burst of them runs into the stroke and pose buckets, and a refused resend is an edit the user
/// made and the scene never gets. So two kinds of edit take no tokens:
///  - those in the ranges the client declared in its JoinScene (`resends`), which it is about to
///    resend;
///  - those at or below what the scene had committed of the client's stream when it joined
///    (answered as duplicates; a client that declares nothing still gets these).
/// Either only in increasing client_seq order per stream, each sequence at most once, and at
/// most allowance() edits per connection in all; everything else is charged as usual, so
/// declaring or replaying sequences is no way around the limits.
/// Thread safety: none; one session's strand owns it.
class ResendAllowance {
 public:
  /// A declared range of client_seq, both ends included; empty when last == 0.
  struct Range {
    uint64_t first = 0;
    uint64_t last = 0;
  };
  using Ranges = std::array<Range, kResendStreams>;

  /// Seconds of strokes at limits.strokes_per_second a connection may resend free, on top of a
  /// stroke burst. A client that knows only Welcome.max_strokes_per_second declares at most
  /// this many seconds of it (proto/README.md, "Declared resends").
  static constexpr double kSeconds = 5.0;

  /// The edits a connection may pass free: limits.stroke_burst + kSeconds *
  /// limits.strokes_per_second, rounded down (0 for limits that are not finite or negative).
  static uint64_t AllowanceFor(const LimitsConfig& limits);

  /// JoinScene.resends as ranges per stream. Refused, naming the field, its value and the
  /// allowed range: more than one range for a stream or a stream out of range (kInvalidArgument),
  /// first_seq 0 or last_seq below first_seq (kInvalidArgument), more sequences in all than
  /// `allowance` (kResourceExhausted, field "JoinScene.resends").
  static StatusOr<Ranges> Decode(const v1::JoinScene& join, uint64_t allowance);

  /// Starts the connection's allowance with the client's declared ranges (at JoinScene).
  void Declare(const Ranges& declared, uint64_t allowance);
  /// What the scene had committed of the client's streams when it joined (its join state).
  void SetCommitted(const std::array<uint64_t, kResendStreams>& committed) {
    committed_ = committed;
  }

  /// True, and counted, when the edit `seq` of `stream` passes without tokens (see the class
  /// comment); false for any other edit, which is then charged.
  bool Take(ResendStream stream, uint64_t seq);

  uint64_t left() const { return left_; }

 private:
  Ranges declared_{};
  std::array<uint64_t, kResendStreams> committed_{};
  std::array<uint64_t, kResendStreams> last_free_{};
  uint64_t left_ = 0;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_RESEND_ALLOWANCE_H_
