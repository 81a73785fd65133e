/// @brief A deliberately low-level blocking test client: it can send exact bytes (truncated,
/// oversized, garbage) as well as well-formed sculpt.v1 messages.
#ifndef SCULPT_TESTS_INTEGRATION_RAW_CLIENT_H_
#define SCULPT_TESTS_INTEGRATION_RAW_CLIENT_H_

#include <utility>

#include <boost/asio.hpp>
#include <atomic>
#include <chrono>
#include <unistd.h>
#include <optional>
#include <string>
#include <sys/socket.h>
#include <sys/time.h>
#include <vector>

#include "sculpt/codec/frame.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::testing {

class RawClient {
 public:
  explicit RawClient(uint16_t port, int recv_buffer_bytes = 0) : socket_(io_) {
    namespace ip = boost::asio::ip;
    socket_.open(ip::tcp::v4());
    if (recv_buffer_bytes > 0) {
      socket_.set_option(boost::asio::socket_base::receive_buffer_size(recv_buffer_bytes));
    }
    socket_.connect(ip::tcp::endpoint(ip::make_address("127.0.0.1"), port));
    SetTimeoutMs(5000);
  }

  void SetTimeoutMs(int ms) {
    timeval tv{ms / 1000, (ms % 1000) * 1000};
    setsockopt(socket_.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }

  bool SendBytes(const std::string& bytes) {
    boost::system::error_code ec;
    boost::asio::write(socket_, boost::asio::buffer(bytes), ec);
    return !ec;
  }
  bool Send(const v1::ClientMessage& m) {
    std::string out;
    codec::AppendMessage(m, &out);
    return SendBytes(out);
  }

  /// The next server message, or nullopt on timeout / close.
  std::optional<v1::ServerMessage> Read() {
    for (;;) {
      auto next = reader_.Next();
      if (next.ok() && next->has_value()) {
        v1::ServerMessage m;
        if (!m.ParseFromString(**next)) return std::nullopt;
        return m;
      }
      char buf[65536];
      boost::system::error_code ec;
      const size_t n = socket_.read_some(boost::asio::buffer(buf), ec);
      if (ec || n == 0) {
        closed_ = ec == boost::asio::error::eof || ec == boost::asio::error::connection_reset;
        return std::nullopt;
      }
      reader_.Feed(buf, n);
    }
  }
  /// Reads until a message of the wanted body case arrives (skipping presence and others).
  std::optional<v1::ServerMessage> ReadUntil(v1::ServerMessage::BodyCase want) {
    for (;;) {
      auto m = Read();
      if (!m) return std::nullopt;
      if (m->body_case() == want) return m;
    }
  }
  /// True once the server closed the connection (reads until EOF or timeout).
  bool WaitClosed() {
    while (Read()) {
    }
    return closed_;
  }

  static constexpr uint64_t kAutoId = ~uint64_t{0};
  bool Hello(const std::string& token, v1::Role role, uint64_t client_id = kAutoId,
             uint32_t version = 1) {
    static std::atomic<uint64_t> next{1};
    if (client_id == kAutoId) client_id = (static_cast<uint64_t>(::getpid()) << 20) + next++;
    v1::ClientMessage m;
    auto* h = m.mutable_hello();
    h->set_protocol_version(version);
    h->set_token(token);
    h->set_role(role);
    h->set_client_name("raw");
    h->set_client_id(client_id);
    return Send(m);
  }
  bool Join(const v1::JoinScene& join = {}) {
    v1::ClientMessage m;
    *m.mutable_join() = join;
    return Send(m);
  }
  /// Hello + Welcome + Join + SceneInfo + all state chunks.
  bool Enter(const std::string& token, v1::Role role, uint64_t client_id = kAutoId,
             const v1::JoinScene& join = {}) {
    if (!Hello(token, role, client_id)) return false;
    if (!ReadUntil(v1::ServerMessage::kWelcome)) return false;
    if (!Join(join)) return false;
    auto info = ReadUntil(v1::ServerMessage::kSceneInfo);
    if (!info) return false;
    info_ = info->scene_info();
    for (;;) {
      auto c = ReadUntil(v1::ServerMessage::kStateChunk);
      if (!c) return false;
      if (c->state_chunk().index() + 1 == c->state_chunk().count()) return true;
    }
  }

  /// A press stroke of `poses` poses around `at` on object "clay".
  static v1::ClientMessage PressStroke(uint64_t client_seq, const Vec3& at, int poses = 4,
                                       double radius = 2.5) {
    v1::ClientMessage m;
    auto* s = m.mutable_stroke();
    s->set_client_seq(client_seq);
    s->set_object("clay");
    s->set_kind(v1::EDIT_KIND_PRESS);
    s->set_tool(v1::TOOL_KIND_SPHERE);
    s->mutable_tool_size()->set_x(static_cast<float>(radius));
    s->set_speed(60);
    s->mutable_origin()->set_x(static_cast<float>(at.x));
    s->mutable_origin()->set_y(static_cast<float>(at.y));
    s->mutable_origin()->set_z(static_cast<float>(at.z));
    std::vector<codec::Pose> p;
    for (int i = 0; i < poses; ++i) p.push_back({at + Vec3{0.3 * i, 0.2 * i, 0}, uint32_t(8 * i)});
    const Vec3 origin{s->origin().x(), s->origin().y(), s->origin().z()};
    s->set_pose_count(static_cast<uint32_t>(poses));
    s->set_poses(codec::PackPoses(p, origin, 0.5).value());
    return m;
  }

  const v1::SceneInfo& info() const { return info_; }
  void Close() {
    boost::system::error_code ec;
    socket_.close(ec);
  }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket socket_;
  codec::FrameReader reader_{64u << 20};
  v1::SceneInfo info_;
  bool closed_ = false;
};

}  // namespace sculpt::testing

#endif  // SCULPT_TESTS_INTEGRATION_RAW_CLIENT_H_
