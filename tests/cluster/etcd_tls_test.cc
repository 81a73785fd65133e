// TLS to etcd (issue 17, docs/cluster.md "TLS to etcd"): an EtcdClient reaches an etcd whose
// client port speaks only TLS and requires client certificates, verifying etcd's certificate
// (chain and host name) and presenting its own; a wrong CA, a wrong host name and a missing
// client certificate fail as Unavailable saying TLS and why; bad files are refused when the
// client is made. A sculptd member configured with https:// endpoints and the etcd_* files
// registers, owns its scene and acknowledges a client's stroke, and `sculpt cluster status`
// reads it with --etcd-ca, --etcd-cert and --etcd-key.
#include <gtest/gtest.h>

#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "cluster/etcd_client.h"
#include "cluster/processes.h"
#include "cluster/records.h"
#include "integration/test_pki.h"
#include "sculpt/client/client.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::EtcdProcess;
using sculpt::testing::EtcdTlsFiles;
using sculpt::testing::Member;
using sculpt::testing::Pki;
using sculpt::testing::TempDir;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

bool Has(const Status& s, const std::string& text) {
  return s.message().find(text) != std::string::npos;
}

EtcdClient::Options Tls(const std::string& endpoint, const std::string& ca,
                        const std::string& cert = "", const std::string& key = "") {
  EtcdClient::Options o;
  o.endpoints = {endpoint};
  o.timeout = milliseconds(1000);
  o.ca_file = ca;
  o.cert_file = cert;
  o.key_file = key;
  return o;
}

// An etcd on https:// that requires client certificates of the test CA.
class EtcdTlsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!sculpt::testing::HaveEtcd()) GTEST_SKIP() << sculpt::testing::kNoEtcd;
    const Pki& pki = Pki::Get();
    ASSERT_TRUE(pki.ok) << "openssl could not make the test certificates";
    etcd_ = std::make_unique<EtcdProcess>(
        EtcdTlsFiles{pki.File("server.pem"), pki.File("server.key"), pki.File("ca.pem"), true});
    auto c = sculpt::testing::ConnectWhenReady(
        *etcd_, Tls("", pki.File("ca.pem"), pki.File("client.pem"), pki.File("client.key")));
    ASSERT_TRUE(c.ok()) << c.status();
    client_ = std::move(c).value();
  }
  void TearDown() override {
    members_.clear();  // each sculptd before etcd
    client_.reset();
    etcd_.reset();
  }

  std::unique_ptr<EtcdProcess> etcd_;
  std::unique_ptr<EtcdClient> client_;  // the right CA and a client certificate
  std::vector<std::unique_ptr<Member>> members_;
};

TEST_F(EtcdTlsTest, PutGetTxnAndLeaseOverTls) {
  EtcdClient& c = *client_;
  auto lease = c.Sync(c.Grant(milliseconds(5000)));
  ASSERT_TRUE(lease.ok()) << lease.status();
  auto put = c.Sync(c.Put({"tls/a", "one", lease->id}));
  ASSERT_TRUE(put.ok()) << put.status();
  auto got = c.Sync(c.Get("tls/a"));
  ASSERT_TRUE(got.ok()) << got.status();
  ASSERT_TRUE(got->has_value());
  EXPECT_EQ((*got)->value, "one");
  EXPECT_EQ((*got)->lease, lease->id);

  // Create-if-absent: succeeds once, then fails and reads what is there.
  TxnRequest txn;
  txn.compares = {{"tls/b", Compare::Target::kCreateRevision, 0}};
  txn.success = {{"tls/b", "two", 0}};
  txn.failure_ranges = {"tls/b"};
  auto first = c.Sync(c.Txn(txn));
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_TRUE(first->succeeded);
  auto second = c.Sync(c.Txn(txn));
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_FALSE(second->succeeded);
  ASSERT_EQ(second->read.size(), 1u);
  EXPECT_EQ(second->read[0].value, "two");

  auto ttl = c.Sync(c.KeepAlive(lease->id));
  ASSERT_TRUE(ttl.ok()) << ttl.status();
  EXPECT_GT(ttl->count(), 0);
  ASSERT_TRUE(c.Sync(c.Revoke(lease->id)).ok());
  auto gone = c.Sync(c.Get("tls/a"));
  ASSERT_TRUE(gone.ok()) << gone.status();
  EXPECT_FALSE(gone->has_value()) << "the leased key outlived its revoked lease";

  // By host name: the certificate names localhost too (SNI and DNS-name verification).
  const Pki& pki = Pki::Get();
  auto by_name =
      EtcdClient::Create(Tls("https://localhost:" + std::to_string(etcd_->client_port()),
                             pki.File("ca.pem"), pki.File("client.pem"), pki.File("client.key")));
  ASSERT_TRUE(by_name.ok()) << by_name.status();
  auto prefix = (*by_name)->Sync((*by_name)->GetPrefix("tls/"));
  ASSERT_TRUE(prefix.ok()) << prefix.status();
  ASSERT_EQ(prefix->size(), 1u);
  EXPECT_EQ(prefix->front().key, "tls/b");
}

TEST_F(EtcdTlsTest, WrongCaIsUnavailableSayingTlsAndWhy) {
  const Pki& pki = Pki::Get();
  auto c = EtcdClient::Create(Tls(etcd_->endpoint(), pki.File("other-ca.pem"),
                                  pki.File("client.pem"), pki.File("client.key")));
  ASSERT_TRUE(c.ok()) << c.status();
  auto got = (*c)->Sync((*c)->Get("tls/a"));
  ASSERT_FALSE(got.ok());
  const Status& s = got.status();
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
  EXPECT_TRUE(Has(s, "TLS")) << s;
  EXPECT_TRUE(Has(s, "certificate verify failed")) << s;
  EXPECT_TRUE(Has(s, "unable to get local issuer certificate")) << s;
  EXPECT_TRUE(Has(s, etcd_->endpoint())) << s;
}

TEST_F(EtcdTlsTest, MissingClientCertificateIsUnavailableSayingTls) {
  auto c = EtcdClient::Create(Tls(etcd_->endpoint(), Pki::Get().File("ca.pem")));
  ASSERT_TRUE(c.ok()) << c.status();
  auto got = (*c)->Sync((*c)->Get("tls/a"));
  ASSERT_FALSE(got.ok());
  const Status& s = got.status();
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
  EXPECT_TRUE(Has(s, "TLS")) << s;
  EXPECT_TRUE(Has(s, "certificate")) << s;
}

// The member's etcd traffic is TLS with a client certificate: it registers, takes its scene and
// acknowledges a client's stroke.
TEST_F(EtcdTlsTest, MemberOverTlsOwnsItsSceneAndServesAClient) {
  const Pki& pki = Pki::Get();
  TempDir dir("sculpt-etcd-tls");
  const std::string extra = "etcd_ca_file = \"" + pki.File("ca.pem") + "\"\netcd_cert_file = \"" +
                            pki.File("client.pem") + "\"\netcd_key_file = \"" +
                            pki.File("client.key") + "\"\n";
  members_.push_back(std::make_unique<Member>("a", etcd_->endpoint(), dir.path(), extra));
  Member& a = *members_.back();
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir.path() / "a.log";
  const Keys keys{"t/"};
  auto member = client_->Sync(client_->Get(keys.Member("a")));
  ASSERT_TRUE(member.ok()) << member.status();
  ASSERT_TRUE(member->has_value()) << "member a is not registered";
  std::optional<OwnerRecord> owner;
  ASSERT_TRUE(WaitFor(
      [&] {
        auto kv = client_->Sync(client_->Get(keys.Owner("default")));
        if (!kv.ok() || !kv->has_value()) return false;
        auto o = DecodeOwner((*kv)->value);
        if (o.ok()) owner = *o;
        return o.ok();
      },
      milliseconds(5000)));
  EXPECT_EQ(owner->member, "a");
  EXPECT_EQ(owner->epoch, 1u);

  // The operator's view over the same TLS: with the CA and the client certificate it lists a;
  // without the client certificate it says why it could not read.
  const std::string status = "cluster status --etcd " + etcd_->endpoint() + " --prefix t/ --json";
  const sculpt::testing::RunResult listed =
      sculpt::testing::Sculpt(status + " --etcd-ca " + pki.File("ca.pem") + " --etcd-cert " +
                              pki.File("client.pem") + " --etcd-key " + pki.File("client.key"));
  EXPECT_EQ(listed.exit_code, 0) << listed.output;
  EXPECT_NE(listed.output.find("\"a\""), std::string::npos) << listed.output;
  const sculpt::testing::RunResult refused =
      sculpt::testing::Sculpt(status + " --etcd-ca " + pki.File("ca.pem"));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find("TLS"), std::string::npos) << refused.output;
  const sculpt::testing::RunResult half =
      sculpt::testing::Sculpt(status + " --etcd-cert " + pki.File("client.pem"));
  EXPECT_EQ(half.exit_code, 2) << half.output;  // a refused option, as the help says
  EXPECT_NE(half.output.find("--etcd-key"), std::string::npos) << half.output;

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(5000);
  sculpt::client::Client client(options);
  ASSERT_TRUE(client.Connect("127.0.0.1", a.port()).ok());
  auto welcome = client.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "etcd-tls-test", 0);
  ASSERT_TRUE(welcome.ok()) << welcome.status();
  auto joined = client.Join("");
  ASSERT_TRUE(joined.ok()) << joined.status();
  sculpt::client::StrokeRequest stroke;
  stroke.poses = {{{0, 0, 22.5}, 0}, {{0, 0.5, 22.5}, 10}};
  ASSERT_TRUE(client.SendStroke(stroke).ok());
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(5000)));
  EXPECT_EQ(client.stats().acks, 1u);
  EXPECT_EQ(client.stats().refused, 0u);
}

// etcd's certificate names elsewhere.invalid only: reached as 127.0.0.1 or localhost, the
// handshake fails on the name, not on the chain (the CA is the right one).
TEST(EtcdTlsNameTest, WrongHostNameIsUnavailableSayingTlsAndWhy) {
  if (!sculpt::testing::HaveEtcd()) GTEST_SKIP() << sculpt::testing::kNoEtcd;
  const Pki& pki = Pki::Get();
  ASSERT_TRUE(pki.ok) << "openssl could not make the test certificates";
  EtcdProcess etcd(EtcdTlsFiles{pki.File("elsewhere.pem"), pki.File("elsewhere.key"), "", false});
  auto by_ip = EtcdClient::Create(Tls(etcd.endpoint(), pki.File("ca.pem")));
  ASSERT_TRUE(by_ip.ok()) << by_ip.status();
  Status last;
  // Until etcd listens (connection refused before) and answers the handshake (a handshake that
  // timed out, on a loaded machine, says "TLS" but not why), then the name check's reason.
  ASSERT_TRUE(WaitFor(
      [&] {
        last = (*by_ip)->Sync((*by_ip)->Get("x")).status();
        return Has(last, "TLS") && !Has(last, "timeout");
      },
      milliseconds(15000)))
      << last;
  EXPECT_EQ(last.code(), Status::Code::kUnavailable) << last;
  EXPECT_TRUE(Has(last, "IP address mismatch")) << last;

  auto by_name = EtcdClient::Create(
      Tls("https://localhost:" + std::to_string(etcd.client_port()), pki.File("ca.pem")));
  ASSERT_TRUE(by_name.ok()) << by_name.status();
  Status s;
  WaitFor(
      [&] {
        s = (*by_name)->Sync((*by_name)->Get("x")).status();
        return !Has(s, "timeout");
      },
      milliseconds(15000));
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
  EXPECT_TRUE(Has(s, "TLS")) << s;
  EXPECT_TRUE(Has(s, "hostname mismatch")) << s;
}

// The files are read when the client is made: a missing or non-PEM file, half a client
// certificate, a mix of schemes or TLS files for http:// endpoints are refused there, by name.
TEST(EtcdTlsOptionsTest, BadFilesAndSchemesAreInvalidArgumentNamingThem) {
  const Pki& pki = Pki::Get();
  ASSERT_TRUE(pki.ok) << "openssl could not make the test certificates";
  const std::string https = "https://127.0.0.1:2379";
  const std::string missing = (pki.dir / "no-such-ca.pem").string();
  auto s = EtcdClient::Create(Tls(https, missing)).status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "cluster.etcd_ca_file=" + missing)) << s;
  EXPECT_TRUE(Has(s, "no such file")) << s;

  s = EtcdClient::Create(Tls(https, pki.dir.string())).status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "is a directory")) << s;

  s = EtcdClient::Create(Tls(https, pki.File("san.ext"))).status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "cluster.etcd_ca_file=" + pki.File("san.ext"))) << s;
  EXPECT_TRUE(Has(s, "not a PEM CA certificate")) << s;

  s = EtcdClient::Create(Tls(https, pki.File("ca.pem"), pki.File("client.pem"))).status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "cluster.etcd_key_file")) << s;

  s = EtcdClient::Create(
          Tls(https, pki.File("ca.pem"), pki.File("client.pem"), pki.File("server.key")))
          .status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "cluster.etcd_key_file=" + pki.File("server.key"))) << s;

  EtcdClient::Options mixed = Tls(https, pki.File("ca.pem"));
  mixed.endpoints.push_back("http://127.0.0.1:2380");
  s = EtcdClient::Create(mixed).status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "http://127.0.0.1:2380")) << s;

  s = EtcdClient::Create(Tls("http://127.0.0.1:2379", pki.File("ca.pem"))).status();
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << s;
  EXPECT_TRUE(Has(s, "cluster.etcd_ca_file")) << s;

  // The system's store when no CA file is named.
  EXPECT_TRUE(EtcdClient::Create(Tls(https, "")).ok());
}

}  // namespace
}  // namespace sculpt::server::cluster
