/// @brief FakeSculptd: a scripted stand-in for sculptd on a loopback port, for client tests that
/// must not depend on the server: it answers Hello and JoinScene itself, records every
/// ClientMessage and lets the test answer the rest (or not, or drop the connection).
#ifndef SCULPT_TESTS_UNIT_CLIENT_FAKE_SCULPTD_H_
#define SCULPT_TESTS_UNIT_CLIENT_FAKE_SCULPTD_H_

#include <utility>

#include <boost/asio.hpp>
#include <sys/socket.h>
#include <sys/time.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "sculpt/codec/frame.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::testing_support {

/// One connection at a time; a reconnect is the next accepted connection. Thread safety: the
/// server runs on its own thread; the public methods may be called from any thread.
class FakeSculptd {
 public:
  /// What to do with a message that is not Hello or JoinScene: the messages to send back, and
  /// whether to close the connection after them.
  struct Reply {
    std::vector<v1::ServerMessage> messages;
    bool close = false;
  };
  using Handler = std::function<Reply(const v1::ClientMessage&, int connection)>;

  /// Scene "fake" with objects "clay" and "stone".
  explicit FakeSculptd(Handler handler = nullptr)
      : handler_(std::move(handler)),
        acceptor_(io_, {boost::asio::ip::make_address("127.0.0.1"), 0}) {
    thread_ = std::thread([this] { Run(); });
  }
  ~FakeSculptd() {
    stop_ = true;
    // A blocking accept does not wake when the acceptor is closed from another thread: a
    // connection of our own wakes it; a served connection sees stop_ within 50 ms.
    boost::system::error_code ignored;
    boost::asio::ip::tcp::socket wake(io_);
    wake.connect({boost::asio::ip::make_address("127.0.0.1"), port()}, ignored);
    thread_.join();
    acceptor_.close(ignored);
  }

  uint16_t port() const { return acceptor_.local_endpoint().port(); }

  void set_handler(Handler handler) {
    std::lock_guard<std::mutex> lock(mu_);
    handler_ = std::move(handler);
  }

  /// SceneInfo.cluster_members of every later join's answer (cluster mode).
  void set_cluster_members(std::vector<v1::ClusterMember> members) {
    std::lock_guard<std::mutex> lock(mu_);
    cluster_members_ = std::move(members);
  }

  /// Every message received (Hello and JoinScene included), with its connection number (0, 1..).
  std::vector<std::pair<int, v1::ClientMessage>> received() const {
    std::lock_guard<std::mutex> lock(mu_);
    return received_;
  }

  /// Waits until `pred(received())` holds; false after `timeout`.
  bool WaitFor(const std::function<bool(const std::vector<std::pair<int, v1::ClientMessage>>&)>& pred,
               std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    std::unique_lock<std::mutex> lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return pred(received_); });
  }

  /// The UndoRequests received, in order.
  std::vector<v1::UndoRequest> undos() const {
    std::vector<v1::UndoRequest> out;
    for (const auto& [c, m] : received()) {
      if (m.has_undo()) out.push_back(m.undo());
    }
    return out;
  }

 private:
  void Run() {
    for (int connection = 0; !stop_; ++connection) {
      boost::asio::ip::tcp::socket socket(io_);
      boost::system::error_code ec;
      acceptor_.accept(socket, ec);
      if (ec || stop_) return;
      timeval tv{0, 50 * 1000};  // reads wake up to see stop_
      setsockopt(socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
      Serve(socket, connection);
    }
  }

  void Serve(boost::asio::ip::tcp::socket& socket, int connection) {
    codec::FrameReader reader;
    char buf[4096];
    while (!stop_) {
      const ssize_t n = ::recv(socket.native_handle(), buf, sizeof buf, 0);
      if (n == 0) return;
      if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) continue;
        return;
      }
      reader.Feed(buf, static_cast<size_t>(n));
      for (;;) {
        auto next = reader.Next();
        if (!next.ok() || !next->has_value()) break;
        v1::ClientMessage m;
        if (!m.ParseFromString(**next)) return;
        Reply reply = Answer(m, connection);
        std::string out;
        for (const v1::ServerMessage& s : reply.messages) codec::AppendMessage(s, &out);
        boost::system::error_code ec;
        if (!out.empty()) boost::asio::write(socket, boost::asio::buffer(out), ec);
        if (ec || reply.close || m.has_bye()) return;
      }
    }
  }

  Reply Answer(const v1::ClientMessage& m, int connection) {
    Handler handler;
    {
      std::lock_guard<std::mutex> lock(mu_);
      received_.emplace_back(connection, m);
      handler = handler_;
    }
    cv_.notify_all();
    Reply r;
    if (m.has_hello()) {
      v1::ServerMessage w;
      w.mutable_welcome()->set_protocol_version(1);
      w.mutable_welcome()->set_role(m.hello().role());
      w.mutable_welcome()->set_client_id(m.hello().client_id());
      r.messages.push_back(w);
    } else if (m.has_join()) {
      v1::ServerMessage s;
      v1::SceneInfo* info = s.mutable_scene_info();
      info->set_scene("fake");
      for (const char* name : {"clay", "stone"}) {
        v1::ObjectInfo* o = info->add_objects();
        o->set_name(name);
        o->set_voxel_size(0.5);
      }
      std::lock_guard<std::mutex> lock(mu_);
      for (const v1::ClusterMember& c : cluster_members_) *info->add_cluster_members() = c;
      r.messages.push_back(s);
    } else if (handler) {
      r = handler(m, connection);
    }
    return r;
  }

  mutable std::mutex mu_;
  std::condition_variable cv_;
  Handler handler_;
  std::vector<std::pair<int, v1::ClientMessage>> received_;
  std::vector<v1::ClusterMember> cluster_members_;
  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// An accepted UndoAck for `request`.
inline v1::ServerMessage AcceptedUndo(const v1::UndoRequest& request, uint64_t global_seq,
                                      uint64_t target_seq) {
  v1::ServerMessage m;
  v1::UndoAck* a = m.mutable_undo_ack();
  a->set_client_seq(request.client_seq());
  a->set_redo(request.redo());
  a->set_accepted(true);
  a->set_global_seq(global_seq);
  a->set_target_seq(target_seq);
  return m;
}

/// An Error with `code`, `field` and `client_seq`.
inline v1::ServerMessage ErrorMessage(v1::ErrorCode code, const std::string& field,
                                      uint64_t client_seq, const std::string& message) {
  v1::ServerMessage m;
  v1::Error* e = m.mutable_error();
  e->set_code(code);
  e->set_field(field);
  e->set_client_seq(client_seq);
  e->set_message(message);
  return m;
}

}  // namespace sculpt::testing_support

#endif  // SCULPT_TESTS_UNIT_CLIENT_FAKE_SCULPTD_H_
