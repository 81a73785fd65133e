/// @brief Session: one client of sculptd, whatever its transport: authentication, roles,
/// validation, rate limits, the hand-off of edits to the scene actor, and a bounded send queue
/// of shared frames.
#ifndef SCULPT_SERVER_NET_SESSION_H_
#define SCULPT_SERVER_NET_SESSION_H_

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

#include "net/budget_pool.h"
#include "net/net.h"
#include "net/rate_limiter.h"
#include "net/resend_allowance.h"
#include "net/transport.h"
#include "net/users.h"
#include "scene/scene.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

class Server;

/// "10.0.0.7:5555" -> "10.0.0.7", "[::1]:5555" -> "::1": limits and failed authentications are
/// counted per address, whatever port a connection comes from.
std::string SourceAddress(const std::string& remote);

/// One client connection. Its logic sees whole sculpt.v1 messages and never the framing: the
/// Transport brings them in and takes frames out. Public methods are entry points callable from
/// any thread; each gets onto the session's strand itself (posting when called elsewhere), so
/// every member is touched only there, except the presence fields (presence_mu_) and the
/// atomics the server reads for metrics.
class Session : public std::enable_shared_from_this<Session> {
 public:
  using Clock = std::chrono::steady_clock;

  /// What each request costs in the request buckets (limits.requests_per_second): per
  /// connection, per source address and per named user. Edits are counted by the stroke and
  /// pose buckets instead.
  static constexpr double kConnectionCost = 1;   // charged to the source address only
  static constexpr double kJoinCost = 4;         // the scene's state is serialised and sent
  static constexpr double kJoinSkipStateCost = 1;
  static constexpr double kSubscribeCost = 2;    // replica, viewer mesh and contour subscriptions
  static constexpr double kSetInterestCost = 1;  // a region of leaves is sent
  static constexpr double kDivergenceCost = 2;   // a log line
  static constexpr double kHoverCost = 0.05;     // presence only
  static constexpr double kHistoryCost = 1;      // up to 1000 history entries are sent

  /// `transport` must run on `strand`.
  Session(Server& server, Strand strand, std::shared_ptr<Transport> transport, uint64_t id);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  /// Arms the authentication timer and starts reading.
  void Start();
  /// Sends a Bye with `reason` and closes.
  void Shutdown(std::string reason);
  /// A connection the server does not admit: sends `error` and a Bye, closes, and logs nothing
  /// (the server logs refusals once per interval).
  void Refuse(v1::Error error);
  /// Takes a connection's cost from the source address's request budget (any thread, before
  /// Start). False when the address has none left.
  bool ChargeConnection();
  /// Queues a presence frame unless one is already waiting (coalesced) or the client has not
  /// joined.
  void DeliverPresence(Frame frame);
  /// Queues a frame built for a subscription (replication, viewer meshes, contours); such frames
  /// get the state allowance on top of the queue bound.
  void DeliverFrame(Frame frame);

  uint64_t id() const { return id_; }
  TransportKind transport_kind() const { return transport_kind_; }
  /// True once joined and until closing (any thread).
  bool joined() const { return joined_flag_.load(); }
  /// The scene bound at the first JoinScene this server accepted from the client, null before
  /// (any thread); it stays bound until the session ends.
  const Scene* joined_scene() const { return scene_flag_.load(); }
  /// ROLE_UNSPECIFIED until authenticated (any thread).
  v1::Role role() const { return role_flag_.load(); }
  /// The presence entry the server broadcasts (any thread).
  v1::PresenceEntry PresenceEntry() const;
  /// The peer's address without port (any thread).
  const std::string& source() const { return source_; }
  SharedBudget& source_budget() { return *source_budget_; }

 private:
  enum class State { kAwaitHello, kAuthenticating, kAuthed, kClosed };

  // Entry points the scene's callbacks reach (any thread; they get onto the strand).
  void OnStrokeDone(StrokeOutcome out, Clock::time_point received);
  void OnSkinAck(v1::SkinAck ack);
  void OnPaintAck(v1::PaintAck ack);
  void OnModelAck(v1::ModelAck ack);
  void OnUndoAck(v1::UndoAck ack);
  void OnHistoryAnswer(v1::HistoryAnswer answer);
  void OnJoinState(StatusOr<JoinState> state);
  void OnSubscriptionRefused(bool* flag, Status status);

  // Reading and dispatch.
  void DoRead();
  void OnRead(ReadResult result);
  void Handle(const std::string& payload);
  void OnHello(const v1::Hello& h);
  void OnAuthenticated(AuthResult r, v1::Role role, uint64_t client_id, const std::string& name);
  void OnJoin(const v1::JoinScene& j);
  // Cluster mode: redirects (or refuses) a join the router says is not served here; false when
  // it answered and the session is closing. A join served here sets `*local_scene` to the
  // scene's resolved name (unchanged when the cluster knows no such scene).
  bool RouteJoin(const v1::JoinScene& j, std::string* local_scene);
  void OnStroke(const v1::Stroke& s, Clock::time_point received);
  void OnHover(const v1::Hover& h);
  void OnSubscribe(const v1::Subscribe& sub);
  void OnSetInterest(const v1::SetInterest& si);
  void OnViewerSubscribe(const v1::ViewerSubscribe& vs);
  void OnContourSubscribe(const v1::ContourSubscribe& c);
  void OnSkinBallEdit(const v1::SkinBallEdit& e);
  void OnSkinSweep(const v1::SkinSweep& s);
  void OnPaint(const v1::PaintEdit& p);
  void OnModelIntent(const v1::ModelIntent& mi);
  void OnUndo(const v1::UndoRequest& u);
  void OnHistory(const v1::HistoryRequest& h);
  // Cluster mode: the scene's standby says how far its copy is durable (sync replication).
  void OnReplicaProgress(const v1::ReplicaProgress& p);

  // Checks shared by the edits that are not strokes: joined, sculptor, the stroke bucket.
  bool MayEdit(const char* what, ResendStream stream, uint64_t client_seq);
  // Takes one stroke and `poses` poses from this connection's, the source's and the user's
  // buckets; false, with the refusal sent and counted as a violation, when one has too few.
  // A resend the client declared at join, or of a request the scene had committed when it
  // joined, takes nothing (ResendAllowance).
  bool TakeEditTokens(double poses, Clock::time_point now, ResendStream stream,
                      uint64_t client_seq);
  // Takes `cost` from the request buckets; false, refused as above, when one has too few.
  bool Charge(const char* what, double cost, Clock::time_point now);
  // Timeouts after authentication: join (armed at Welcome), idle (armed at join), an
  // incomplete frame (armed while one is buffered).
  void ArmJoinTimer();
  void ArmIdleTimer(Clock::time_point deadline);
  void OnPartialFrame(bool partial);
  void TimedOut(v1::Error error, const std::string& reason);
  // Starts a once-per-connection subscription (see session.cc); null when refused.
  std::function<void(Status)> BeginSubscription(const char* what, bool* flag,
                                                const char* repeat_hint);
  Scene& PricingScene();
  ReplicaSink Sink();
  void Violation();

  // Sending: every message becomes one shared frame in the queue.
  void SendError(v1::Error error);
  void SendStatus(const Status& status, uint64_t client_seq = 0);
  void Send(const v1::ServerMessage& m, bool is_state = false);
  void Enqueue(Frame frame, size_t allowance, bool is_bye);
  void DoWrite();
  void OnWritten(Status status, uint64_t bytes);
  void Close(const std::string& reason, bool send_bye);
  void FinishClose();

  Server& server_;
  Strand strand_;
  std::shared_ptr<Transport> transport_;
  const TransportKind transport_kind_;
  asio::steady_timer auth_timer_;  // Hello, then JoinScene, within their timeouts
  asio::steady_timer close_timer_;
  asio::steady_timer idle_timer_;
  asio::steady_timer frame_timer_;
  bool frame_timer_armed_ = false;
  Clock::time_point last_message_;
  const uint64_t id_;
  const std::string source_;
  std::shared_ptr<SharedBudget> source_budget_;  // shared with every session of source_
  std::shared_ptr<SharedBudget> user_budget_;    // a named user's, shared likewise; else null
  bool quiet_close_ = false;

  std::deque<Frame> queue_;
  // Coalescing key (frame_key.h) -> index in queue_ of the frame waiting in that slot. The
  // queue only grows until DoWrite takes all of it, so the indices stay valid until then.
  std::unordered_map<std::string, size_t> queued_slots_;
  size_t queued_bytes_ = 0;
  size_t writing_bytes_ = 0;
  bool writing_ = false;
  bool presence_queued_ = false;

  State state_ = State::kAwaitHello;
  bool closing_ = false;
  bool joined_ = false;
  // The hosted scene this session joined (bound at its first accepted JoinScene, kept until it
  // ends); every request after the join goes to it.
  Scene* scene_ = nullptr;
  std::atomic<const Scene*> scene_flag_{nullptr};  // scene_, for the server's other threads
  bool subscribed_ = false;
  bool viewing_ = false;
  std::atomic<bool> joined_flag_{false};
  std::atomic<v1::Role> role_flag_{v1::ROLE_UNSPECIFIED};
  v1::Role role_ = v1::ROLE_UNSPECIFIED;
  uint64_t client_id_ = 0;  // the id edits are filed under (bound to the user when named)
  std::string user_;        // the authenticated user name (named users) or the claimed name
  bool peer_ = false;       // presented the cluster's peer token (a member's follower)
  bool named_ = false;      // user_ is an authenticated named user
  RateLimiter strokes_;  // strokes and every other edit message
  RateLimiter poses_;    // each pose is an edit: bounds the work one client queues
  RateLimiter requests_;  // every request that is not an edit, by its cost
  // Resends after a reconnect that take no tokens: those declared in JoinScene.resends and
  // those of requests the scene had committed when this client joined.
  ResendAllowance resends_;
  int violations_ = 0;
  // Strokes handed to the scene and not yet answered. A client disconnected for its violations
  // first gets the acks of these (draining_), so no applied stroke is reported as lost.
  uint32_t strokes_in_flight_ = 0;
  bool draining_ = false;
  std::string drain_reason_;

  mutable std::mutex presence_mu_;
  v1::PresenceEntry presence_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_SESSION_H_
