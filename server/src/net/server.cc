/// @brief sculptd's sessions: framing, authentication, validation, rate limits, bounded send
/// queues, presence, and the hand-off of strokes to the scene actor.
#include "net/server.h"

#include <sodium.h>
#include <spdlog/spdlog.h>

#include <array>
#include <chrono>
#include <deque>
#include <sstream>

#include "sculpt/codec/frame.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"
#include "scene/models.h"
#include "scene/paint.h"
#include "scene/skins.h"

namespace sculpt::server {
namespace {

constexpr uint32_t kProtocolVersion = 1;
constexpr size_t kStateChunkBytes = 256 * 1024;

// Constant-time token comparison (no early exit on the first differing byte).
bool TokenEquals(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  return sodium_memcmp(a.data(), b.data(), a.size()) == 0;
}

std::string Num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

uint32_t ColorFor(uint64_t id) {
  static const uint32_t kColors[] = {0xe6194bff, 0x3cb44bff, 0x4363d8ff, 0xf58231ff,
                                     0x911eb4ff, 0x46f0f0ff, 0xf032e6ff, 0xbcf60cff};
  return kColors[id % 8];
}

}  // namespace

namespace {

// A refusal as a wire Error: the Status's field, value, allowed range and message.
v1::Error ErrorOf(const Status& st, v1::ErrorCode code, uint64_t client_seq) {
  const codec::FieldError fe = codec::SplitFieldError(st);
  v1::Error e;
  e.set_code(code);
  e.set_field(fe.field);
  e.set_value(fe.value);
  e.set_allowed_range(fe.allowed_range);
  e.set_message(fe.message);
  e.set_client_seq(client_seq);
  return e;
}

}  // namespace

/// One client connection. Every member is touched only on the socket's strand, except the
/// presence fields (presence_mu_).
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(Server& server, tcp::socket socket, uint64_t id)
      : server_(server),
        socket_(std::move(socket)),
        auth_timer_(socket_.get_executor()),
        close_timer_(socket_.get_executor()),
        reader_(server.config().limits.max_frame_bytes),
        id_(id) {
    tokens_ = server.config().limits.stroke_burst;
    pose_tokens_ = server.config().limits.pose_burst;
    last_refill_ = last_pose_refill_ = std::chrono::steady_clock::now();
  }

  void Start() {
    auto self = shared_from_this();
    asio::dispatch(socket_.get_executor(), [self] {
      self->auth_timer_.expires_after(
          std::chrono::milliseconds(self->server_.config().limits.auth_timeout_ms));
      self->auth_timer_.async_wait([self](boost::system::error_code ec) {
        if (ec || self->state_ != State::kAwaitHello) return;
        self->SendError(v1::ERROR_CODE_UNAUTHENTICATED, "Hello", "none",
                        "within " + std::to_string(self->server_.config().limits.auth_timeout_ms) +
                            " ms",
                        "no Hello received in time", 0);
        self->Close("authentication timeout", true);
      });
      self->DoRead();
    });
  }

  /// Posts a Bye and closes (from any thread).
  void Shutdown(const std::string& reason) {
    auto self = shared_from_this();
    asio::post(socket_.get_executor(), [self, reason] { self->Close(reason, true); });
  }

  /// Queues a presence update unless one is already waiting (coalesced; from any thread).
  void PostPresence(std::shared_ptr<const v1::ServerMessage> msg) {
    auto self = shared_from_this();
    asio::post(socket_.get_executor(), [self, msg] {
      if (!self->joined_ || self->closing_ || self->presence_queued_) return;
      self->presence_queued_ = true;
      self->Send(*msg);
    });
  }

  bool joined() const { return joined_flag_.load(); }
  v1::PresenceEntry PresenceEntry() const {
    std::lock_guard<std::mutex> lock(presence_mu_);
    return presence_;
  }

 private:
  enum class State { kAwaitHello, kAuthed, kClosed };

  void DoRead() {
    if (closing_) return;
    auto self = shared_from_this();
    socket_.async_read_some(asio::buffer(buf_), [self](boost::system::error_code ec, size_t n) {
      if (ec) {
        if (self->reader_.buffered() > 0 && ec == asio::error::eof) {
          spdlog::info("session {}: closed mid-frame ({} bytes of a truncated frame dropped)",
                       self->id_, self->reader_.buffered());
        }
        self->Close(ec == asio::error::eof ? "client closed" : "read: " + ec.message(), false);
        return;
      }
      self->reader_.Feed(self->buf_.data(), n);
      for (;;) {
        auto next = self->reader_.Next();
        if (!next.ok()) {
          const codec::FieldError fe = codec::SplitFieldError(next.status());
          self->SendError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, fe.field, fe.value, fe.allowed_range,
                          fe.message, 0);
          self->Close("oversized frame", true);
          return;
        }
        if (!next->has_value()) break;
        self->Handle(**next);
        if (self->closing_) return;
      }
      self->DoRead();
    });
  }

  void Handle(const std::string& payload) {
    v1::ClientMessage msg;
    if (!msg.ParseFromString(payload)) {
      // The stream cannot be trusted after a frame that does not parse.
      SendError(v1::ERROR_CODE_MALFORMED, "frame", std::to_string(payload.size()) + " bytes",
                "a serialized sculpt.v1.ClientMessage", "frame does not parse", 0);
      Close("malformed frame", true);
      return;
    }
    switch (msg.body_case()) {
      case v1::ClientMessage::kHello: return OnHello(msg.hello());
      case v1::ClientMessage::kJoin: return OnJoin(msg.join());
      case v1::ClientMessage::kStroke: return OnStroke(msg.stroke());
      case v1::ClientMessage::kHover: return OnHover(msg.hover());
      case v1::ClientMessage::kBye: return Close("client said bye: " + msg.bye().reason(), false);
      case v1::ClientMessage::kSubscribe: return OnSubscribe(msg.subscribe());
      case v1::ClientMessage::kSetInterest: return OnSetInterest(msg.set_interest());
      case v1::ClientMessage::kDivergence:
        if (subscribed_) server_.scene().ReportDivergence(id_, msg.divergence());
        return;
      case v1::ClientMessage::kViewerSubscribe: return OnViewerSubscribe(msg.viewer_subscribe());
      case v1::ClientMessage::kSkinBallEdit: return OnSkinBallEdit(msg.skin_ball_edit());
      case v1::ClientMessage::kContourSubscribe: return OnContourSubscribe(msg.contour_subscribe());
      case v1::ClientMessage::kSkinSweep: return OnSkinSweep(msg.skin_sweep());
      case v1::ClientMessage::kPaint: return OnPaint(msg.paint());
      case v1::ClientMessage::kModelIntent: return OnModelIntent(msg.model_intent());
      case v1::ClientMessage::BODY_NOT_SET: break;
    }
    SendError(v1::ERROR_CODE_MALFORMED, "ClientMessage.body", "unknown or empty",
              "{hello, join, stroke, hover, bye, subscribe, set_interest, divergence, viewer_subscribe}",
              "unknown message", 0);
    Violation();
  }

  void OnHello(const v1::Hello& h) {
    if (state_ != State::kAwaitHello) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, "Hello", "repeated", "once per connection",
                "already authenticated", 0);
      return Violation();
    }
    const ServerConfig& c = server_.config();
    if (h.protocol_version() != kProtocolVersion) {
      SendError(v1::ERROR_CODE_VERSION_MISMATCH, "Hello.protocol_version",
                std::to_string(h.protocol_version()), "[1, 1]",
                "this server speaks protocol version 1; update the client", 0);
      return Close("protocol version mismatch", true);
    }
    bool ok = false;
    if (h.role() == v1::ROLE_SCULPTOR) ok = TokenEquals(h.token(), c.sculptor_token);
    if (h.role() == v1::ROLE_VIEWER) ok = TokenEquals(h.token(), c.viewer_token);
    if (h.role() != v1::ROLE_SCULPTOR && h.role() != v1::ROLE_VIEWER) {
      SendError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hello.role", std::to_string(h.role()),
                "{ROLE_SCULPTOR, ROLE_VIEWER}", "unknown role", 0);
      return Close("bad role", true);
    }
    if (!ok) {
      SendError(v1::ERROR_CODE_UNAUTHENTICATED, "Hello.token", "(hidden)",
                "the configured token of the requested role", "wrong token", 0);
      return Close("wrong token", true);
    }
    if (h.client_id() == 0) {
      // Resends are de-duplicated on (client_id, client_seq) across restarts, so the id must be
      // the client's own, stable one; a server-made id would collide after a restart.
      SendError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hello.client_id", "0", "[1, 2^64 - 1]",
                "choose a random client id once and keep it across reconnects", 0);
      return Close("client_id 0", true);
    }
    if (h.client_name().size() > 64) {
      SendError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hello.client_name",
                std::to_string(h.client_name().size()) + " bytes", "[0, 64] bytes",
                "name too long", 0);
      return Close("bad name", true);
    }
    auth_timer_.cancel();
    state_ = State::kAuthed;
    role_ = h.role();
    client_id_ = h.client_id();
    {
      std::lock_guard<std::mutex> lock(presence_mu_);
      presence_.set_session_id(id_);
      presence_.set_name(h.client_name().empty() ? "user-" + std::to_string(id_)
                                                 : h.client_name());
      presence_.set_color_rgba(ColorFor(id_));
      presence_.set_role(role_);
    }
    v1::ServerMessage out;
    v1::Welcome* w = out.mutable_welcome();
    w->set_protocol_version(kProtocolVersion);
    w->set_session_id(id_);
    w->set_role(role_);
    w->add_scenes(server_.scene().name());
    w->set_max_frame_bytes(c.limits.max_frame_bytes);
    w->set_max_poses_per_stroke(c.limits.max_poses_per_stroke);
    w->set_max_strokes_per_second(static_cast<float>(c.limits.strokes_per_second));
    Send(out);
  }

  void OnJoin(const v1::JoinScene& j) {
    if (state_ != State::kAuthed) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, "JoinScene", "before Hello", "after Hello",
                "authenticate first", 0);
      return Close("join before hello", true);
    }
    if (!j.scene().empty() && j.scene() != server_.scene().name()) {
      SendError(v1::ERROR_CODE_NOT_FOUND, "JoinScene.scene", j.scene(),
                "{" + server_.scene().name() + "}", "unknown scene", 0);
      return Violation();
    }
    if (joined_) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, "JoinScene", "repeated", "once per connection",
                "already joined", 0);
      return Violation();
    }
    size_t joined = 0;
    {
      std::lock_guard<std::mutex> lock(server_.sessions_mu_);
      for (const auto& s : server_.sessions_) joined += s->joined() ? 1 : 0;
    }
    if (joined >= server_.config().limits.max_clients_per_scene) {
      SendError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "clients", std::to_string(joined),
                "[0, " + std::to_string(server_.config().limits.max_clients_per_scene) + "]",
                "scene full", 0);
      return Close("scene full", true);
    }
    joined_ = true;
    joined_flag_ = true;
    auto self = shared_from_this();
    if (j.skip_state()) {
      // A replica loads its region through Subscribe: scene info only.
      v1::ServerMessage info;
      *info.mutable_scene_info() = server_.scene().Info();
      Send(info);
      return;
    }
    server_.scene().RequestJoinState([self](StatusOr<JoinState> js) {
      asio::post(self->socket_.get_executor(), [self, js = std::move(js)]() mutable {
        if (self->closing_) return;
        if (!js.ok()) {
          self->SendError(v1::ERROR_CODE_INTERNAL, "", "", "", js.status().ToString(), 0);
          return;
        }
        v1::ServerMessage info;
        *info.mutable_scene_info() = js->info;
        self->Send(info);
        // The state goes out in chunks, queued behind nothing else of this session; other
        // sessions are not touched (late join without stalling the others).
        for (auto& [name, bytes] : js->objects) {
          const uint32_t count =
              static_cast<uint32_t>((bytes.size() + kStateChunkBytes - 1) / kStateChunkBytes);
          for (uint32_t i = 0; i < count; ++i) {
            v1::ServerMessage m;
            v1::StateChunk* c = m.mutable_state_chunk();
            c->set_object(name);
            c->set_global_seq(js->info.global_seq());
            c->set_index(i);
            c->set_count(count);
            c->set_data(bytes.substr(i * kStateChunkBytes, kStateChunkBytes));
            self->Send(m, /*is_state=*/true);
            if (self->closing_) return;
          }
        }
      });
    });
  }

  void OnStroke(const v1::Stroke& s) {
    if (!joined_) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, "Stroke", "before JoinScene",
                "after JoinScene", "join a scene first", s.client_seq());
      return Violation();
    }
    if (role_ != v1::ROLE_SCULPTOR) {
      server_.stats().strokes_refused++;
      SendError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.role", "ROLE_VIEWER", "{ROLE_SCULPTOR}",
                "viewers may not edit", s.client_seq());
      return Violation();
    }
    // Token bucket: strokes_per_second sustained, stroke_burst at once.
    const LimitsConfig& l = server_.config().limits;
    const auto now = std::chrono::steady_clock::now();
    tokens_ = std::min(l.stroke_burst,
                       tokens_ + l.strokes_per_second *
                                     std::chrono::duration<double>(now - last_refill_).count());
    last_refill_ = now;
    if (tokens_ < 1.0) {
      server_.stats().strokes_refused++;
      SendError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "strokes_per_second", "above the limit",
                "[0, " + Num(l.strokes_per_second) + "] (burst " + Num(l.stroke_burst) + ")",
                "stroke rate limit", s.client_seq());
      return Violation();
    }
    tokens_ -= 1.0;
    // Each pose is an edit: a second bucket bounds the edits a client may queue per second.
    pose_tokens_ = std::min(l.pose_burst, pose_tokens_ + l.poses_per_second *
                                                       std::chrono::duration<double>(
                                                           now - last_pose_refill_)
                                                           .count());
    last_pose_refill_ = now;
    if (pose_tokens_ < static_cast<double>(s.pose_count())) {
      server_.stats().strokes_refused++;
      SendError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "poses_per_second", "above the limit",
                "[0, " + Num(l.poses_per_second) + "] (burst " + Num(l.pose_burst) + ")",
                "pose rate limit", s.client_seq());
      return Violation();
    }
    pose_tokens_ -= static_cast<double>(s.pose_count());
    auto limits = server_.scene().LimitsFor(s.object());
    if (!limits.ok()) {
      server_.stats().strokes_refused++;
      const codec::FieldError fe = codec::SplitFieldError(limits.status());
      SendError(v1::ERROR_CODE_NOT_FOUND, fe.field, fe.value, fe.allowed_range, fe.message,
                s.client_seq());
      return Violation();
    }
    auto decoded = codec::DecodeStroke(s, *limits);
    if (!decoded.ok()) {
      server_.stats().strokes_refused++;
      const codec::FieldError fe = codec::SplitFieldError(decoded.status());
      SendError(v1::ERROR_CODE_INVALID_ARGUMENT, fe.field, fe.value, fe.allowed_range,
                fe.message, s.client_seq());
      return Violation();
    }
    {
      std::lock_guard<std::mutex> lock(presence_mu_);
      *presence_.mutable_position() = codec::ToProto(decoded->poses.back().position);
      presence_.set_radius(s.tool_size().x());
    }
    auto self = shared_from_this();
    server_.scene().Submit(client_id_, std::move(decoded).value(),
                           [self](const StrokeOutcome& out) {
                             asio::post(self->socket_.get_executor(),
                                        [self, out] { self->OnOutcome(out); });
                           });
  }

  void OnOutcome(const StrokeOutcome& out) {
    if (closing_) return;
    if (!out.status.ok()) {
      server_.stats().strokes_refused++;
      const codec::FieldError fe = codec::SplitFieldError(out.status);
      const auto code = out.status.code() == Status::Code::kNotFound
                            ? v1::ERROR_CODE_NOT_FOUND
                            : (out.status.code() == Status::Code::kInvalidArgument
                                   ? v1::ERROR_CODE_INVALID_ARGUMENT
                                   : v1::ERROR_CODE_INTERNAL);
      SendError(code, fe.field, fe.value, fe.allowed_range, fe.message, out.client_seq);
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
    Send(m);
  }

  // A refusal from the scene as an Error naming field, value and range.
  void SendStatus(const Status& st) {
    const codec::FieldError fe = codec::SplitFieldError(st);
    const auto code = st.code() == Status::Code::kNotFound ? v1::ERROR_CODE_NOT_FOUND
                      : st.code() == Status::Code::kFailedPrecondition
                          ? v1::ERROR_CODE_FAILED_PRECONDITION
                          : v1::ERROR_CODE_INVALID_ARGUMENT;
    SendError(code, fe.field, fe.value, fe.allowed_range, fe.message, 0);
  }

  ReplicaSink Sink() {
    ReplicaSink sink;
    sink.session_id = id_;
    sink.client_id = client_id_;
    std::weak_ptr<Session> weak = shared_from_this();
    sink.send = [weak](std::shared_ptr<const std::string> frame) {
      auto self = weak.lock();
      if (!self) return;
      asio::post(self->socket_.get_executor(), [self, frame] { self->SendFrame(*frame); });
    };
    return sink;
  }

  // Starts a once-per-connection subscription: refuses one before JoinScene or a repeat, else
  // sets `*flag`. The returned callback reports the scene's refusal (and clears the flag).
  std::function<void(Status)> BeginSubscription(const char* what, bool* flag,
                                                const char* repeat_hint) {
    if (!joined_) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, what, "before JoinScene", "after JoinScene",
                "join a scene first", 0);
      Violation();
      return nullptr;
    }
    if (flag && *flag) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, what, "repeated", "once per connection",
                repeat_hint, 0);
      Violation();
      return nullptr;
    }
    if (flag) *flag = true;
    auto self = shared_from_this();
    return [self, flag](Status st) {
      if (st.ok()) return;
      asio::post(self->socket_.get_executor(), [self, flag, st] {
        if (flag) *flag = false;
        self->SendStatus(st);
        self->Violation();
      });
    };
  }

  void OnSubscribe(const v1::Subscribe& sub) {
    auto done = BeginSubscription("Subscribe", &subscribed_, "use SetInterest to move the region");
    if (done) server_.scene().Subscribe(Sink(), sub, std::move(done));
  }

  void OnSetInterest(const v1::SetInterest& si) {
    auto done = BeginSubscription("SetInterest", nullptr, "");
    if (done) server_.scene().SetInterest(id_, si, std::move(done));
  }

  void OnViewerSubscribe(const v1::ViewerSubscribe& vs) {
    auto done = BeginSubscription("ViewerSubscribe", &viewing_, "already subscribed to meshes");
    if (done) server_.scene().SubscribeViewer(Sink(), vs, std::move(done));
  }

  // Ball skins (issue 6). Ball edits and sweeps are strokes: joined sculptors only, the stroke
  // token bucket, every field checked here before the scene sees it.
  bool MaySkinEdit(const char* what, uint64_t seq) {
    if (!joined_) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, what, "before JoinScene", "after JoinScene",
                "join a scene first", seq);
      Violation();
      return false;
    }
    if (role_ != v1::ROLE_SCULPTOR) {
      server_.stats().strokes_refused++;
      SendError(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.role", "ROLE_VIEWER", "{ROLE_SCULPTOR}",
                "viewers may not edit", seq);
      Violation();
      return false;
    }
    const LimitsConfig& l = server_.config().limits;
    const auto now = std::chrono::steady_clock::now();
    tokens_ = std::min(l.stroke_burst,
                       tokens_ + l.strokes_per_second *
                                     std::chrono::duration<double>(now - last_refill_).count());
    last_refill_ = now;
    if (tokens_ < 1.0) {
      server_.stats().strokes_refused++;
      SendError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "strokes_per_second", "above the limit",
                "[0, " + Num(l.strokes_per_second) + "] (burst " + Num(l.stroke_burst) + ")",
                "stroke rate limit", seq);
      Violation();
      return false;
    }
    tokens_ -= 1.0;
    return true;
  }

  // Refusals go out twice: as the generic Error, and in the SkinAck a skin client waits for.
  void SendSkinAck(const v1::SkinAck& a) {
    if (closing_) return;
    if (!a.accepted()) {
      server_.stats().strokes_refused++;
      const v1::Error& e = a.error();
      SendError(e.code(), e.field(), e.value(), e.allowed_range(), e.message(), 0);
    }
    v1::ServerMessage m;
    *m.mutable_skin_ack() = a;
    Send(m);
  }

  void RefuseSkin(const Status& st, uint64_t seq) {
    v1::SkinAck a;
    a.set_client_seq(seq);
    *a.mutable_error() = ErrorOf(st, v1::ERROR_CODE_INVALID_ARGUMENT, seq);
    SendSkinAck(a);
    Violation();
  }

  std::function<void(v1::SkinAck)> PostSkinAck() {
    auto self = shared_from_this();
    return [self](v1::SkinAck a) {
      asio::post(self->socket_.get_executor(), [self, a = std::move(a)] { self->SendSkinAck(a); });
    };
  }

  void OnSkinBallEdit(const v1::SkinBallEdit& e) {
    if (!MaySkinEdit("SkinBallEdit", e.client_seq())) return;
    if (const Status st = ValidateSkinBallEdit(e); !st.ok()) return RefuseSkin(st, e.client_seq());
    server_.scene().EditSkin(client_id_, e, PostSkinAck());
  }

  void OnSkinSweep(const v1::SkinSweep& s) {
    if (!MaySkinEdit("SkinSweep", s.client_seq())) return;
    if (const Status st = ValidateSkinSweep(s); !st.ok()) return RefuseSkin(st, s.client_seq());
    server_.scene().SweepSkin(client_id_, s, PostSkinAck());
  }

  // Paints (issue 7) are strokes too: joined sculptors, the stroke token bucket, every field
  // checked here against the object's limits before the scene sees it.
  void SendPaintAck(const v1::PaintAck& a) {
    if (closing_) return;
    if (!a.accepted()) {
      server_.stats().strokes_refused++;
      const v1::Error& e = a.error();
      // client_seq 0: a paint's sequence is not a stroke's, and must not settle one.
      SendError(e.code(), e.field(), e.value(), e.allowed_range(), e.message(), 0);
    } else if (!a.duplicate()) {
      server_.stats().strokes_accepted++;
    }
    v1::ServerMessage m;
    *m.mutable_paint_ack() = a;
    Send(m);
  }

  void OnPaint(const v1::PaintEdit& p) {
    if (!MaySkinEdit("PaintEdit", p.client_seq())) return;
    auto refuse = [&](const Status& st, v1::ErrorCode code) {
      v1::PaintAck a;
      a.set_client_seq(p.client_seq());
      *a.mutable_error() = ErrorOf(st, code, p.client_seq());
      SendPaintAck(a);
      Violation();
    };
    auto limits = server_.scene().LimitsFor(p.object());
    if (!limits.ok()) {
      return refuse(NotFound("PaintEdit.object=" + p.object() + " outside the scene's objects"),
                    v1::ERROR_CODE_NOT_FOUND);
    }
    const Status st =
        ValidatePaintEdit(p, *limits, static_cast<int>(server_.config().scene.materials.size()));
    if (!st.ok()) {
      return refuse(st, st.code() == Status::Code::kFailedPrecondition
                            ? v1::ERROR_CODE_FAILED_PRECONDITION
                            : v1::ERROR_CODE_INVALID_ARGUMENT);
    }
    auto self = shared_from_this();
    server_.scene().Paint(client_id_, p, [self](v1::PaintAck a) {
      asio::post(self->socket_.get_executor(), [self, a = std::move(a)] { self->SendPaintAck(a); });
    });
  }

  // Hyperpatch model intents (issue 7) are strokes too: joined sculptors, the stroke token
  // bucket, the fields that need no model checked here; the scene checks the rest.
  void SendModelAck(const v1::ModelAck& a) {
    if (closing_) return;
    if (!a.accepted()) {
      server_.stats().strokes_refused++;
      if (a.has_error()) {
        const v1::Error& e = a.error();
        SendError(e.code(), e.field(), e.value(), e.allowed_range(), e.message(), 0);
      }
    } else if (!a.duplicate()) {
      server_.stats().strokes_accepted++;
    }
    v1::ServerMessage m;
    *m.mutable_model_ack() = a;
    Send(m);
  }

  void OnModelIntent(const v1::ModelIntent& mi) {
    if (!MaySkinEdit("ModelIntent", mi.client_seq())) return;
    if (const Status st = ValidateModelIntent(mi); !st.ok()) {
      v1::ModelAck a;
      a.set_client_seq(mi.client_seq());
      *a.mutable_error() = ErrorOf(st, v1::ERROR_CODE_INVALID_ARGUMENT, mi.client_seq());
      SendModelAck(a);
      Violation();
      return;
    }
    auto self = shared_from_this();
    server_.scene().EditModel(client_id_, mi, [self](v1::ModelAck a) {
      asio::post(self->socket_.get_executor(), [self, a = std::move(a)] { self->SendModelAck(a); });
    });
  }

  void OnContourSubscribe(const v1::ContourSubscribe& c) {
    if (!joined_) {
      SendError(v1::ERROR_CODE_FAILED_PRECONDITION, "ContourSubscribe", "before JoinScene",
                "after JoinScene", "join a scene first", 0);
      return Violation();
    }
    if (const Status st = ValidateContourSubscribe(c); !st.ok()) {
      SendStatus(st);
      return Violation();
    }
    auto self = shared_from_this();
    server_.scene().SubscribeContours(Sink(), c, [self](Status st) {
      if (st.ok()) return;
      asio::post(self->socket_.get_executor(), [self, st] {
        self->SendStatus(st);
        self->Violation();
      });
    });
  }

  // A pre-built frame shared with other sessions (replication). Replica loads may be large, so
  // they get the state allowance on top of the queue bound.
  void SendFrame(const std::string& frame) {
    if (closing_) return;
    const size_t limit = server_.config().limits.send_queue_bytes + (64u << 20);
    if (out_.size() + writing_bytes_ + frame.size() > limit) {
      server_.stats().disconnects_for_cause++;
      Close("send queue overflow: replica is not reading", true);
      return;
    }
    out_ += frame;
    DoWrite();
  }

  void OnHover(const v1::Hover& h) {
    if (!joined_) return;
    if (!std::isfinite(h.position().x()) || !std::isfinite(h.position().y()) ||
        !std::isfinite(h.position().z()) || !std::isfinite(h.radius())) {
      SendError(v1::ERROR_CODE_INVALID_ARGUMENT, "Hover.position", "not finite",
                "finite numbers", "hover must be finite", 0);
      return Violation();
    }
    std::lock_guard<std::mutex> lock(presence_mu_);
    *presence_.mutable_position() = h.position();
    presence_.set_radius(h.radius());
  }

  void Violation() {
    if (++violations_ >= server_.config().limits.violations_before_disconnect) {
      server_.stats().disconnects_for_cause++;
      Close("too many refused messages (" + std::to_string(violations_) + ")", true);
    }
  }

  void SendError(v1::ErrorCode code, const std::string& field, const std::string& value,
                 const std::string& range, const std::string& message, uint64_t client_seq) {
    server_.stats().errors_sent++;
    v1::ServerMessage m;
    v1::Error* e = m.mutable_error();
    e->set_code(code);
    e->set_field(field);
    e->set_value(value);
    e->set_allowed_range(range);
    e->set_message(message);
    e->set_client_seq(client_seq);
    Send(m);
  }

  void Send(const v1::ServerMessage& m, bool is_state = false) {
    if (closing_ && !m.has_bye()) return;
    const size_t before = out_.size();
    codec::AppendMessage(m, &out_);
    // A client that does not read lets its queue grow: presence is coalesced (one queued at a
    // time), the rest counts against the queue bound, and past it the client is dropped.
    const size_t limit = server_.config().limits.send_queue_bytes + (is_state ? 64u << 20 : 0);
    if (!m.has_bye() && out_.size() + writing_bytes_ > limit) {
      out_.resize(before);
      server_.stats().disconnects_for_cause++;
      Close("send queue overflow: client is not reading", true);
      return;
    }
    DoWrite();
  }

  void DoWrite() {
    if (writing_bytes_ > 0 || out_.empty() || state_ == State::kClosed) return;
    writing_.swap(out_);
    out_.clear();
    writing_bytes_ = writing_.size();
    presence_queued_ = false;
    auto self = shared_from_this();
    asio::async_write(socket_, asio::buffer(writing_),
                      [self](boost::system::error_code ec, size_t) {
                        self->writing_bytes_ = 0;
                        self->writing_.clear();
                        if (ec) {
                          self->Close("write: " + ec.message(), false);
                          return;
                        }
                        if (self->closing_ && self->out_.empty()) {
                          self->FinishClose();
                          return;
                        }
                        self->DoWrite();
                      });
  }

  void Close(const std::string& reason, bool send_bye) {
    if (closing_) return;
    closing_ = true;
    joined_flag_ = false;
    auth_timer_.cancel();
    spdlog::info("session {} ({}): closing: {}", id_, PresenceEntry().name(), reason);
    if (send_bye && state_ != State::kClosed) {
      v1::ServerMessage m;
      m.mutable_bye()->set_reason(reason);
      codec::AppendMessage(m, &out_);
      DoWrite();
      // Give the Bye a moment to leave; a client that does not read is closed regardless.
      auto self = shared_from_this();
      close_timer_.expires_after(std::chrono::milliseconds(500));
      close_timer_.async_wait([self](boost::system::error_code) { self->FinishClose(); });
      if (writing_bytes_ == 0) FinishClose();
      return;
    }
    FinishClose();
  }

  void FinishClose() {
    if (state_ == State::kClosed) return;
    state_ = State::kClosed;
    boost::system::error_code ec;
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
    close_timer_.cancel();
    if (subscribed_) server_.scene().Unsubscribe(id_);
    if (joined_) server_.scene().UnsubscribeContours(id_);
    if (viewing_) server_.scene().UnsubscribeViewer(id_);
    server_.Unregister(this);
  }

  Server& server_;
  tcp::socket socket_;
  asio::steady_timer auth_timer_;
  asio::steady_timer close_timer_;
  codec::FrameReader reader_;
  std::array<char, 64 * 1024> buf_{};
  std::string out_;
  std::string writing_;
  size_t writing_bytes_ = 0;
  bool presence_queued_ = false;
  bool closing_ = false;
  bool joined_ = false;
  bool subscribed_ = false;
  bool viewing_ = false;
  std::atomic<bool> joined_flag_{false};
  State state_ = State::kAwaitHello;
  v1::Role role_ = v1::ROLE_UNSPECIFIED;
  uint64_t client_id_ = 0;
  uint64_t id_;
  double tokens_ = 0;
  double pose_tokens_ = 0;
  std::chrono::steady_clock::time_point last_refill_;
  std::chrono::steady_clock::time_point last_pose_refill_;
  int violations_ = 0;
  mutable std::mutex presence_mu_;
  v1::PresenceEntry presence_;
};

Server::Server(asio::io_context& io, const ServerConfig& config, Scene& scene)
    : io_(io), config_(config), scene_(scene), acceptor_(io), presence_timer_(io) {}

Server::~Server() { Stop(); }

StatusOr<uint16_t> Server::Start() {
  if (sodium_init() < 0) return Internal("libsodium failed to initialise");
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseHostPort(config_.listen, &host, &port));
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(host == "localhost" ? "127.0.0.1" : host, ec);
  if (ec) return InvalidArgument("listen host=" + host + " is not an IP address");
  const tcp::endpoint ep(address, port);
  acceptor_.open(ep.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(ep, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) return Status(Status::Code::kUnavailable, "listen on " + config_.listen + ": " + ec.message());
  Accept();
  SchedulePresence();
  return acceptor_.local_endpoint().port();
}

void Server::Stop() {
  if (stopped_.exchange(true)) return;
  asio::post(io_, [this] {
    boost::system::error_code ec;
    acceptor_.close(ec);
    presence_timer_.cancel();
  });
  std::set<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard<std::mutex> lock(sessions_mu_);
    sessions = sessions_;
  }
  for (const auto& s : sessions) s->Shutdown("server shutting down");
}

void Server::Accept() {
  acceptor_.async_accept(asio::make_strand(io_), [this](boost::system::error_code ec,
                                                        tcp::socket socket) {
    if (ec) {
      if (ec != asio::error::operation_aborted) spdlog::warn("accept: {}", ec.message());
      if (!stopped_) Accept();
      return;
    }
    boost::system::error_code nd;
    socket.set_option(tcp::no_delay(true), nd);
    stats_.connections++;
    auto s = std::make_shared<Session>(*this, std::move(socket), next_session_id_++);
    if (Register(s)) s->Start();
    if (!stopped_) Accept();
  });
}

bool Server::Register(const std::shared_ptr<Session>& s) {
  std::lock_guard<std::mutex> lock(sessions_mu_);
  if (stopped_) return false;
  sessions_.insert(s);
  return true;
}

void Server::Unregister(const Session* s) {
  std::lock_guard<std::mutex> lock(sessions_mu_);
  for (auto it = sessions_.begin(); it != sessions_.end(); ++it) {
    if (it->get() == s) {
      sessions_.erase(it);
      return;
    }
  }
}

void Server::SchedulePresence() {
  presence_timer_.expires_after(std::chrono::microseconds(
      static_cast<int64_t>(1e6 / std::max(0.1, config_.presence_hz))));
  presence_timer_.async_wait([this](boost::system::error_code ec) {
    if (ec || stopped_) return;
    BroadcastPresence();
    SchedulePresence();
  });
}

void Server::BroadcastPresence() {
  std::vector<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard<std::mutex> lock(sessions_mu_);
    for (const auto& s : sessions_) {
      if (s->joined()) sessions.push_back(s);
    }
  }
  if (sessions.size() < 2) return;
  auto msg = std::make_shared<v1::ServerMessage>();
  for (const auto& s : sessions) *msg->mutable_presence()->add_users() = s->PresenceEntry();
  for (const auto& s : sessions) s->PostPresence(msg);
}

}  // namespace sculpt::server
