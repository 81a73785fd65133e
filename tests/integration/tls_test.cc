// TLS on sculptd's ports (issue 14), in-process: strokes acked over TLS on the TCP port and over
// WSS on the HTTP port; plaintext, silent handshakes, wrong and expired certificates, missing
// client certificates, and bad TLS files at start-up. The certificates are made at test time by
// the `openssl` command into a temporary directory.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <thread>

#include "integration/in_process_server.h"
#include "integration/raw_client.h"
#include "integration/raw_server.h"
#include "integration/test_pki.h"
#include "net/beast.h"
#include "net/http_server.h"
#include "net/server.h"
#include "net/tls.h"
#include "scene/scene.h"
#include "sculpt/client/client.h"

#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket/ssl.hpp>

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using sculpt::testing::Pki;
using sculpt::testing::RawClient;
using sculpt::testing_support::PressArc;

// A blocking WebSocket-over-TLS client speaking sculpt.v1, one message per binary message.
class WssClient {
 public:
  WssClient(uint16_t port, const std::string& ca_file)
      : ctx_(ssl::context::tls_client), ws_(io_, ctx_) {
    ctx_.load_verify_file(ca_file);
    ctx_.set_verify_mode(ssl::verify_peer);
    beast::get_lowest_layer(ws_).connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    timeval tv{5, 0};
    setsockopt(beast::get_lowest_layer(ws_).native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv,
               sizeof tv);
    ws_.next_layer().handshake(ssl::stream_base::client);
    ws_.handshake("127.0.0.1:" + std::to_string(port), "/ws");
    ws_.binary(true);
  }
  bool Send(const v1::ClientMessage& m) {
    beast::error_code ec;
    ws_.write(asio::buffer(m.SerializeAsString()), ec);
    return !ec;
  }
  std::optional<v1::ServerMessage> ReadUntil(v1::ServerMessage::BodyCase want) {
    for (;;) {
      beast::flat_buffer buf;
      beast::error_code ec;
      ws_.read(buf, ec);
      if (ec) return std::nullopt;
      v1::ServerMessage m;
      if (!m.ParseFromString(beast::buffers_to_string(buf.data()))) return std::nullopt;
      if (m.body_case() == want) return m;
    }
  }

 private:
  asio::io_context io_;
  ssl::context ctx_;
  websocket::stream<beast::ssl_stream<tcp::socket>> ws_;
};

// True once the peer closes a plain socket (EOF or reset), false if it stays open `ms`.
bool ClosedWithin(tcp::socket& s, int ms) {
  timeval tv{ms / 1000, (ms % 1000) * 1000};
  setsockopt(s.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  const auto deadline = Clock::now() + std::chrono::milliseconds(ms);
  char buf[4096];
  while (Clock::now() < deadline) {
    boost::system::error_code ec;
    s.read_some(asio::buffer(buf), ec);
    if (ec == asio::error::eof || ec == asio::error::connection_reset) return true;
    if (ec) return false;  // the receive timeout
  }
  return false;
}

class TlsTest : public sculpt::testing::RawServerTest {
 protected:
  void SetUp() override {
    ASSERT_TRUE(Pki::Get().ok) << "openssl could not make the test certificates";
    Prepare("sculpt_tls");
    config_.scene.voxel_size = 0.5;
    config_.limits.auth_timeout_ms = 400;
    config_.tls.cert_file = pki().File("server.pem");
    config_.tls.key_file = pki().File("server.key");
    with_http_ = true;
    http_config_.listen = "127.0.0.1:0";
    http_config_.web_root = dir_ / "web";
  }
  static const Pki& pki() { return Pki::Get(); }
  client::ClientOptions TlsOptions() {
    client::ClientOptions o;
    o.timeout = std::chrono::seconds(5);
    o.skip_state = true;
    o.tls.enabled = true;
    o.tls.ca_file = pki().File("ca.pem");
    return o;
  }
  // Connect, Hello and Join as a sculptor; the first failure's status.
  Status Enter(client::Client& c, const std::string& host = "127.0.0.1") {
    SCULPT_RETURN_IF_ERROR(c.Connect(host, port_));
    auto w = c.Hello(config_.sculptor_token, v1::ROLE_SCULPTOR, "tls", 0);
    if (!w.ok()) return w.status();
    auto j = c.Join();
    return j.ok() ? Status::Ok() : j.status();
  }
  // Sends `n` strokes and waits for every ack.
  static ::testing::AssertionResult StrokesAcked(client::Client& c, int n, int first = 0) {
    for (int i = first; i < first + n; ++i) {
      auto seq = c.SendStroke(PressArc(0, i));
      if (!seq.ok()) return ::testing::AssertionFailure() << seq.status();
    }
    if (!c.WaitAllAcked(std::chrono::seconds(10))) {
      return ::testing::AssertionFailure() << c.unacked() << " strokes not acked";
    }
    return ::testing::AssertionSuccess();
  }

};

TEST_F(TlsTest, StrokesAckedOverTls) {
  ASSERT_TRUE(TryStart().ok());
  client::Client c(TlsOptions());
  ASSERT_TRUE(Enter(c).ok());
  EXPECT_TRUE(StrokesAcked(c, 40));
  EXPECT_EQ(c.stats().acks, 40u);
  // The certificate names localhost too; the name is checked against it.
  client::Client by_name(TlsOptions());
  ASSERT_TRUE(Enter(by_name, "localhost").ok());
  EXPECT_TRUE(StrokesAcked(by_name, 5, 100));
}

TEST_F(TlsTest, WebSocketOverTlsThroughTheSameSessions) {
  ASSERT_TRUE(TryStart().ok());
  client::Client tcp_client(TlsOptions());
  ASSERT_TRUE(Enter(tcp_client).ok());
  WssClient ws(http_port_, pki().File("ca.pem"));
  v1::ClientMessage hello;
  hello.mutable_hello()->set_protocol_version(1);
  hello.mutable_hello()->set_token(config_.sculptor_token);
  hello.mutable_hello()->set_role(v1::ROLE_SCULPTOR);
  hello.mutable_hello()->set_client_name("wss");
  hello.mutable_hello()->set_client_id(4242);
  ASSERT_TRUE(ws.Send(hello));
  ASSERT_TRUE(ws.ReadUntil(v1::ServerMessage::kWelcome));
  v1::ClientMessage join;
  join.mutable_join()->set_skip_state(true);
  ASSERT_TRUE(ws.Send(join));
  ASSERT_TRUE(ws.ReadUntil(v1::ServerMessage::kSceneInfo));
  v1::ClientMessage stroke = RawClient::PressStroke(1, {0, 0, 23.3});
  ASSERT_TRUE(ws.Send(stroke));
  auto ack = ws.ReadUntil(v1::ServerMessage::kAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->ack().client_seq(), 1u);
  // Both sessions are in one scene: the TCP sculptor's presence lists the WSS one.
  auto p = ws.ReadUntil(v1::ServerMessage::kPresence);
  ASSERT_TRUE(p);
  EXPECT_EQ(p->presence().users_size(), 2);
  EXPECT_TRUE(StrokesAcked(tcp_client, 5));
  EXPECT_GE(server_->stats().stroke_ack_seconds[static_cast<int>(TransportKind::kWebSocket)]
                .Read()
                .count,
            1u);
}

TEST_F(TlsTest, PlaintextOnTheTlsPortsIsClosedAndOthersUnaffected) {
  ASSERT_TRUE(TryStart().ok());
  client::Client sculptor(TlsOptions());
  ASSERT_TRUE(Enter(sculptor).ok());
  // A native client speaking the plain protocol: its Hello is no TLS record.
  RawClient plain(port_);
  v1::ClientMessage hello;
  hello.mutable_hello()->set_protocol_version(1);
  hello.mutable_hello()->set_token(config_.sculptor_token);
  hello.mutable_hello()->set_role(v1::ROLE_SCULPTOR);
  ASSERT_TRUE(plain.Send(hello));
  // Two bytes: too little to tell, so the handshake waits, until the authentication timeout.
  asio::io_context io;
  tcp::socket partial(io);
  partial.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port_));
  asio::write(partial, asio::buffer("\x16\x03", 2));
  // Plain HTTP to the HTTPS port.
  tcp::socket http(io);
  http.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), http_port_));
  asio::write(http, asio::buffer(std::string("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")));
  const auto t0 = Clock::now();
  EXPECT_FALSE(plain.Read().has_value());
  EXPECT_TRUE(plain.WaitClosed());
  EXPECT_TRUE(ClosedWithin(http, 2000));
  EXPECT_TRUE(ClosedWithin(partial, 2000));
  const double waited_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  EXPECT_LT(waited_ms, config_.limits.auth_timeout_ms + 1000);
  // The library's own client, without TLS, is told what to do.
  client::ClientOptions po;
  po.timeout = std::chrono::seconds(3);
  client::Client plain_client(po);
  const Status ps = Enter(plain_client);
  EXPECT_EQ(ps.code(), Status::Code::kUnavailable);
  EXPECT_NE(ps.message().find("connect with --tls"), std::string::npos) << ps;
  // The TLS sculptor kept sculpting throughout.
  EXPECT_TRUE(StrokesAcked(sculptor, 20));
  EXPECT_GE(server_->stats().tls_handshake_failures.load(), 2u);
  EXPECT_GE(http_->stats().tls_handshake_failures.load(), 1u);
}

TEST_F(TlsTest, HandshakeThatNeverCompletesIsClosedWithinTheAuthTimeout) {
  ASSERT_TRUE(TryStart().ok());
  asio::io_context io;
  tcp::socket silent_tcp(io), silent_http(io);
  silent_tcp.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port_));
  silent_http.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), http_port_));
  const auto t0 = Clock::now();
  EXPECT_TRUE(ClosedWithin(silent_tcp, 3000));
  EXPECT_TRUE(ClosedWithin(silent_http, 3000));
  const double waited_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  EXPECT_GE(waited_ms, config_.limits.auth_timeout_ms * 0.9);
  EXPECT_LT(waited_ms, config_.limits.auth_timeout_ms + 1000);
}

TEST_F(TlsTest, WrongCertificateFailsWithAClearError) {
  ASSERT_TRUE(TryStart().ok());
  // A CA that did not sign the server's certificate.
  client::ClientOptions o = TlsOptions();
  o.tls.ca_file = pki().File("other-ca.pem");
  client::Client wrong_ca(o);
  const Status s = wrong_ca.Connect("127.0.0.1", port_);
  EXPECT_EQ(s.code(), Status::Code::kUnavailable);
  EXPECT_NE(s.message().find("certificate verify failed: unable to get local issuer certificate"),
            std::string::npos)
      << s;
  // The right CA, but a name the certificate does not carry.
  client::ClientOptions named = TlsOptions();
  named.tls.server_name = "sculpt.example.org";
  client::Client wrong_name(named);
  const Status n = wrong_name.Connect("127.0.0.1", port_);
  EXPECT_NE(n.message().find("hostname mismatch"), std::string::npos) << n;
  // The name check can be turned off (the chain is still verified).
  named.tls.verify_server_name = false;
  client::Client unnamed(named);
  EXPECT_TRUE(Enter(unnamed).ok());
}

TEST_F(TlsTest, ExpiredCertificateFailsWithAClearError) {
  config_.tls.cert_file = pki().File("expired.pem");
  config_.tls.key_file = pki().File("expired.key");
  ASSERT_TRUE(TryStart().ok());  // starts (with a warning in the log): clients refuse it
  client::Client c(TlsOptions());
  const Status s = c.Connect("127.0.0.1", port_);
  EXPECT_EQ(s.code(), Status::Code::kUnavailable);
  EXPECT_NE(s.message().find("certificate has expired"), std::string::npos) << s;
}

TEST_F(TlsTest, ClientCertificateRequiredAndMissingIsRefused) {
  config_.tls.client_ca_file = pki().File("ca.pem");
  ASSERT_TRUE(TryStart().ok());
  client::Client without(TlsOptions());
  const Status s = Enter(without);
  EXPECT_FALSE(s.ok());
  // TLS 1.3 completes the client's side first; the server's alert ends the connection before
  // any Welcome, and the client says why.
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
  EXPECT_NE(s.message().find("certificate required"), std::string::npos) << s;
  client::ClientOptions o = TlsOptions();
  o.tls.cert_file = pki().File("client.pem");
  o.tls.key_file = pki().File("client.key");
  client::Client with(o);
  ASSERT_TRUE(Enter(with).ok());
  EXPECT_TRUE(StrokesAcked(with, 5));
  // A certificate from another CA is refused the same way.
  o.tls.cert_file = pki().File("other-ca.pem");
  o.tls.key_file = pki().File("other-ca.key");
  client::Client foreign(o);
  EXPECT_FALSE(Enter(foreign).ok());
  // The HTTP port asks browsers for no certificate.
  WssClient ws(http_port_, pki().File("ca.pem"));
}

TEST_F(TlsTest, RefusesStartWithAMissingCertificateNamingKeyAndFile) {
  config_.tls.cert_file = (dir_ / "nope.pem").string();
  const Status s = TryStart();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("tls.cert_file=" + config_.tls.cert_file), std::string::npos) << s;
  config_.tls.cert_file = pki().File("server.pem");
  config_.tls.client_ca_file = (dir_ / "ca-nope.pem").string();
  auto ctx = MakeServerTlsContext(config_.tls, true);
  ASSERT_FALSE(ctx.ok());
  EXPECT_NE(ctx.status().message().find("tls.client_ca_file=" + config_.tls.client_ca_file),
            std::string::npos);
}

TEST_F(TlsTest, RefusesAKeyThatDoesNotMatchTheCertificate) {
  config_.tls.key_file = pki().File("client.key");
  auto ctx = MakeServerTlsContext(config_.tls, true);
  ASSERT_FALSE(ctx.ok());
  EXPECT_EQ(ctx.status().code(), Status::Code::kInvalidArgument);
  EXPECT_NE(ctx.status().message().find("tls.key_file=" + config_.tls.key_file +
                                        " does not match the certificate in tls.cert_file=" +
                                        config_.tls.cert_file),
            std::string::npos)
      << ctx.status();
  // Not PEM at all.
  std::ofstream(dir_ / "garbage.pem") << "not a certificate\n";
  config_.tls.cert_file = (dir_ / "garbage.pem").string();
  auto garbage = MakeServerTlsContext(config_.tls, true);
  ASSERT_FALSE(garbage.ok());
  EXPECT_NE(garbage.status().message().find("tls.cert_file=" + config_.tls.cert_file),
            std::string::npos);
}

TEST_F(TlsTest, PlaintextOnlyOnLoopbackUnlessAllowed) {
  ServerConfig c;
  EXPECT_TRUE(ValidateConfig(c).ok());  // the embedded default: plaintext on 127.0.0.1
  c.listen = "0.0.0.0:7420";
  // Beyond loopback the development tokens are refused too (NamedUsersConfigTest): own ones.
  c.sculptor_token = "a-long-sculptor-secret";
  c.viewer_token = "a-long-viewer-secret";
  const Status s = ValidateConfig(c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("allow_plaintext"), std::string::npos) << s;
  c.tls.allow_plaintext = true;
  EXPECT_TRUE(ValidateConfig(c).ok());
  c.tls.allow_plaintext = false;
  c.tls.cert_file = "server.pem";
  EXPECT_FALSE(ValidateConfig(c).ok());  // a certificate without its key
  c.tls.key_file = "server.key";
  EXPECT_TRUE(ValidateConfig(c).ok());
  c.listen = "[::1]:7420";
  c.tls = {};
  EXPECT_TRUE(ValidateConfig(c).ok());
  EXPECT_TRUE(IsLoopbackListen("localhost:1"));
  EXPECT_TRUE(IsLoopbackListen("127.0.0.2:1"));
  EXPECT_FALSE(IsLoopbackListen("10.0.0.1:1"));
  // The HTTP port follows the same rule.
  http_config_.listen = "0.0.0.0:0";
  config_.tls = {};
  const Status h = TryStart();
  ASSERT_FALSE(h.ok());
  EXPECT_NE(h.message().find("http listen=0.0.0.0:0"), std::string::npos) << h;
}

TEST_F(TlsTest, ConfigFileTlsSectionWithPathsFromItsFolder) {
  std::ofstream(dir_ / "scene.toml") << "[tls]\ncert_file = \"certs/server.pem\"\n"
                                        "key_file = \"/abs/server.key\"\nallow_plaintext = true\n";
  ServerConfig c;
  ASSERT_TRUE(LoadConfigFile((dir_ / "scene.toml").string(), &c).ok());
  EXPECT_EQ(c.tls.cert_file, (dir_ / "certs/server.pem").string());
  EXPECT_EQ(c.tls.key_file, "/abs/server.key");
  EXPECT_TRUE(c.tls.allow_plaintext);
  std::ofstream(dir_ / "typo.toml") << "[tls]\ncert = \"x\"\n";
  const Status s = LoadConfigFile((dir_ / "typo.toml").string(), &c);
  EXPECT_NE(s.message().find("unknown key tls.cert"), std::string::npos) << s;
}

// Stroke->ack over TLS vs plaintext, one run: two in-process sculptds with the same scene (one
// with TLS), a sculptor on each, strokes alternating one at a time so both see the same load.
// A measurement (docs/benchmarks.md, "TLS"), not a test: run with --gtest_also_run_disabled_tests.
TEST(TlsBench, DISABLED_StrokeAckTlsVsPlaintext) {
  ASSERT_TRUE(Pki::Get().ok);
  testing_support::InProcessServer plain("tlsbench_plain"), secure("tlsbench_tls");
  for (auto* s : {&plain, &secure}) {
    s->config().limits.strokes_per_second = 1000;
    s->config().limits.stroke_burst = 1000;
  }
  secure.config().tls.cert_file = Pki::Get().File("server.pem");
  secure.config().tls.key_file = Pki::Get().File("server.key");
  ASSERT_TRUE(plain.Start());
  ASSERT_TRUE(secure.Start());
  client::ClientOptions po;
  po.skip_state = true;
  client::ClientOptions so = po;
  so.tls.enabled = true;
  so.tls.ca_file = Pki::Get().File("ca.pem");
  client::Client a(po), b(so);
  for (auto [c, port] : {std::pair{&a, plain.port()}, std::pair{&b, secure.port()}}) {
    ASSERT_TRUE(c->Connect("127.0.0.1", port).ok());
    ASSERT_TRUE(c->Hello(plain.config().sculptor_token, v1::ROLE_SCULPTOR, "bench", 0).ok());
    ASSERT_TRUE(c->Join().ok());
  }
  const int kStrokes = 400;
  std::vector<double> plain_ms, tls_ms;
  auto one = [](client::Client& c, int i, std::vector<double>* out) {
    const auto t0 = Clock::now();
    ASSERT_TRUE(c.SendStroke(PressArc(0, i, 1)).ok());
    ASSERT_TRUE(c.WaitAllAcked(std::chrono::seconds(10)));
    out->push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  };
  for (int i = 0; i < kStrokes; ++i) {
    // Which goes first alternates too.
    if (i % 2 == 0) {
      one(a, i, &plain_ms);
      one(b, i, &tls_ms);
    } else {
      one(b, i, &tls_ms);
      one(a, i, &plain_ms);
    }
  }
  auto pct = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(q * (v.size() - 1))];
  };
  std::printf("{\"strokes\": %d, \"plain_p50_ms\": %.3f, \"plain_p99_ms\": %.3f, "
              "\"tls_p50_ms\": %.3f, \"tls_p99_ms\": %.3f, \"added_p50_ms\": %.3f}\n",
              kStrokes, pct(plain_ms, 0.5), pct(plain_ms, 0.99), pct(tls_ms, 0.5),
              pct(tls_ms, 0.99), pct(tls_ms, 0.5) - pct(plain_ms, 0.5));
  EXPECT_EQ(tls_ms.size(), plain_ms.size());
}

}  // namespace
}  // namespace sculpt::server
