/// @brief SkinClient: a client's side of the ball skins (issue 6): ball edits and sweeps with
/// their acks, contour subscriptions, and the ContourView of each followed skin and the
/// polylines of each followed slice.
#ifndef SCULPT_CLIENT_SKIN_CLIENT_H_
#define SCULPT_CLIENT_SKIN_CLIENT_H_

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "sculpt/client/client.h"
#include "sculpt/core/status.h"
#include "sculpt/skin/contour_codec.h"
#include "sculpt/skin/oriented_ball.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::client {

/// Drives the skin messages of one joined Client. It takes the client's replication handler
/// (ContourUpdate and SkinAck arrive there), so a Client is either a Replica or a SkinClient.
/// Thread safety: every method may be called from any thread except the client's handlers;
/// destroy it before the Client.
class SkinClient {
 public:
  explicit SkinClient(Client& client);
  ~SkinClient();
  SkinClient(const SkinClient&) = delete;
  SkinClient& operator=(const SkinClient&) = delete;

  /// Each returns the edit's client_seq (its SkinAck's), or FailedPrecondition when the client
  /// is not joined. The server checks every field.
  StatusOr<uint64_t> AddBall(const std::string& skin, uint32_t index, const skin::OrientedBall& b);
  StatusOr<uint64_t> MoveBall(const std::string& skin, uint32_t index, skin::Vec2 c, double r);
  StatusOr<uint64_t> OrientBall(const std::string& skin, uint32_t index, double theta);
  StatusOr<uint64_t> RemoveBall(const std::string& skin, uint32_t index);
  /// Any edit message as the caller built it (client_seq is overwritten).
  StatusOr<uint64_t> SendEdit(v1::SkinBallEdit edit);
  StatusOr<uint64_t> Sweep(v1::SkinSweep sweep);

  /// Follows a skin (its snapshot, then updates) or a slice of an object.
  Status FollowSkin(const std::string& skin);
  Status FollowSlice(const v1::ContourSlice& slice);

  /// The SkinAck of `client_seq`; DeadlineExceeded after `timeout`.
  StatusOr<v1::SkinAck> WaitAck(uint64_t client_seq, std::chrono::milliseconds timeout);
  /// Waits until the skin's view reached `version` (ContourUpdate.skin_version).
  bool WaitSkinVersion(const std::string& skin, uint64_t version, std::chrono::milliseconds timeout);
  /// Waits until a slice of `object` showing at least edit sequence `seq` arrived.
  bool WaitSlice(const std::string& object, uint64_t seq, std::chrono::milliseconds timeout);

  /// A copy of a followed skin's view (empty before its snapshot).
  skin::ContourView View(const std::string& skin) const;
  /// The chain of balls of the skin's newest ContourUpdate (plane coordinates).
  std::vector<skin::OrientedBall> Balls(const std::string& skin) const;
  /// The sections each ContourUpdate of the skin carried, in arrival order (the snapshot first).
  std::vector<uint32_t> UpdateSections(const std::string& skin) const;
  /// The newest slice of `object`, in its plane's coordinates.
  std::vector<skin::Polyline2> Slice(const std::string& object) const;
  /// Contour bytes received (ContourUpdate.data).
  uint64_t contour_bytes() const;
  /// Updates that failed to decode or apply (a gap would show here).
  uint64_t decode_errors() const;

 private:
  void OnMessage(v1::ServerMessage&& m);
  StatusOr<uint64_t> Send(v1::ClientMessage m, uint64_t seq);

  Client& client_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  uint64_t next_seq_ = 1;
  struct Followed {
    skin::ContourView view;
    uint64_t version = 0;
    std::vector<uint32_t> sections;
    std::vector<skin::OrientedBall> balls;
  };
  std::map<std::string, Followed> skins_;
  struct SliceView {
    std::vector<skin::Polyline2> lines;
    uint64_t seq = 0;
    bool any = false;
  };
  std::map<std::string, SliceView> slices_;
  std::map<uint64_t, v1::SkinAck> acks_;
  uint64_t bytes_ = 0;
  uint64_t decode_errors_ = 0;
};

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_SKIN_CLIENT_H_
