/// @brief libFuzzer target for sculptd's message handler: arbitrary sequences of client messages
/// (session_input.h) delivered through an in-memory transport to one or two sessions of a real
/// Server and Scene. Two small scenes, chosen by the input: a sphere and a skin with contours on,
/// and the same with two materials declared (paint; undo is refused there).
///
/// The servers live for the whole process (a new scene every kScenesEvery inputs keeps their
/// state small); each input gets fresh sessions, which are closed at its end. It fails (aborts) when
///  - an answer frame is not a length-prefixed, parseable, non-empty sculpt.v1.ServerMessage;
///  - a session is still registered with the server after its peer closed and the server idled;
///  - a fresh, well-behaved sculptor can no longer Hello, JoinScene and get a stroke acknowledged
///    (checked on the first input and every kHealthEvery inputs; after every input when replayed
///    by `make test`, SCULPT_FUZZ_REPLAY);
/// and, under the sanitizers, on any memory error, leak or undefined behaviour.
#include <sodium.h>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <google/protobuf/stubs/logging.h>

#include "net/server.h"
#include "net/transport.h"
#include "scene/scene.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"
#include "session_input.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

#ifdef SCULPT_FUZZ_REPLAY
constexpr uint64_t kHealthEvery = 1;
#else
constexpr uint64_t kHealthEvery = 64;
#endif
constexpr uint64_t kScenesEvery = 4096;

// SCULPT_FUZZ_LOG=1: sculptd's log lines on stderr; 2: every answer too (to check a seed).
const char* const kLogEnv = std::getenv("SCULPT_FUZZ_LOG");
const bool kShowAnswers = kLogEnv != nullptr && std::string(kLogEnv) == "2";

[[noreturn]] void Fail(const std::string& what) {
  std::fprintf(stderr, "session fuzz invariant failed: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

// Every frame a session writes must be what a client can read: a 4-byte little-endian length, then
// that many bytes of a ServerMessage with its body set.
v1::ServerMessage CheckAnswer(const std::string& frame) {
  if (frame.size() < 4) Fail("answer frame of " + std::to_string(frame.size()) + " bytes");
  uint32_t n = 0;
  for (int i = 0; i < 4; ++i) n |= static_cast<uint32_t>(static_cast<uint8_t>(frame[i])) << (8 * i);
  if (n != frame.size() - 4) {
    Fail("answer frame prefix " + std::to_string(n) + " for " + std::to_string(frame.size() - 4) +
         " bytes");
  }
  v1::ServerMessage m;
  if (!m.ParseFromArray(frame.data() + 4, static_cast<int>(n))) Fail("answer does not parse");
  if (m.body_case() == v1::ServerMessage::BODY_NOT_SET) Fail("answer without a body");
  return m;
}

// A connection in memory. The session calls it on its strand; the driver below calls it from the
// one thread that polls the io_context, so nothing here is shared between threads.
class FakeTransport final : public Transport {
 public:
  FakeTransport(Strand strand, std::string remote, TransportKind kind, bool keep_answers)
      : strand_(std::move(strand)),
        remote_(std::move(remote)),
        kind_(kind),
        keep_answers_(keep_answers) {}

  TransportKind kind() const override { return kind_; }
  std::string remote() const override { return remote_; }
  void AsyncRead(ReadHandler done) override {
    OnDriverThread();
    trace_ += " R";
    if (closed_) return Post(std::move(done), Ended());
    read_ = std::move(done);
  }
  void AsyncWrite(std::vector<Frame> frames, WriteHandler done) override {
    uint64_t bytes = 0;
    OnDriverThread();
    trace_ += " W";
    for (const Frame& f : frames) {
      v1::ServerMessage m = CheckAnswer(*f);
      trace_ += std::to_string(m.body_case()) + ",";
      if (kShowAnswers) {
        std::fprintf(stderr, "%s <- %.200s\n", remote_.c_str(), m.ShortDebugString().c_str());
      }
      if (keep_answers_) answers.push_back(std::move(m));
      bytes += f->size();
    }
    if (closed_) {
      asio::post(strand_, [done = std::move(done)] {
        done(Status(Status::Code::kUnavailable, "closed"), 0);
      });
    } else if (stalled_) {
      held_ = std::move(done);
      held_bytes_ = bytes;
    } else {
      asio::post(strand_, [done = std::move(done), bytes] { done(Status::Ok(), bytes); });
    }
  }
  void Close() override {
    trace_ += " C";
    closed_ = true;
    if (read_) Post(std::exchange(read_, nullptr), Ended());
    if (held_) {
      asio::post(strand_, [done = std::exchange(held_, nullptr)] {
        done(Status(Status::Code::kUnavailable, "closed"), 0);
      });
    }
  }

  // Driver side. Hands `r` to the pending read; false when none is pending (closed).
  bool Deliver(ReadResult r) {
    trace_ += " D" + std::to_string(r.payloads.size()) + "/" + std::to_string(int(r.end));
    if (!read_) return false;
    Post(std::exchange(read_, nullptr), std::move(r));
    return true;
  }
  bool read_pending() const { return static_cast<bool>(read_); }
  bool closed() const { return closed_; }
  std::string State() const {
    return remote_ + (closed_ ? " closed" : " open") + (read_ ? " reading" : "") +
           (held_ ? " write-held" : "") + (stalled_ ? " stalled" : "") + " trace:" + trace_;
  }
  void SetStalled(bool stalled) {
    stalled_ = stalled;
    if (!stalled_ && held_) {
      asio::post(strand_, [done = std::exchange(held_, nullptr), bytes = held_bytes_] {
        done(Status::Ok(), bytes);
      });
    }
  }

  std::vector<v1::ServerMessage> answers;  // kept when keep_answers

 private:
  void OnDriverThread() const {
    if (std::this_thread::get_id() != driver_) Fail("transport called off the driver's thread");
  }
  static ReadResult Ended() {
    ReadResult r;
    r.end = ReadResult::End::kClosed;
    r.reason = Status(Status::Code::kUnavailable, "connection closed");
    return r;
  }
  void Post(ReadHandler h, ReadResult r) {
    asio::post(strand_, [h = std::move(h), r = std::move(r)]() mutable { h(std::move(r)); });
  }

  Strand strand_;
  const std::string remote_;
  const TransportKind kind_;
  const bool keep_answers_;
  ReadHandler read_;
  WriteHandler held_;
  uint64_t held_bytes_ = 0;
  bool stalled_ = false;
  bool closed_ = false;
  std::string trace_;
  const std::thread::id driver_ = std::this_thread::get_id();
};

// The scene: small and cheap to edit, with every kind of edit available (strokes, a skin with
// contours; paint when `materials`); limits such that the fuzzer is not throttled by wall-clock
// rate limits it cannot control, and a small send queue so that stalled writes overflow it.
ServerConfig FuzzConfig(const fs::path& data_dir, bool materials) {
  ServerConfig c;
  c.listen = "127.0.0.1:0";
  c.data_dir = data_dir.string();
  c.snapshot_every_seconds = 86400;
  SceneConfig& s = c.scene;
  s.voxel_size = 0.5;
  s.objects[0].radius = 4;
  s.min_tool_size = 0.5;
  s.max_tool_size = 2;
  s.bounds_margin = 2;
  s.mesh_chunk_voxels = 16;
  if (materials) s.materials = {{"clay", {0.8, 0.5, 0.3}}, {"glaze", {0.2, 0.4, 0.9}}};
  SkinConfig skin;
  skin.balls = {{-2, 0, 1, 0}, {0, 1, 1.2, 0.3}, {2, 0, 1, 0}};
  s.skins.push_back(skin);
  s.effects.contours = true;
  LimitsConfig& l = c.limits;
  l.max_poses_per_stroke = 8;
  // The largest rates ValidateConfig allows.
  l.strokes_per_second = 1e5;
  l.stroke_burst = l.poses_per_second = l.requests_per_second = 1e6;
  l.pose_burst = l.request_burst = 1e7;
  l.auth_backoff_ms = 0;
  l.send_queue_bytes = 64 * 1024;
  l.violations_before_disconnect = 8;
  return c;
}

class World {
 public:
  explicit World(bool materials) : materials_(materials) {
    const fs::path base = fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
    dir_ = base / ("sculpt-fuzz-session-" + std::to_string(::getpid()) +
                   (materials ? "-materials" : "-plain"));
    fs::remove_all(dir_);
    Open();
  }
  ~World() {
    Close();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // Runs everything that is ready until nothing is: the sessions' handlers, the scene's compute
  // thread (Flush: every task posted so far has run, every durable answer released) and late
  // joins. The mesher thread's chunks may still arrive later; they go to the sessions then.
  void Pump() {
    for (int round = 0; round < 256; ++round) {
      if (io_->poll() > 0) continue;
      if (!scene_) return;
      scene_->Flush();
      if (io_->poll() > 0) continue;
      if (scene_->pending_joins() == 0) return;
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
  }
  void Poll() { io_->poll(); }
  // Polls until `done` holds; false after `limit`. Handlers posted by the scene's threads can be
  // late by a scheduler time slice on a loaded machine (a thread preempted between taking a
  // strand and queueing it), so whatever an invariant depends on is waited for, not assumed.
  template <typename Pred>
  bool WaitFor(Pred done, std::chrono::milliseconds limit = std::chrono::seconds(5)) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (!done()) {
      if (io_->poll() > 0) continue;
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    return true;
  }
  void BroadcastPresence() {
    server_->BroadcastPresence();
    io_->poll();
  }

  // A new connection to the server, as the acceptor would hand it over.
  std::shared_ptr<FakeTransport> Connect(const std::string& remote, TransportKind kind,
                                         bool keep_answers) {
    Strand strand = asio::make_strand(*io_);
    auto t = std::make_shared<FakeTransport>(strand, remote, kind, keep_answers);
    if (!server_->Adopt(strand, t)) Fail("the server refused to adopt a connection");
    io_->poll();
    return t;
  }

  std::string DescribeSessions() {
    std::string out;
    for (const auto& [key, count] : server_->CountSessions()) {
      if (count > 0) out += key.first + "/" + key.second + "=" + std::to_string(count) + " ";
    }
    return out;
  }
  size_t LiveSessions() {
    size_t n = 0;
    for (const auto& [key, count] : server_->CountSessions()) n += count;
    return n;
  }

  // Every kScenesEvery inputs: a new scene, so that thousands of strokes do not make each input
  // slower than the last.
  void MaybeRenew() {
    if (++inputs_ % kScenesEvery != 0) return;
    Close();
    Open();
  }
  uint64_t inputs() const { return inputs_; }
  const ServerConfig& config() const { return config_; }

 private:
  void Open() {
    const fs::path data = dir_ / ("scene-" + std::to_string(epoch_++));
    config_ = FuzzConfig(data, materials_);
    if (const Status v = ValidateConfig(config_); !v.ok()) Fail("fuzz config: " + v.ToString());
    io_ = std::make_unique<asio::io_context>();
    guard_.emplace(io_->get_executor());
    auto scene = Scene::Open(config_);
    if (!scene.ok()) Fail("scene: " + scene.status().ToString());
    scene_ = std::move(scene).value();
    server_ = std::make_unique<Server>(*io_, config_, *scene_);
  }
  void Close() {
    if (!server_) return;
    server_->Stop();  // posts the acceptor's close: run it while the server exists
    Pump();
    scene_.reset();  // joins its threads; late answers are posted to closed sessions
    io_->poll();
    server_.reset();
    guard_.reset();
    io_.reset();
    std::error_code ec;
    fs::remove_all(config_.data_dir, ec);
  }

  const bool materials_;
  fs::path dir_;
  uint64_t epoch_ = 0;
  uint64_t inputs_ = 0;
  ServerConfig config_;
  std::unique_ptr<asio::io_context> io_;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> guard_;
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Server> server_;
};

void Setup() {
  static const bool done = [] {
    // Invalid UTF-8 in a string field is an expected rejection; protobuf's log line for each one
    // would drown the fuzzer's output. sculptd's own log lines are formatted into a null sink
    // (unless SCULPT_FUZZ_LOG is set).
    google::protobuf::SetLogHandler(nullptr);
    if (kLogEnv == nullptr) {
      spdlog::set_default_logger(std::make_shared<spdlog::logger>(
          "fuzz", std::make_shared<spdlog::sinks::null_sink_mt>()));
    }
    if (sodium_init() < 0) Fail("libsodium failed to initialise");
    return true;
  }();
  (void)done;
}

World* TheWorld(bool materials) {
  Setup();
  static World* plain = nullptr;
  static World* painted = nullptr;
  World*& w = materials ? painted : plain;
  if (w == nullptr) {
    w = new World(materials);
    if (materials) {
      std::atexit([] { delete painted; });
    } else {
      std::atexit([] { delete plain; });
    }
  }
  return w;
}

// One fuzzed connection: its transport and the messages of the read being assembled.
struct Client {
  std::shared_ptr<FakeTransport> transport;
  ReadResult pending;
  bool has_pending = false;

  void Flush(World& w) {
    if (!has_pending) return;
    has_pending = false;
    Deliver(w, std::exchange(pending, ReadResult{}));
  }
  void End(World& w, ReadResult r) {
    Flush(w);
    Deliver(w, std::move(r));
  }
  // A session reads again after every read unless it is closing: wait for that, then hand over.
  void Deliver(World& w, ReadResult r) {
    const FakeTransport& t = *transport;
    if (!w.WaitFor([&t] { return t.read_pending() || t.closed(); })) {
      Fail("a session neither reads nor closes: " + t.State());
    }
    if (transport->Deliver(std::move(r))) w.Poll();
  }
};

std::string Serialize(const v1::ClientMessage& m) {
  std::string s;
  m.SerializeToString(&s);
  return s;
}

// A well-behaved sculptor from another address: Hello, JoinScene, one stroke, its Ack.
void CheckStillServed(World& w) {
  static uint64_t n = 0;
  ++n;
  auto t = w.Connect("127.0.0.2:" + std::to_string(1000 + n % 50000), TransportKind::kTcp, true);
  auto send = [&](const v1::ClientMessage& m) {
    ReadResult r;
    r.payloads.push_back(Serialize(m));
    r.bytes = r.payloads.back().size() + 4;
    const FakeTransport& ft = *t;
    if (!w.WaitFor([&ft] { return ft.read_pending() || ft.closed(); }) ||
        !t->Deliver(std::move(r))) {
      Fail("well-behaved sculptor: connection closed (" + t->State() + ")");
    }
    w.Pump();
  };
  auto expect = [&](v1::ServerMessage::BodyCase want, const char* step) {
    const FakeTransport& ft = *t;
    auto answered = [&ft, want] {
      for (const v1::ServerMessage& m : ft.answers) {
        if (m.body_case() == want || m.has_error() || m.has_bye()) return true;
      }
      return false;
    };
    w.WaitFor([&] {
      w.Pump();
      return answered();
    });
    for (const v1::ServerMessage& m : t->answers) {
      if (m.body_case() == want) return;
      if (m.has_error() || m.has_bye()) {
        Fail(std::string("well-behaved sculptor refused at ") + step + ": " + m.ShortDebugString());
      }
    }
    Fail(std::string("well-behaved sculptor got no answer to ") + step + " (" +
         std::to_string(t->answers.size()) + " answers)");
  };

  v1::ClientMessage hello;
  hello.mutable_hello()->set_protocol_version(1);
  hello.mutable_hello()->set_token(w.config().sculptor_token);
  hello.mutable_hello()->set_role(v1::ROLE_SCULPTOR);
  hello.mutable_hello()->set_client_name("health");
  hello.mutable_hello()->set_client_id(0x4845414c54480000ull + n);
  send(hello);
  expect(v1::ServerMessage::kWelcome, "Hello");

  v1::ClientMessage join;
  join.mutable_join()->set_skip_state(true);
  send(join);
  expect(v1::ServerMessage::kSceneInfo, "JoinScene");

  v1::ClientMessage stroke;
  v1::Stroke* s = stroke.mutable_stroke();
  s->set_client_seq(1);
  s->set_object(w.config().scene.objects[0].name);
  s->set_kind(v1::EDIT_KIND_PRESS);
  s->set_tool(v1::TOOL_KIND_SPHERE);
  s->mutable_tool_size()->set_x(1);
  s->set_speed(60);
  const Vec3 at{0, 0, w.config().scene.objects[0].radius};
  s->mutable_origin()->set_z(static_cast<float>(at.z));
  s->set_pose_count(1);
  s->set_poses(codec::PackPoses({codec::Pose{at, 0}}, at, w.config().scene.voxel_size).value());
  send(stroke);
  expect(v1::ServerMessage::kAck, "Stroke");

  v1::ClientMessage bye;
  bye.mutable_bye()->set_reason("done");
  send(bye);
}

}  // namespace
}  // namespace sculpt::server

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace sculpt::server;
  namespace fuzz = sculpt::fuzz;
  if (size == 0) return 0;
  World& w = *TheWorld(data[0] & fuzz::kMaterials);
  w.MaybeRenew();

  static uint64_t port = 0;
  const int clients_n = (data[0] & fuzz::kTwoSessions) ? 2 : 1;
  Client clients[2];
  for (int i = 0; i < clients_n; ++i) {
    clients[i].transport =
        w.Connect("127.0.0.1:" + std::to_string(1024 + port++ % 60000),
                  i == 0 ? TransportKind::kTcp : TransportKind::kWebSocket, false);
  }

  size_t at = 1;
  while (at < size) {
    const uint8_t op = data[at++];
    Client& c = clients[(op & fuzz::kSessionB) && clients_n == 2 ? 1 : 0];
    const uint8_t arg = op >> 4;
    switch (op & 7) {
      case fuzz::kPump:
        for (int i = 0; i < clients_n; ++i) clients[i].Flush(w);
        w.Pump();
        break;
      case fuzz::kStall:
        c.transport->SetStalled(arg & 1);
        w.Poll();
        break;
      case fuzz::kEnd: {
        ReadResult r;
        switch (arg & 3) {
          case 0:
            r.end = ReadResult::End::kClosed;
            r.reason = sculpt::Status(sculpt::Status::Code::kUnavailable, "peer closed");
            break;
          case 1:
            r.end = ReadResult::End::kTooLarge;
            r.reason = sculpt::FieldViolation(sculpt::Status::Code::kResourceExhausted,
                                              "frame length", "2000000", "[0, 1048576]",
                                              "frame too large");
            break;
          case 2:
            r.end = ReadResult::End::kMalformed;
            r.reason = sculpt::InvalidArgument("a text message of 3 bytes");
            break;
          default:
            r.partial = true;
            r.bytes = 2;
            break;
        }
        c.End(w, std::move(r));
        break;
      }
      case fuzz::kPresence:
        w.BroadcastPresence();
        break;
      default: {  // kMessage and the spare kinds
        size_t n = 0;
        if (at < size) n |= data[at++];
        if (at < size) n |= static_cast<size_t>(data[at++]) << 8;
        if (n > size - at) n = size - at;
        c.pending.payloads.emplace_back(reinterpret_cast<const char*>(data) + at, n);
        c.pending.bytes += n + 4;
        c.has_pending = true;
        at += n;
        if (!(arg & 1)) c.Flush(w);
        break;
      }
    }
  }

  // The peers leave: held writes complete, the last reads arrive, then the connections close.
  for (int i = 0; i < clients_n; ++i) {
    clients[i].transport->SetStalled(false);
    clients[i].Flush(w);
  }
  w.Pump();
  for (int i = 0; i < clients_n; ++i) {
    ReadResult r;
    r.end = ReadResult::End::kClosed;
    r.reason = sculpt::Status(sculpt::Status::Code::kUnavailable, "peer closed");
    clients[i].End(w, std::move(r));
    const FakeTransport& t = *clients[i].transport;
    if (!w.WaitFor([&t] { return t.closed(); })) {
      Fail("a session did not close after its peer closed: " + t.State());
    }
  }
  w.Pump();
  if (const size_t live = w.LiveSessions(); live != 0) {
    std::string state;
    for (int i = 0; i < clients_n; ++i) state += " " + clients[i].transport->State();
    Fail(std::to_string(live) + " session(s) still registered after their peers closed (" +
         w.DescribeSessions() + "; transports:" + state + ")");
  }
  if (w.inputs() % kHealthEvery == 1 || kHealthEvery == 1) CheckStillServed(w);
  return 0;
}
