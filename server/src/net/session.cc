/// @brief Session: authentication, validation, rate limits, the scene hand-off and the bounded
/// send queue of one client, independent of its transport.
#include "net/session.h"

#include "cluster/scene_router.h"

#include <sodium.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "config/seats.h"
#include "net/frame_key.h"
#include "net/server.h"
#include "net/untrusted_text.h"
#include "net/wire_acks.h"
#include "net/wire_error.h"
#include "net/wire_info.h"
#include "sculpt/codec/shared_frame.h"
#include "sculpt/codec/model_messages.h"
#include "sculpt/codec/paint_messages.h"
#include "sculpt/codec/replica_messages.h"
#include "sculpt/codec/skin_messages.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/codec/undo.h"

namespace sculpt::server {
namespace {

constexpr uint32_t kProtocolVersion = 1;
constexpr size_t kStateChunkBytes = 256 * 1024;
// Late-join state and subscription frames may exceed the queue bound by this much.
constexpr size_t kStateAllowanceBytes = 64u << 20;
// How long a Bye may take to leave before the connection is closed regardless.
constexpr auto kByeGrace = std::chrono::milliseconds(500);
// How long a client being disconnected for violations waits for its accepted strokes' acks.
constexpr auto kDrainLimit = std::chrono::seconds(5);

// Whose share of the scene's compute thread a session's requests take (Scene::RequesterScope):
// a named user's, wherever it connects from, else its source address's, like the rate budgets.
// More sessions or reconnecting buy no larger share. Never 0 (the scene's own work).
uint64_t ComputeOwner(bool named, const std::string& user, const std::string& source) {
  const uint64_t h = std::hash<std::string>{}(named ? "user " + user : "source " + source);
  return h == 0 ? 1 : h;
}

// Cluster mode: whether a session is the scene's standby, as this owner names it in etcd. Its
// Hello says `standby-<member>`; when the cluster has a peer token (cluster.peer_token), the
// session must also have presented it, so a viewer-token holder claiming the name is not taken
// for the standby.
bool IsSceneStandby(const cluster::Route& route, const std::string& user, bool peer,
                    const ServerConfig& config) {
  return route.kind == cluster::Route::Kind::kLocal && !route.standby.empty() &&
         user == "standby-" + route.standby && (peer || config.cluster.peer_token.empty());
}

// The id a named user's client_id is filed under: 64 bits of BLAKE2b(user, client_id), never 0.
uint64_t BoundClientId(const std::string& user, uint64_t client_id) {
  std::string in = user;
  in.push_back('\0');
  for (int i = 0; i < 8; ++i) in.push_back(static_cast<char>((client_id >> (8 * i)) & 0xff));
  unsigned char h[16];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(in.data()), in.size(),
                     nullptr, 0);
  uint64_t id = 0;
  for (int i = 0; i < 8; ++i) id |= static_cast<uint64_t>(h[i]) << (8 * i);
  return id == 0 ? 1 : id;
}

uint32_t ColorFor(uint64_t id) {
  static const uint32_t kColors[] = {0xe6194bff, 0x3cb44bff, 0x4363d8ff, 0xf58231ff,
                                     0x911eb4ff, 0x46f0f0ff, 0xf032e6ff, 0xbcf60cff};
  return kColors[id % 8];
}

size_t Index(TransportKind k) { return static_cast<size_t>(k); }

std::string Num(double v) {
  std::string s = std::to_string(v);
  s.erase(s.find_last_not_of('0') + 1);
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// A request for a region of leaves (Subscribe, SetInterest) is charged by what it may make the
// server send: its base cost plus 1 per kRegionVoxelsPerToken voxels of its box clipped to the
// object's bounds (the whole object when unset), at most half the request burst so that any
// region can be asked for. An unknown object costs the base (the scene refuses it).
constexpr double kRegionVoxelsPerToken = 64.0 * 64.0 * 64.0;

double RegionCost(const v1::SceneInfo& info, const std::string& object, const v1::Box3* box,
                  double base, double burst) {
  for (const v1::ObjectInfo& o : info.objects()) {
    if (o.name() != object || !(o.voxel_size() > 0)) continue;
    const float lo[3] = {o.bounds_min().x(), o.bounds_min().y(), o.bounds_min().z()};
    const float hi[3] = {o.bounds_max().x(), o.bounds_max().y(), o.bounds_max().z()};
    double voxels = 1;
    for (int a = 0; a < 3; ++a) {
      double l = lo[a], h = hi[a];
      if (box) {
        const float bl[3] = {box->min().x(), box->min().y(), box->min().z()};
        const float bh[3] = {box->max().x(), box->max().y(), box->max().z()};
        // NaN bounds compare false and leave the object's: the scene refuses them anyway.
        if (bl[a] > l) l = bl[a];
        if (bh[a] < h) h = bh[a];
      }
      voxels *= std::max(0.0, (h - l) / o.voxel_size());
    }
    return std::min(base + voxels / kRegionVoxelsPerToken, std::max(base, burst / 2));
  }
  return base;
}

}  // namespace

std::string SourceAddress(const std::string& remote) {
  if (!remote.empty() && remote.front() == '[') {
    const size_t close = remote.find(']');
    return close == std::string::npos ? remote : remote.substr(1, close - 1);
  }
  const size_t colon = remote.rfind(':');
  return colon == std::string::npos ? remote : remote.substr(0, colon);
}

const char* TransportName(TransportKind kind) {
  return kind == TransportKind::kWebSocket ? "ws" : "tcp";
}

Session::Session(Server& server, Strand strand, std::shared_ptr<Transport> transport, uint64_t id)
    : server_(server),
      strand_(std::move(strand)),
      transport_(std::move(transport)),
      transport_kind_(transport_->kind()),
      auth_timer_(strand_),
      close_timer_(strand_),
      idle_timer_(strand_),
      frame_timer_(strand_),
      id_(id),
      source_(SourceAddress(transport_->remote())),
      source_budget_(server.budgets().Get("addr:" + source_,
                                          server.config().limits.source_rate_factor)),
      strokes_(server.config().limits.strokes_per_second, server.config().limits.stroke_burst),
      poses_(server.config().limits.poses_per_second, server.config().limits.pose_burst),
      requests_(server.config().limits.requests_per_second, server.config().limits.request_burst) {}

Session::~Session() = default;

// ---- Entry points: each gets onto the strand itself ----------------------------------------

void Session::Start() {
  if (!strand_.running_in_this_thread()) {
    return asio::dispatch(strand_, [self = shared_from_this()] { self->Start(); });
  }
  const int timeout_ms = server_.config().limits.auth_timeout_ms;
  auth_timer_.expires_after(std::chrono::milliseconds(timeout_ms));
  auth_timer_.async_wait([self = shared_from_this(), timeout_ms](boost::system::error_code ec) {
    if (ec || (self->state_ != State::kAwaitHello && self->state_ != State::kAuthenticating)) {
      return;
    }
    self->SendError(ProtocolError(v1::ERROR_CODE_UNAUTHENTICATED, "Hello", "none",
                                  "within " + std::to_string(timeout_ms) + " ms",
                                  "no Hello received in time"));
    self->Close("authentication timeout", true);
  });
  DoRead();
}

void Session::Refuse(v1::Error error) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), error = std::move(error)]() mutable {
      self->Refuse(std::move(error));
    });
  }
  quiet_close_ = true;
  const std::string reason = error.message();
  SendError(std::move(error));
  Close(reason, true);
}

bool Session::ChargeConnection() {
  return source_budget_->TryTake(SharedBudget::Kind::kRequests, kConnectionCost, Clock::now());
}

void Session::Shutdown(std::string reason) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), reason = std::move(reason)]() mutable {
      self->Shutdown(std::move(reason));
    });
  }
  Close(reason, true);
}

void Session::DeliverPresence(Frame frame) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), frame = std::move(frame)]() mutable {
      self->DeliverPresence(std::move(frame));
    });
  }
  if (!joined_ || closing_ || presence_queued_) return;
  presence_queued_ = true;
  Enqueue(std::move(frame), 0, false);
}

void Session::DeliverFrame(Frame frame) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), frame = std::move(frame)]() mutable {
      self->DeliverFrame(std::move(frame));
    });
  }
  if (closing_) return;
  // A viewer that falls behind gets the newest version of each mesh chunk, never a backlog of
  // versions: a chunk frame still waiting in the queue is replaced in place by the newer one.
  std::string key = CoalescingKey(*frame);
  if (!key.empty()) {
    if (auto it = queued_slots_.find(key); it != queued_slots_.end()) {
      Frame& slot = queue_[it->second];
      queued_bytes_ = queued_bytes_ - slot->size() + frame->size();
      slot = std::move(frame);
      server_.stats().frames_superseded++;
      return;
    }
  }
  Enqueue(std::move(frame), kStateAllowanceBytes, false);
  // Still queued (a write is in flight): remember its slot.
  if (!key.empty() && !closing_ && !queue_.empty()) {
    queued_slots_[std::move(key)] = queue_.size() - 1;
  }
}

void Session::OnStrokeDone(StrokeOutcome out, Clock::time_point received) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), out = std::move(out),
                                received]() mutable { self->OnStrokeDone(std::move(out), received); });
  }
  if (strokes_in_flight_ > 0) --strokes_in_flight_;
  if (closing_) return;
  if (!out.status.ok()) {
    server_.stats().strokes_refused++;
    SendStatus(out.status, out.client_seq);
    if (draining_ && strokes_in_flight_ == 0) Close(drain_reason_, true);
    return;
  }
  server_.stats().strokes_accepted++;
  v1::ServerMessage m;
  v1::Ack* a = m.mutable_ack();
  a->set_client_seq(out.client_seq);
  a->set_global_seq_first(out.global_seq_first);
  a->set_edits(out.edits);
  a->set_duplicate(out.duplicate);
  v1::EditSummary* sum = a->mutable_summary();
  sum->set_changed_voxels(static_cast<uint32_t>(out.last.changed_voxels));
  sum->set_dirty_leaves(static_cast<uint32_t>(out.last.dirty_leaves.size()));
  sum->set_volume_after(out.last.volume_after);
  sum->set_reference_volume(out.last.reference_volume);
  sum->set_substeps(static_cast<uint32_t>(out.last.substeps));
  sum->set_reinit_passes(static_cast<uint32_t>(out.last.reinit_passes));
  sum->set_islands_removed(static_cast<uint32_t>(out.last.islands_removed));
  sum->set_elapsed_ms(static_cast<float>(out.last.elapsed_ms));
  // Observed before the Ack is queued, so whoever has read the Ack sees it counted.
  server_.stats().stroke_ack_seconds[Index(transport_kind_)].Observe(
      std::chrono::duration<double>(Clock::now() - received).count());
  Send(m);
  if (draining_ && strokes_in_flight_ == 0) Close(drain_reason_, true);
}

// Refusals go out twice: as the generic Error, and in the ack the client waits for. The Error
// carries client_seq 0: these sequences are not a stroke's and must not settle one.
void Session::OnSkinAck(v1::SkinAck a) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), a = std::move(a)]() mutable {
      self->OnSkinAck(std::move(a));
    });
  }
  if (closing_) return;
  if (!a.accepted()) {
    server_.stats().strokes_refused++;
    v1::Error e = a.error();
    e.set_client_seq(0);
    SendError(std::move(e));
  }
  v1::ServerMessage m;
  *m.mutable_skin_ack() = std::move(a);
  Send(m);
}

void Session::OnPaintAck(v1::PaintAck a) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), a = std::move(a)]() mutable {
      self->OnPaintAck(std::move(a));
    });
  }
  if (closing_) return;
  if (!a.accepted()) {
    server_.stats().strokes_refused++;
    v1::Error e = a.error();
    e.set_client_seq(0);
    SendError(std::move(e));
  } else if (!a.duplicate()) {
    server_.stats().strokes_accepted++;
  }
  v1::ServerMessage m;
  *m.mutable_paint_ack() = std::move(a);
  Send(m);
}

void Session::OnModelAck(v1::ModelAck a) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), a = std::move(a)]() mutable {
      self->OnModelAck(std::move(a));
    });
  }
  if (closing_) return;
  if (!a.accepted()) {
    server_.stats().strokes_refused++;
    if (a.has_error()) {
      v1::Error e = a.error();
      e.set_client_seq(0);
      SendError(std::move(e));
    }
  } else if (!a.duplicate()) {
    server_.stats().strokes_accepted++;
  }
  v1::ServerMessage m;
  *m.mutable_model_ack() = std::move(a);
  Send(m);
}

void Session::OnUndoAck(v1::UndoAck a) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), a = std::move(a)]() mutable {
      self->OnUndoAck(std::move(a));
    });
  }
  if (closing_) return;
  // A refused undo (nothing to undo, beyond the history) is an answer, not a violation: the
  // ack carries the error.
  v1::ServerMessage m;
  *m.mutable_undo_ack() = std::move(a);
  Send(m);
}

void Session::OnJoinState(StatusOr<JoinState> js) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), js = std::move(js)]() mutable {
      self->OnJoinState(std::move(js));
    });
  }
  if (closing_) return;
  if (!js.ok()) {
    // Not joined: the client may ask again (a refusal over limits.max_pending_joins says so).
    joined_ = false;
    joined_flag_ = false;
    return SendStatus(js.status());
  }
  resends_.SetCommitted(js->committed_up_to);
  v1::ServerMessage info;
  *info.mutable_scene_info() = ToWireSceneInfo(js->info);
  if (const cluster::SceneRouter* router = server_.router()) {
    SetWireClusterMembers(router->LiveMembers(), info.mutable_scene_info());
  }
  Send(info);
  // The state goes out in chunks, queued behind nothing else of this session; other sessions
  // are not touched (late join without stalling the others).
  for (auto& [name, bytes] : js->objects) {
    const uint32_t count =
        static_cast<uint32_t>((bytes.size() + kStateChunkBytes - 1) / kStateChunkBytes);
    for (uint32_t i = 0; i < count; ++i) {
      v1::ServerMessage m;
      v1::StateChunk* c = m.mutable_state_chunk();
      c->set_object(name);
      c->set_global_seq(js->info.global_seq);
      c->set_index(i);
      c->set_count(count);
      c->set_data(bytes.substr(i * kStateChunkBytes, kStateChunkBytes));
      Send(m, /*is_state=*/true);
      if (closing_) return;
    }
  }
}

void Session::OnSubscriptionRefused(bool* flag, Status st) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), flag, st = std::move(st)]() mutable {
      self->OnSubscriptionRefused(flag, std::move(st));
    });
  }
  if (flag) *flag = false;
  SendStatus(st);
  Violation();
}

v1::PresenceEntry Session::PresenceEntry() const {
  std::lock_guard<std::mutex> lock(presence_mu_);
  return presence_;
}

// ---- Reading and dispatch (on the strand) --------------------------------------------------

void Session::DoRead() {
  if (closing_) return;
  transport_->AsyncRead([self = shared_from_this()](ReadResult r) { self->OnRead(std::move(r)); });
}

void Session::OnRead(ReadResult r) {
  if (closing_) return;
  ServerStats& stats = server_.stats();
  stats.bytes_in[Index(transport_kind_)] += r.bytes;
  if (!r.payloads.empty()) last_message_ = Clock::now();
  for (const std::string& payload : r.payloads) {
    stats.messages_in[Index(transport_kind_)]++;
    Handle(payload);
    if (closing_) return;
  }
  switch (r.end) {
    case ReadResult::End::kNone:
      OnPartialFrame(r.partial);
      return DoRead();
    case ReadResult::End::kClosed: return Close(r.reason.message(), false);
    case ReadResult::End::kTooLarge:
      SendStatus(r.reason);
      return Close("oversized frame", true);
    case ReadResult::End::kMalformed:
      SendError(ProtocolError(v1::ERROR_CODE_MALFORMED, "frame", r.reason.message(),
                              "binary messages, each a serialized sculpt.v1.ClientMessage",
                              "unsupported framing"));
      return Close("malformed framing", true);
  }
}

void Session::Handle(const std::string& payload) {
  if (draining_) return;  // being disconnected: only the pending acks go out
  // The compute work this message asks for is scheduled as its owner's (a fair share).
  const Scene::RequesterScope requester(ComputeOwner(user_budget_ != nullptr, user_, source_));
  const Clock::time_point received = Clock::now();
  v1::ClientMessage msg;
  if (!msg.ParseFromString(payload)) {
    // The stream cannot be trusted after a frame that does not parse.
    SendError(ProtocolError(v1::ERROR_CODE_MALFORMED, "frame",
                            std::to_string(payload.size()) + " bytes",
                            "a serialized sculpt.v1.ClientMessage", "frame does not parse"));
    return Close("malformed frame", true);
  }
  switch (msg.body_case()) {
    case v1::ClientMessage::kHello: return OnHello(msg.hello());
    case v1::ClientMessage::kJoin: return OnJoin(msg.join());
    case v1::ClientMessage::kStroke: return OnStroke(msg.stroke(), received);
    case v1::ClientMessage::kHover: return OnHover(msg.hover());
    case v1::ClientMessage::kBye:
      // The reason is the client's text: bounded and escaped before it reaches the log.
      return Close("client said bye: " + Printable(msg.bye().reason()), false);
    case v1::ClientMessage::kSubscribe: return OnSubscribe(msg.subscribe());
    case v1::ClientMessage::kSetInterest: return OnSetInterest(msg.set_interest());
    case v1::ClientMessage::kDivergence: {
      // Each report is a log line: charged, and its object name bounded and escaped.
      if (!subscribed_ || !Charge("DivergenceReport", kDivergenceCost, received)) return;
      v1::DivergenceReport r = msg.divergence();
      r.set_object(Printable(r.object()));
      scene_->ReportDivergence(id_, codec::DecodeDivergenceReport(r));
      return;
    }
    case v1::ClientMessage::kViewerSubscribe: return OnViewerSubscribe(msg.viewer_subscribe());
    case v1::ClientMessage::kSkinBallEdit: return OnSkinBallEdit(msg.skin_ball_edit());
    case v1::ClientMessage::kContourSubscribe: return OnContourSubscribe(msg.contour_subscribe());
    case v1::ClientMessage::kSkinSweep: return OnSkinSweep(msg.skin_sweep());
    case v1::ClientMessage::kPaint: return OnPaint(msg.paint());
    case v1::ClientMessage::kModelIntent: return OnModelIntent(msg.model_intent());
    case v1::ClientMessage::kUndo: return OnUndo(msg.undo());
    case v1::ClientMessage::kHistory: return OnHistory(msg.history());
    case v1::ClientMessage::kReplicaProgress:
      return OnReplicaProgress(msg.replica_progress());
    case v1::ClientMessage::BODY_NOT_SET: break;
  }
  SendError(ProtocolError(
      v1::ERROR_CODE_MALFORMED, "ClientMessage.body", "unknown or empty",
      "{hello, join, stroke, hover, bye, subscribe, set_interest, divergence, viewer_subscribe, "
      "skin_ball_edit, contour_subscribe, skin_sweep, paint, model_intent, undo, history, "
      "replica_progress}",
      "unknown message"));
  Violation();
}

void Session::OnHello(const v1::Hello& h) {
  if (state_ != State::kAwaitHello) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "Hello", "repeated",
                            "once per connection", "already authenticated"));
    return Violation();
  }
  if (h.protocol_version() != kProtocolVersion) {
    SendError(ProtocolError(v1::ERROR_CODE_VERSION_MISMATCH, "Hello.protocol_version",
                            std::to_string(h.protocol_version()), "[1, 1]",
                            "this server speaks protocol version 1; update the client"));
    return Close("protocol version mismatch", true);
  }
  if (h.role() != v1::ROLE_SCULPTOR && h.role() != v1::ROLE_VIEWER) {
    SendError(ProtocolError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hello.role",
                            std::to_string(h.role()), "{ROLE_SCULPTOR, ROLE_VIEWER}",
                            "unknown role"));
    return Close("bad role", true);
  }
  if (h.client_id() == 0) {
    // Resends are de-duplicated on (client_id, client_seq) across restarts, so the id must be
    // the client's own, stable one; a server-made id would collide after a restart.
    SendError(ProtocolError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hello.client_id", "0",
                            "[1, 2^64 - 1]",
                            "choose a random client id once and keep it across reconnects"));
    return Close("client_id 0", true);
  }
  if (h.client_name().size() > 64) {
    SendError(ProtocolError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hello.client_name",
                            std::to_string(h.client_name().size()) + " bytes", "[0, 64] bytes",
                            "name too long"));
    return Close("bad name", true);
  }
  if (server_.auth().named_users()) {
    if (const Status n = CheckUserName("Hello.client_name", h.client_name()); !n.ok()) {
      SendError(ProtocolError(v1::ERROR_CODE_UNAUTHENTICATED, "Hello.client_name", "(hidden)",
                              "a user of the users file: 1 to 64 characters of [A-Za-z0-9._-]",
                              "this server has named users: give your user name"));
      return Close("bad user name", true);
    }
  }
  state_ = State::kAuthenticating;
  const UserRole role = h.role() == v1::ROLE_SCULPTOR ? UserRole::kSculptor : UserRole::kViewer;
  server_.auth().Authenticate(
      h.client_name(), h.token(), role, SourceAddress(transport_->remote()),
      [self = shared_from_this(), role = h.role(), client_id = h.client_id(),
       name = h.client_name()](AuthResult r) mutable {
        asio::post(self->strand_, [self, r = std::move(r), role, client_id,
                                   name = std::move(name)]() mutable {
          self->OnAuthenticated(std::move(r), role, client_id, name);
        });
      });
}

void Session::OnAuthenticated(AuthResult r, v1::Role role, uint64_t client_id,
                              const std::string& name) {
  if (state_ != State::kAuthenticating) return;  // closed meanwhile (auth timeout, shutdown)
  switch (r.outcome) {
    case AuthResult::Outcome::kOk:
      break;
    case AuthResult::Outcome::kPermissionDenied:
      SendError(ProtocolError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.role",
                              v1::Role_Name(role), "the user's role", r.message));
      return Close("role not allowed", true);
    case AuthResult::Outcome::kBackoff:
    case AuthResult::Outcome::kBusy:
      SendError(ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "Hello", "authentication",
                              "after earlier failures, wait", r.message));
      return Close("authentication backoff", true);
    case AuthResult::Outcome::kUnauthenticated:
      SendError(ProtocolError(
          v1::ERROR_CODE_UNAUTHENTICATED, "Hello.token", "(hidden)",
          server_.auth().named_users() ? "the token of the named user (users file)"
                                       : "the configured token of the requested role",
          "wrong token"));
      return Close("wrong token", true);
  }
  const ServerConfig& c = server_.config();
  auth_timer_.cancel();
  state_ = State::kAuthed;
  // A named user's sessions share one budget, wherever they connect from: reconnecting, or
  // opening more connections, buys no more strokes.
  if (r.named) user_budget_ = server_.budgets().Get("user:" + r.user, 1.0);
  ArmJoinTimer();
  role_ = role;
  role_flag_ = role_;
  // With named users, edits are filed under an id bound to the user: another user presenting
  // the same client_id gets another id, so it can neither pass for this client nor have this
  // client's strokes taken for resends.
  client_id_ = r.named ? BoundClientId(r.user, client_id) : client_id;
  user_ = r.user;
  peer_ = r.peer;
  if (r.peer) spdlog::info("session {}: cluster peer {} from {}", id_, r.user, transport_->remote());
  named_ = r.named;  // the scene joined names the author (OnJoin)
  {
    std::lock_guard<std::mutex> lock(presence_mu_);
    presence_.set_session_id(id_);
    presence_.set_name(name.empty() ? "user-" + std::to_string(id_) : name);
    presence_.set_color_rgba(ColorFor(id_));
    presence_.set_role(role_);
  }
  if (r.named) spdlog::info("session {}: user {} ({}) from {}", id_, r.user,
                            v1::Role_Name(role), transport_->remote());
  v1::ServerMessage out;
  v1::Welcome* w = out.mutable_welcome();
  w->set_protocol_version(kProtocolVersion);
  w->set_session_id(id_);
  w->set_role(role_);
  for (const Scene* scene : server_.scenes()) w->add_scenes(scene->name());
  w->set_max_frame_bytes(c.limits.max_frame_bytes);
  w->set_max_poses_per_stroke(c.limits.max_poses_per_stroke);
  w->set_max_stroke_work(c.limits.max_stroke_work);
  w->set_max_strokes_per_second(static_cast<float>(c.limits.strokes_per_second));
  w->set_client_id(client_id_);
  w->set_user(r.named ? r.user : std::string());
  Send(out);
}

bool Session::RouteJoin(const v1::JoinScene& j, std::string* local_scene) {
  // Cluster mode: the routing table is read without waiting on etcd (cluster/cluster_agent.h).
  const cluster::Route r = server_.router()->RouteScene(j.scene());
  switch (r.kind) {
    case cluster::Route::Kind::kLocal:
      *local_scene = r.scene;  // "" resolved to the member's scene
      return true;
    case cluster::Route::Kind::kUnknown:
      return true;
    case cluster::Route::Kind::kRedirect: {
      v1::ServerMessage m;
      v1::Redirect* d = m.mutable_redirect();
      d->set_scene(r.scene);
      d->set_member(r.member);
      d->set_tcp_address(r.tcp);
      d->set_http_address(r.http);
      d->set_epoch(r.epoch);
      Send(m);
      // The Bye follows the Redirect out before the connection closes.
      Close("redirected to member " + r.member + " (" + r.tcp + "), the owner of scene " + r.scene,
            true);
      return false;
    }
    case cluster::Route::Kind::kUnavailable:
      SendError(ProtocolError(v1::ERROR_CODE_UNAVAILABLE, "JoinScene.scene", r.scene,
                              "scenes with a live owner", r.reason));
      Close("scene " + r.scene + " unavailable", true);
      return false;
  }
  return true;
}

void Session::OnJoin(const v1::JoinScene& j) {
  if (state_ != State::kAuthed) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "JoinScene", "before Hello",
                            "after Hello", "authenticate first"));
    return Close("join before hello", true);
  }
  if (!Charge("JoinScene", j.skip_state() ? kJoinSkipStateCost : kJoinCost, Clock::now())) return;
  std::string name = j.scene();
  if (!joined_ && server_.router() && !RouteJoin(j, &name)) return;
  // An empty name joins the default scene (the first hosted).
  Scene* const target = name.empty() ? &server_.scene() : server_.FindScene(name);
  if (!target) {
    std::string hosted;
    for (const Scene* scene : server_.scenes()) {
      hosted += (hosted.empty() ? "" : ", ") + scene->name();
    }
    SendError(ProtocolError(v1::ERROR_CODE_NOT_FOUND, "JoinScene.scene", name, "{" + hosted + "}",
                            "unknown scene"));
    return Violation();
  }
  if (joined_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "JoinScene", "repeated",
                            "once per connection", "already joined"));
    return Violation();
  }
  // A join the scene refused (OnJoinState) may be asked again, of the same scene: the session's
  // subscriptions and author name stay with the scene it was bound to.
  if (scene_ && target != scene_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "JoinScene.scene", name,
                            "{" + scene_->name() + "} (the scene this connection asked first)",
                            "a connection joins one scene"));
    return Violation();
  }
  const uint64_t allowance = ResendAllowance::AllowanceFor(server_.config().limits);
  auto declared = ResendAllowance::Decode(j, allowance);
  if (!declared.ok()) {
    SendStatus(declared.status());
    return Violation();
  }
  // Seats are counted per scene: each hosted scene has max_clients_per_scene of its own.
  const Server::Seats seats = server_.JoinedSeats(*target);
  const uint32_t max_clients = server_.config().limits.max_clients_per_scene;
  if (seats.joined >= max_clients) {
    SendError(ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "clients",
                            std::to_string(seats.joined), "[0, " + std::to_string(max_clients) + "]",
                            "scene full"));
    return Close("scene full", true);
  }
  // The last reserved_sculptor_seats seats are for sculptors: viewers alone cannot fill a scene
  // so that nobody may sculpt.
  const size_t viewer_seats = ViewerSeats(server_.config().limits);
  const size_t reserved = max_clients - viewer_seats;
  if (role_ == v1::ROLE_VIEWER && seats.viewers >= viewer_seats) {
    SendError(ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "viewers",
                            std::to_string(seats.viewers),
                            "[0, " + std::to_string(viewer_seats) + "] (" +
                                std::to_string(reserved) + " of " + std::to_string(max_clients) +
                                " seats reserved for sculptors)",
                            "no seat left for viewers"));
    return Close("no seat left for viewers", true);
  }
  if (!scene_) {
    scene_ = target;
    scene_flag_ = target;  // before joined_flag_: a joined session always names its scene
    if (named_) scene_->NameAuthor(client_id_, user_);  // in its log records and history
  }
  joined_ = true;
  joined_flag_ = true;
  resends_.Declare(*declared, allowance);
  if (const int idle = server_.config().limits.idle_timeout_ms; idle > 0) {
    last_message_ = Clock::now();
    ArmIdleTimer(last_message_ + std::chrono::milliseconds(idle));
  }
  if (j.skip_state()) {
    // A replica loads its region through Subscribe: scene info only.
    v1::ServerMessage info;
    *info.mutable_scene_info() = ToWireSceneInfo(scene_->Info());
    if (const cluster::SceneRouter* router = server_.router()) {
      SetWireClusterMembers(router->LiveMembers(), info.mutable_scene_info());
    }
    return Send(info);
  }
  scene_->RequestJoinState(
      [self = shared_from_this()](StatusOr<JoinState> js) { self->OnJoinState(std::move(js)); },
      client_id_);
}

void Session::OnStroke(const v1::Stroke& s, Clock::time_point received) {
  if (!joined_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "Stroke", "before JoinScene",
                            "after JoinScene", "join a scene first", s.client_seq()));
    return Violation();
  }
  if (role_ != v1::ROLE_SCULPTOR) {
    server_.stats().strokes_refused++;
    SendError(ProtocolError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.role", "ROLE_VIEWER",
                            "{ROLE_SCULPTOR}", "viewers may not edit", s.client_seq()));
    return Violation();
  }
  if (!TakeEditTokens(static_cast<double>(s.pose_count()), received, ResendStream::kStrokes,
                      s.client_seq())) {
    return;
  }
  auto limits = scene_->LimitsFor(s.object());
  if (!limits.ok()) {
    server_.stats().strokes_refused++;
    SendStatus(limits.status(), s.client_seq());
    return Violation();
  }
  auto decoded = codec::DecodeStroke(s, *limits);
  if (!decoded.ok()) {
    server_.stats().strokes_refused++;
    SendStatus(decoded.status(), s.client_seq());
    return Violation();
  }
  {
    std::lock_guard<std::mutex> lock(presence_mu_);
    *presence_.mutable_position() = codec::ToProto(decoded->poses.back().position);
    presence_.set_radius(s.tool_size().x());
  }
  ++strokes_in_flight_;
  scene_->Submit(client_id_, std::move(decoded).value(),
                 [self = shared_from_this(), received](const StrokeOutcome& out) {
                   self->OnStrokeDone(out, received);
                 });
}

void Session::OnHover(const v1::Hover& h) {
  if (!joined_ || !Charge("Hover", kHoverCost, Clock::now())) return;
  if (!std::isfinite(h.position().x()) || !std::isfinite(h.position().y()) ||
      !std::isfinite(h.position().z()) || !std::isfinite(h.radius())) {
    SendError(ProtocolError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hover.position", "not finite",
                            "finite numbers", "hover must be finite"));
    return Violation();
  }
  std::lock_guard<std::mutex> lock(presence_mu_);
  *presence_.mutable_position() = h.position();
  presence_.set_radius(h.radius());
}

// A Subscribe or SetInterest is charged before the join check refuses one sent too early: the
// joined scene prices it, or the default scene before a join.
Scene& Session::PricingScene() { return scene_ ? *scene_ : server_.scene(); }

ReplicaSink Session::Sink() {
  ReplicaSink sink;
  sink.session_id = id_;
  sink.client_id = client_id_;
  // Cluster mode: the scene's named standby (as for ReplicaProgress: its Hello name, and the
  // peer token when the cluster has one) gets the resend table with its region loads.
  if (const cluster::SceneRouter* router = server_.router()) {
    sink.standby = IsSceneStandby(router->RouteScene(scene_ ? scene_->name() : ""), user_, peer_,
                                  server_.config());
  }
  // Weak: a subscription the scene still holds must not keep a closed session alive.
  std::weak_ptr<Session> weak = shared_from_this();
  sink.send = [weak](std::shared_ptr<const std::string> frame) {
    if (auto self = weak.lock()) self->DeliverFrame(std::move(frame));
  };
  return sink;
}

// Starts a once-per-connection subscription: refuses one before JoinScene or a repeat, else sets
// `*flag`. The returned callback reports the scene's refusal (and clears the flag).
std::function<void(Status)> Session::BeginSubscription(const char* what, bool* flag,
                                                       const char* repeat_hint) {
  if (!joined_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, what, "before JoinScene",
                            "after JoinScene", "join a scene first"));
    Violation();
    return nullptr;
  }
  if (flag && *flag) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, what, "repeated",
                            "once per connection", repeat_hint));
    Violation();
    return nullptr;
  }
  if (flag) *flag = true;
  return [self = shared_from_this(), flag](Status st) {
    if (!st.ok()) self->OnSubscriptionRefused(flag, std::move(st));
  };
}

void Session::OnSubscribe(const v1::Subscribe& sub) {
  const double cost = RegionCost(ToWireSceneInfo(PricingScene().Info()), sub.object(),
                                 sub.has_interest() ? &sub.interest() : nullptr, kSubscribeCost,
                                 server_.config().limits.request_burst);
  if (!Charge("Subscribe", cost, Clock::now())) return;
  auto done = BeginSubscription("Subscribe", &subscribed_, "use SetInterest to move the region");
  if (!done) return;
  auto request = codec::DecodeSubscribe(sub);
  if (!request.ok()) return done(request.status());
  scene_->Subscribe(Sink(), std::move(request).value(), std::move(done));
}

void Session::OnSetInterest(const v1::SetInterest& si) {
  const double cost = RegionCost(ToWireSceneInfo(PricingScene().Info()), si.object(),
                                 si.has_interest() ? &si.interest() : nullptr, kSetInterestCost,
                                 server_.config().limits.request_burst);
  if (!Charge("SetInterest", cost, Clock::now())) return;
  auto done = BeginSubscription("SetInterest", nullptr, "");
  if (!done) return;
  auto request = codec::DecodeSetInterest(si);
  if (!request.ok()) return done(request.status());
  scene_->SetInterest(id_, std::move(request).value(), std::move(done));
}

// Not charged when accepted: the named standby sends one per sync of its copy's log (a few
// hundred a second at most); refusals are charged or counted as violations.
void Session::OnReplicaProgress(const v1::ReplicaProgress& p) {
  const cluster::SceneRouter* router = server_.router();
  if (!router) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "ReplicaProgress", "sent",
                            "cluster mode only", "this server is not a cluster member"));
    return Violation();
  }
  if (!subscribed_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "ReplicaProgress",
                            "before Subscribe", "after a Subscribe",
                            "only a standby following the scene reports progress"));
    return Violation();
  }
  // The follower says who it is in its Hello (client_name "standby-<member>"); only the member
  // this owner named in etcd counts, and with cluster.peer_token only a session that presented
  // it (without one: as strong as the viewer token it connected with).
  const cluster::Route route = router->RouteScene(scene_ ? scene_->name() : "");
  if (!IsSceneStandby(route, user_, peer_, server_.config())) {
    // Charged rather than counted as a violation: a member just named standby may report before
    // this owner's routing table (up to one tick old) names it, and must not be disconnected
    // for that; anyone else sending these runs out of request tokens.
    if (!Charge("ReplicaProgress", kDivergenceCost, Clock::now())) return;
    if (!route.standby.empty() && user_ == "standby-" + route.standby) {
      // The right name without the peer token: a viewer passing for the standby.
      SendError(ProtocolError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.token", "(hidden)",
                              "the cluster's peer token (cluster.peer_token)",
                              "ReplicaProgress is accepted only from the scene's standby, which "
                              "says Hello with the members' peer token"));
      return;
    }
    SendError(ProtocolError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.client_name", user_,
                            route.standby.empty() ? std::string("the scene's named standby (none)")
                                                  : "standby-" + route.standby,
                            "ReplicaProgress is accepted only from the scene's standby"));
    return;
  }
  auto progress = codec::DecodeReplicaProgress(p);
  if (progress.ok() && !scene_->LimitsFor(progress->object).ok()) {
    progress =
        Outside("ReplicaProgress.object", Printable(progress->object), "an object of this scene");
  }
  if (progress.ok() && progress->durable_seq > scene_->global_seq()) {
    progress = Outside("ReplicaProgress.durable_seq", std::to_string(progress->durable_seq),
                       "[1, " + std::to_string(scene_->global_seq()) +
                           "] (the scene's last applied sequence)");
  }
  if (!progress.ok()) {
    SendStatus(progress.status());
    return Violation();
  }
  scene_->StandbyDurable(progress->durable_seq);
}

void Session::OnViewerSubscribe(const v1::ViewerSubscribe& vs) {
  if (!Charge("ViewerSubscribe", kSubscribeCost, Clock::now())) return;
  auto done = BeginSubscription("ViewerSubscribe", &viewing_, "already subscribed to meshes");
  if (!done) return;
  auto request = codec::DecodeViewerSubscribe(vs);
  if (!request.ok()) return done(request.status());
  scene_->SubscribeViewer(Sink(), std::move(request).value(), std::move(done));
}

void Session::OnContourSubscribe(const v1::ContourSubscribe& c) {
  if (!Charge("ContourSubscribe", kSubscribeCost, Clock::now())) return;
  if (!joined_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "ContourSubscribe",
                            "before JoinScene", "after JoinScene", "join a scene first"));
    return Violation();
  }
  auto request = codec::DecodeContourSubscribe(c);
  if (!request.ok()) {
    SendStatus(request.status());
    return Violation();
  }
  scene_->SubscribeContours(Sink(), std::move(request).value(),
                            [self = shared_from_this()](Status st) {
                              if (!st.ok()) {
                                self->OnSubscriptionRefused(nullptr, std::move(st));
                              }
                            });
}

// Ball edits, sweeps, paints and model intents are strokes too: joined sculptors only, the
// stroke token bucket, every field checked here before the scene sees it.
bool Session::MayEdit(const char* what, ResendStream stream, uint64_t seq) {
  if (!joined_) {
    SendError(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, what, "before JoinScene",
                            "after JoinScene", "join a scene first", seq));
    Violation();
    return false;
  }
  if (role_ != v1::ROLE_SCULPTOR) {
    server_.stats().strokes_refused++;
    SendError(ProtocolError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.role", "ROLE_VIEWER",
                            "{ROLE_SCULPTOR}", "viewers may not edit", seq));
    Violation();
    return false;
  }
  return TakeEditTokens(0, Clock::now(), stream, seq);
}

// The connection's own bucket first, then the ones it shares: a refusal names the one that
// ran out. Tokens taken from an earlier bucket of a refused edit are not given back (the
// refusal itself was work).
bool Session::TakeEditTokens(double poses, Clock::time_point now, ResendStream stream,
                             uint64_t seq) {
  using Kind = SharedBudget::Kind;
  if (resends_.Take(stream, seq)) return true;
  struct Shared {
    SharedBudget* budget;
    const char* scope;
  };
  const Shared shared[] = {{source_budget_.get(), " per source address"},
                           {user_budget_.get(), " per user"}};
  auto refuse = [&](const char* field, const std::string& range, const char* message) {
    server_.stats().strokes_refused++;
    SendError(ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, field, "above the limit", range,
                            message, seq));
    Violation();
    return false;
  };
  if (!strokes_.TryTake(1.0, now)) {
    return refuse("strokes_per_second", strokes_.AllowedRange(), "stroke rate limit");
  }
  for (const Shared& s : shared) {
    if (s.budget && !s.budget->TryTake(Kind::kStrokes, 1.0, now)) {
      return refuse("strokes_per_second", s.budget->AllowedRange(Kind::kStrokes) + s.scope,
                    "stroke rate limit");
    }
  }
  if (poses <= 0) return true;
  if (!poses_.TryTake(poses, now)) {
    return refuse("poses_per_second", poses_.AllowedRange(), "pose rate limit");
  }
  for (const Shared& s : shared) {
    if (s.budget && !s.budget->TryTake(Kind::kPoses, poses, now)) {
      return refuse("poses_per_second", s.budget->AllowedRange(Kind::kPoses) + s.scope,
                    "pose rate limit");
    }
  }
  return true;
}

bool Session::Charge(const char* what, double cost, Clock::time_point now) {
  using Kind = SharedBudget::Kind;
  std::string range;
  if (!requests_.TryTake(cost, now)) {
    range = requests_.AllowedRange() + " per connection";
  } else if (!source_budget_->TryTake(Kind::kRequests, cost, now)) {
    range = source_budget_->AllowedRange(Kind::kRequests) + " per source address";
  } else if (user_budget_ && !user_budget_->TryTake(Kind::kRequests, cost, now)) {
    range = user_budget_->AllowedRange(Kind::kRequests) + " per user";
  } else {
    return true;
  }
  SendError(ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "requests_per_second",
                          std::string(what) + " costs " + Num(cost), range,
                          "request rate limit: every request has a cost (docs/limits.md)"));
  Violation();
  return false;
}

// ---- Timeouts after authentication (on the strand) ------------------------------------------

void Session::TimedOut(v1::Error error, const std::string& reason) {
  if (closing_) return;
  server_.stats().sessions_timed_out++;
  SendError(std::move(error));
  Close(reason, true);
}

// Not cancelled by a join: a join the scene refuses (max_pending_joins) leaves the session
// unjoined, and the timer still closes it if it never gets in.
void Session::ArmJoinTimer() {
  const int ms = server_.config().limits.join_timeout_ms;
  if (ms <= 0) return;
  auth_timer_.expires_after(std::chrono::milliseconds(ms));
  auth_timer_.async_wait([self = shared_from_this(), ms](boost::system::error_code ec) {
    if (ec || self->joined_ || self->closing_) return;
    self->TimedOut(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "JoinScene", "none",
                                 "within " + std::to_string(ms) + " ms of Welcome",
                                 "no JoinScene received in time"),
                   "join timeout");
  });
}

void Session::ArmIdleTimer(Clock::time_point deadline) {
  idle_timer_.expires_at(deadline);
  idle_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (ec || self->closing_) return;
    const auto idle = std::chrono::milliseconds(self->server_.config().limits.idle_timeout_ms);
    const Clock::time_point due = self->last_message_ + idle;
    if (Clock::now() < due) return self->ArmIdleTimer(due);
    self->TimedOut(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "idle",
                                 "no message for " + std::to_string(idle.count()) + " ms",
                                 "a message at least every " + std::to_string(idle.count()) +
                                     " ms (limits.idle_timeout_ms)",
                                 "idle connection closed"),
                   "idle timeout");
  });
}

// A frame whose first bytes have arrived must be complete within limits.frame_timeout_ms,
// however slowly the rest trickles in: a client that keeps a frame open holds its connection
// without ever sending a message.
void Session::OnPartialFrame(bool partial) {
  if (!partial) {
    if (frame_timer_armed_) frame_timer_.cancel();
    frame_timer_armed_ = false;
    return;
  }
  if (frame_timer_armed_) return;
  frame_timer_armed_ = true;
  const int ms = server_.config().limits.frame_timeout_ms;
  frame_timer_.expires_after(std::chrono::milliseconds(ms));
  frame_timer_.async_wait([self = shared_from_this(), ms](boost::system::error_code ec) {
    if (ec || !self->frame_timer_armed_ || self->closing_) return;
    self->TimedOut(ProtocolError(v1::ERROR_CODE_MALFORMED, "frame",
                                 "incomplete after " + std::to_string(ms) + " ms",
                                 "complete within " + std::to_string(ms) +
                                     " ms of its first byte (limits.frame_timeout_ms)",
                                 "frame too slow"),
                   "frame not completed in time");
  });
}

void Session::OnSkinBallEdit(const v1::SkinBallEdit& e) {
  if (!MayEdit("SkinBallEdit", ResendStream::kBallEdits, e.client_seq())) return;
  auto edit = codec::DecodeSkinBallEdit(e);
  if (!edit.ok()) {
    OnSkinAck(ToWireAck(SkinOutcome{edit.status(), e.client_seq()}));
    return Violation();
  }
  scene_->EditSkin(client_id_, std::move(edit).value(),
                   [self = shared_from_this()](const SkinOutcome& o) {
                     self->OnSkinAck(ToWireAck(o));
                   });
}

void Session::OnSkinSweep(const v1::SkinSweep& s) {
  if (!MayEdit("SkinSweep", ResendStream::kSweeps, s.client_seq())) return;
  auto sweep = codec::DecodeSkinSweep(s);
  if (!sweep.ok()) {
    OnSkinAck(ToWireAck(SkinOutcome{sweep.status(), s.client_seq()}));
    return Violation();
  }
  scene_->SweepSkin(client_id_, std::move(sweep).value(),
                    [self = shared_from_this()](const SkinOutcome& o) {
                      self->OnSkinAck(ToWireAck(o));
                    });
}

void Session::OnPaint(const v1::PaintEdit& p) {
  if (!MayEdit("PaintEdit", ResendStream::kPaints, p.client_seq())) return;
  auto refuse = [&](const Status& st) {
    OnPaintAck(ToWireAck(PaintOutcome{st, p.client_seq()}));
    Violation();
  };
  auto limits = scene_->LimitsFor(p.object());
  if (!limits.ok()) {
    return refuse(
        Outside("PaintEdit.object", p.object(), "the scene's objects", Status::Code::kNotFound));
  }
  auto paint =
      codec::DecodePaintEdit(p, *limits, static_cast<int>(server_.config().scene.materials.size()));
  if (!paint.ok()) return refuse(paint.status());
  scene_->Paint(
      client_id_, std::move(paint).value(),
      [self = shared_from_this()](const PaintOutcome& o) { self->OnPaintAck(ToWireAck(o)); });
}

void Session::OnModelIntent(const v1::ModelIntent& mi) {
  if (!MayEdit("ModelIntent", ResendStream::kModels, mi.client_seq())) return;
  auto edit = codec::DecodeModelIntent(mi);
  if (!edit.ok()) {
    ModelOutcome refused;
    refused.status = edit.status();
    refused.client_seq = mi.client_seq();
    OnModelAck(ToWireAck(refused));
    return Violation();
  }
  scene_->EditModel(client_id_, std::move(edit).value(),
                    [self = shared_from_this()](const ModelOutcome& o) {
                      self->OnModelAck(ToWireAck(o));
                    });
}

void Session::OnUndo(const v1::UndoRequest& u) {
  if (!MayEdit("UndoRequest", ResendStream::kUndos, u.client_seq())) return;
  auto command = codec::DecodeUndo(u);
  if (!command.ok()) {
    // Answered in the UndoAck like any refused undo (as the scene's refusals are), not counted
    // as a violation.
    UndoCommandOutcome refused;
    refused.status = command.status();
    refused.client_seq = u.client_seq();
    refused.redo = u.redo();
    return OnUndoAck(ToWireAck(refused));
  }
  scene_->Undo(client_id_, std::move(command).value(),
               [self = shared_from_this()](const UndoCommandOutcome& o) {
                 self->OnUndoAck(ToWireAck(o));
               });
}

// The history view: any joined session (viewers too) may read it; a request costs tokens of the
// request bucket, and a refusal is answered in a HistoryAnswer naming the field.
void Session::OnHistory(const v1::HistoryRequest& h) {
  if (!Charge("HistoryRequest", kHistoryCost, Clock::now())) return;
  auto refuse = [&](v1::Error error) {
    v1::HistoryAnswer a;
    a.set_request_id(h.request_id());
    *a.mutable_error() = std::move(error);
    OnHistoryAnswer(std::move(a));
    Violation();
  };
  if (!joined_) {
    return refuse(ProtocolError(v1::ERROR_CODE_FAILED_PRECONDITION, "HistoryRequest",
                                "before JoinScene", "after JoinScene", "join a scene first"));
  }
  auto query = codec::DecodeHistoryRequest(h);
  if (!query.ok()) return refuse(ToWireError(query.status(), 0));
  scene_->History(std::move(query).value(),
                  [self = shared_from_this()](const HistoryOutcome& o) {
                    self->OnHistoryAnswer(ToWireAnswer(o));
                  });
}

void Session::OnHistoryAnswer(v1::HistoryAnswer a) {
  if (!strand_.running_in_this_thread()) {
    return asio::post(strand_, [self = shared_from_this(), a = std::move(a)]() mutable {
      self->OnHistoryAnswer(std::move(a));
    });
  }
  if (closing_) return;
  v1::ServerMessage m;
  *m.mutable_history() = std::move(a);
  Send(m);
}

void Session::Violation() {
  if (draining_ || ++violations_ < server_.config().limits.violations_before_disconnect) return;
  server_.stats().disconnects_for_cause++;
  const std::string reason = "too many refused messages (" + std::to_string(violations_) + ")";
  if (strokes_in_flight_ == 0) return Close(reason, true);
  // Strokes already accepted will be applied: their acks go out first, then the Bye. Nothing
  // more is read from this client meanwhile, and a scene that takes too long does not keep the
  // connection open past kDrainLimit.
  draining_ = true;
  drain_reason_ = reason;
  close_timer_.expires_after(kDrainLimit);
  close_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (ec == asio::error::operation_aborted) return;
    self->Close(self->drain_reason_ + "; acks still pending", true);
  });
}

// ---- Sending (on the strand) ---------------------------------------------------------------

void Session::SendError(v1::Error error) {
  server_.stats().errors_sent++;
  v1::ServerMessage m;
  *m.mutable_error() = std::move(error);
  Send(m);
}

void Session::SendStatus(const Status& st, uint64_t client_seq) {
  SendError(ToWireError(st, client_seq));
}

void Session::Send(const v1::ServerMessage& m, bool is_state) {
  if (closing_) return;
  Enqueue(codec::EncodeSharedFrame(m), is_state ? kStateAllowanceBytes : 0, false);
}

// A client that does not read lets its queue grow: presence is coalesced (one queued at a time),
// the rest counts against the queue bound, and past it the client is dropped.
void Session::Enqueue(Frame frame, size_t allowance, bool is_bye) {
  const size_t limit = server_.config().limits.send_queue_bytes + allowance;
  if (!is_bye && queued_bytes_ + writing_bytes_ + frame->size() > limit) {
    server_.stats().disconnects_for_cause++;
    Close(allowance > 0 ? "send queue overflow: replica is not reading"
                        : "send queue overflow: client is not reading",
          true);
    return;
  }
  queued_bytes_ += frame->size();
  queue_.push_back(std::move(frame));
  DoWrite();
}

void Session::DoWrite() {
  if (writing_ || queue_.empty() || state_ == State::kClosed) return;
  // Everything queued goes in one gathered write; the frames are shared, not copied.
  std::vector<Frame> frames(std::make_move_iterator(queue_.begin()),
                            std::make_move_iterator(queue_.end()));
  queue_.clear();
  queued_slots_.clear();
  writing_ = true;
  writing_bytes_ = queued_bytes_;
  queued_bytes_ = 0;
  presence_queued_ = false;
  transport_->AsyncWrite(std::move(frames), [self = shared_from_this()](Status st, uint64_t n) {
    self->OnWritten(std::move(st), n);
  });
}

void Session::OnWritten(Status st, uint64_t bytes) {
  writing_ = false;
  writing_bytes_ = 0;
  server_.stats().bytes_out[Index(transport_kind_)] += bytes;
  if (!st.ok()) return Close(st.message(), false);
  if (closing_ && queue_.empty()) return FinishClose();
  DoWrite();
}

void Session::Close(const std::string& reason, bool send_bye) {
  if (closing_) return;
  closing_ = true;
  joined_flag_ = false;
  auth_timer_.cancel();
  idle_timer_.cancel();
  frame_timer_.cancel();
  frame_timer_armed_ = false;
  if (!quiet_close_) {
    spdlog::info("session {} ({}, {} {}): closing: {}", id_, Printable(PresenceEntry().name()),
                 TransportName(transport_kind_), transport_->remote(), reason);
  }
  if (send_bye && state_ != State::kClosed) {
    v1::ServerMessage m;
    m.mutable_bye()->set_reason(reason);
    Enqueue(codec::EncodeSharedFrame(m), 0, /*is_bye=*/true);
    // Give the Bye a moment to leave; a client that does not read is closed regardless.
    close_timer_.expires_after(kByeGrace);
    close_timer_.async_wait([self = shared_from_this()](boost::system::error_code) {
      self->FinishClose();
    });
    if (!writing_) FinishClose();
    return;
  }
  FinishClose();
}

void Session::FinishClose() {
  if (state_ == State::kClosed) return;
  state_ = State::kClosed;
  transport_->Close();
  close_timer_.cancel();
  const Scene::RequesterScope requester(ComputeOwner(user_budget_ != nullptr, user_, source_));
  if (subscribed_) scene_->Unsubscribe(id_);
  if (joined_) scene_->UnsubscribeContours(id_);
  if (viewing_) scene_->UnsubscribeViewer(id_);
  server_.Unregister(this);
}

}  // namespace sculpt::server
