// TLS between cluster members (issue 17, docs/cluster.md "TLS between members"): a member whose
// TCP port speaks TLS only could not be followed before, since a standby connected to its owner
// in plaintext. Members now follow over TLS (cluster.peer_ca_file), checking the owner's
// certificate and presenting their own to owners that require one; a certificate from another
// CA stops the follow with the reason in the log.
#include <gtest/gtest.h>
#include <signal.h>

#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "cluster/processes.h"
#include "config/server_config.h"
#include "integration/test_pki.h"
#include "sculpt/client/client.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::AckLog;
using sculpt::testing::EtcdTest;
using sculpt::testing::Member;
using sculpt::testing::Pki;
using sculpt::testing::TempDir;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

constexpr const char* kPeerToken = "peer-tls-test-token-0123456789";

class PeerTlsTest : public EtcdTest {
 protected:
  void SetUp() override {
    EtcdTest::SetUp();
    if (IsSkipped()) return;
    ASSERT_TRUE(Pki::Get().ok) << "openssl could not make the test certificates";
  }
  void TearDown() override {
    members_.clear();
    EtcdTest::TearDown();
  }
  // A member whose TCP port speaks only TLS and asks for client certificates of the test CA;
  // `peer_ca` is the CA it checks other members' certificates against.
  Member& Start(const std::string& name, const std::string& peer_ca) {
    const Pki& pki = Pki::Get();
    const std::string extra =
        std::string("peer_token = \"") + kPeerToken + "\"\npeer_ca_file = \"" + peer_ca +
        "\"\nreplication = \"sync\"\nsync_fallback_ms = 60000\n[tls]\ncert_file = \"" +
        pki.File("server.pem") + "\"\nkey_file = \"" + pki.File("server.key") +
        "\"\nclient_ca_file = \"" + pki.File("ca.pem") + "\"\n";
    members_.push_back(std::make_unique<Member>(name, etcd_->endpoint(), dir_.path(), extra));
    return *members_.back();
  }
  std::string Log(const std::string& member) {
    std::ifstream in(dir_.path() / (member + ".log"));
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  static sculpt::client::ClientOptions TlsClient() {
    sculpt::client::ClientOptions o;
    o.timeout = milliseconds(10000);
    o.tls.enabled = true;
    o.tls.ca_file = Pki::Get().File("ca.pem");
    o.tls.cert_file = Pki::Get().File("client.pem");
    o.tls.key_file = Pki::Get().File("client.key");
    return o;
  }

  TempDir dir_{"sculpt-peer-tls"};
  std::vector<std::unique_ptr<Member>> members_;
};

// Both members on TLS with required client certificates: b follows a over TLS, its word
// releases a's synchronous acks, and when a is killed b takes the scene over with every
// acknowledged stroke.
TEST_F(PeerTlsTest, TlsClusterFollowsSyncsAndFailsOver) {
  const std::string ca = Pki::Get().File("ca.pem");
  Member& a = Start("a", ca);
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  const auto first_owner = AwaitOwner("default", "", milliseconds(5000));
  ASSERT_TRUE(first_owner.has_value());
  ASSERT_EQ(first_owner->member, "a");
  Member& b = Start("b", ca);
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(WaitFor(
      [&] {
        auto s = StandbyOf("default");
        auto m = MemberOf("b");
        return s && s->member == "b" && m && m->follows == "default";
      },
      milliseconds(15000)))
      << "b's copy over TLS never completed; see " << dir_.path() / "b.log";

  sculpt::client::Client client(TlsClient());
  AckLog acks(client);
  ASSERT_TRUE(client.Connect("127.0.0.1", a.port()).ok());
  ASSERT_TRUE(client.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "tls-sculptor", 0).ok());
  ASSERT_TRUE(client.Join("").ok());
  for (int i = 0; i < 12; ++i) {
    sculpt::client::StrokeRequest stroke;
    const double x = -4.0 + i * 0.5;
    stroke.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}};
    ASSERT_TRUE(client.SendStroke(stroke).ok());
  }
  // Each ack waited for b's progress, which reaches a only over b's TLS session.
  ASSERT_TRUE(WaitFor([&] { return acks.size() == 12; }, milliseconds(20000)))
      << "a did not acknowledge the strokes; see " << dir_.path() / "a.log";
  acks.Stop();
  client.DropConnection();
  const uint64_t highest = acks.highest();
  EXPECT_EQ(Log("a").find("acknowledging asynchronously"), std::string::npos)
      << "a fell back to async: b's word did not count";

  a.process().Kill(SIGKILL);
  const auto owner = AwaitOwner("default", "b", milliseconds(25000));
  ASSERT_TRUE(owner.has_value()) << "b did not take the scene over; see " << dir_.path() / "b.log";
  EXPECT_EQ(owner->epoch, 2u);
  // b restarted on its copy (the same port file, rewritten); a TLS client finds every
  // acknowledged stroke there.
  uint64_t seq = 0;
  ASSERT_TRUE(WaitFor(
      [&] {
        std::ifstream in(dir_.path() / "b.ports");
        unsigned p = 0;
        if (!(in >> p) || p == 0) return false;
        sculpt::client::Client c(TlsClient());
        if (!c.Connect("127.0.0.1", static_cast<uint16_t>(p)).ok()) return false;
        if (!c.Hello("sculpt-dev-viewer", v1::ROLE_VIEWER, "tls-viewer", 0).ok()) return false;
        auto info = c.Join("");
        if (!info.ok()) return false;
        seq = info->info.global_seq();
        return true;
      },
      milliseconds(15000)))
      << "b did not serve the scene over TLS after the failover; see " << dir_.path() / "b.log";
  EXPECT_GE(seq, highest);
}

// A member checking other members against a CA that did not sign them does not follow, and
// says why: the certificate, not a silent plaintext attempt.
TEST_F(PeerTlsTest, OwnerCertificateFromAnotherCaStopsTheFollow) {
  Member& a = Start("a", Pki::Get().File("ca.pem"));
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return OwnerOf("default").has_value(); }, milliseconds(5000)));
  Member& b = Start("b", Pki::Get().File("other-ca.pem"));
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(
      WaitFor([&] { return Log("b").find("certificate verify failed") != std::string::npos; },
              milliseconds(15000)))
      << "b's log does not name the certificate failure; see " << dir_.path() / "b.log";
  auto m = MemberOf("b");
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->follows, "") << "b follows a although it cannot verify a's certificate";
}

// cluster.peer_ca_file is checked at start-up: a file that is not there, or the setting
// without a cluster, is refused with the field named.
TEST(PeerTlsConfigTest, RejectsMissingFileAndUseWithoutCluster) {
  TempDir dir("sculpt-peer-tls-config");
  const auto load = [&](const std::string& text) -> StatusOr<ServerConfig> {
    const auto path = dir.path() / "sculptd.toml";
    std::ofstream(path) << text;
    ServerConfig c;
    SCULPT_RETURN_IF_ERROR(LoadConfigFile(path.string(), &c));
    SCULPT_RETURN_IF_ERROR(ValidateConfig(c));
    return c;
  };
  auto missing = load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\n"
      "peer_ca_file = \"no-such-ca.pem\"\n");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("cluster.peer_ca_file="), std::string::npos)
      << missing.status();
  EXPECT_NE(missing.status().message().find("no-such-ca.pem"), std::string::npos)
      << missing.status();
  std::ofstream(dir.path() / "ca.pem") << "not used\n";
  auto alone = load("[cluster]\npeer_ca_file = \"ca.pem\"\n");
  ASSERT_FALSE(alone.ok());
  EXPECT_NE(alone.status().message().find("cluster.etcd is empty"), std::string::npos)
      << alone.status();
  auto fine = load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\n"
      "peer_ca_file = \"ca.pem\"\n");
  ASSERT_TRUE(fine.ok()) << fine.status();
  EXPECT_EQ(fine->cluster.peer_ca_file, (dir.path() / "ca.pem").lexically_normal().string());
  EXPECT_TRUE(fine->cluster.PeerTls(fine->tls));
}

}  // namespace
}  // namespace sculpt::server::cluster
