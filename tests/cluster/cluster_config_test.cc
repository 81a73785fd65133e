// The [cluster] section of sculptd's configuration: read, checked, and absent by default.
#include <gtest/gtest.h>

#include <fstream>

#include "cluster/processes.h"
#include "config/server_config.h"

namespace sculpt::server {
namespace {

class ClusterConfigTest : public ::testing::Test {
 protected:
  // Loads `toml` into a default configuration and validates it.
  Status Load(const std::string& toml, ServerConfig* c) {
    const auto path = dir_.path() / "sculptd.toml";
    std::ofstream(path) << toml;
    SCULPT_RETURN_IF_ERROR(LoadConfigFile(path.string(), c));
    return ValidateConfig(*c);
  }
  Status Load(const std::string& toml) {
    ServerConfig c;
    return Load(toml, &c);
  }
  sculpt::testing::TempDir dir_{"sculpt-cluster-config"};
};

TEST_F(ClusterConfigTest, AbsentSectionIsSingleProcess) {
  ServerConfig c;
  EXPECT_FALSE(c.cluster.enabled());
  ASSERT_TRUE(Load("[server]\ndata_dir = \"d\"\n", &c).ok());
  EXPECT_FALSE(c.cluster.enabled());
}

TEST_F(ClusterConfigTest, ReadsTheSection) {
  ServerConfig c;
  const Status s = Load(R"([cluster]
etcd = ["http://127.0.0.1:2379", "127.0.0.1:22379"]
member = "m-1"
advertise = "127.0.0.1:7420"
advertise_http = "127.0.0.1:7421"
lease_ttl_ms = 3000
prefix = "test/"
)",
                        &c);
  ASSERT_TRUE(s.ok()) << s;
  EXPECT_TRUE(c.cluster.enabled());
  EXPECT_EQ(c.cluster.etcd.size(), 2u);
  EXPECT_EQ(c.cluster.member, "m-1");
  EXPECT_EQ(c.cluster.advertise, "127.0.0.1:7420");
  EXPECT_EQ(c.cluster.advertise_http, "127.0.0.1:7421");
  EXPECT_EQ(c.cluster.lease_ttl_ms, 3000);
  EXPECT_EQ(c.cluster.prefix, "test/");
}

TEST_F(ClusterConfigTest, DefaultLeaseTtlIsTwoSeconds) {
  ServerConfig c;
  ASSERT_TRUE(Load("[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\n", &c).ok());
  EXPECT_EQ(c.cluster.lease_ttl_ms, 2000);
  EXPECT_TRUE(c.cluster.standby);
}

TEST_F(ClusterConfigTest, StandbyMayBeTurnedOff) {
  ServerConfig c;
  ASSERT_TRUE(
      Load("[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\nstandby = false\n", &c)
          .ok());
  EXPECT_FALSE(c.cluster.standby);
}

TEST_F(ClusterConfigTest, ReplicationDefaultsToAsyncAndReadsSync) {
  ServerConfig c;
  ASSERT_TRUE(Load("[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\n", &c).ok());
  EXPECT_EQ(c.cluster.replication, "async");
  EXPECT_EQ(c.cluster.sync_fallback_ms, 1000);
  ServerConfig d;
  const Status s = Load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\nreplication = \"sync\"\n"
      "sync_fallback_ms = 0\n",
      &d);
  ASSERT_TRUE(s.ok()) << s;
  EXPECT_EQ(d.cluster.replication, "sync");
  EXPECT_EQ(d.cluster.sync_fallback_ms, 0);
}

TEST_F(ClusterConfigTest, RejectsUnknownReplication) {
  const Status s = Load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\nreplication = \"semi\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.replication"), std::string::npos) << s;
  EXPECT_NE(s.message().find("semi"), std::string::npos) << s;
  EXPECT_NE(s.message().find("sync, async, none"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, RejectsNegativeSyncFallback) {
  const Status s = Load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\nsync_fallback_ms = -5\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.sync_fallback_ms"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, RejectsMemberWithoutEtcd) {
  const Status s = Load("[cluster]\nmember = \"a\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.etcd is empty"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, RejectsMissingOrBadMemberName) {
  for (const char* member : {"", "a/b", "with space"}) {
    const Status s =
        Load(std::string("[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"") + member +
             "\"\n");
    EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << member;
    ASSERT_NE(s.violation(), nullptr);
    EXPECT_EQ(s.violation()->field, "cluster.member");
  }
}

TEST_F(ClusterConfigTest, RejectsLeaseTtlOutOfRange) {
  for (const char* ttl : {"999", "60001"}) {
    const Status s = Load(std::string("[cluster]\netcd = [\"http://127.0.0.1:2379\"]\n"
                                      "member = \"a\"\nlease_ttl_ms = ") +
                          ttl + "\n");
    EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << ttl;
    EXPECT_NE(s.message().find("cluster.lease_ttl_ms"), std::string::npos) << s;
  }
}

TEST_F(ClusterConfigTest, RejectsMalformedEtcdEndpoint) {
  for (const char* e : {"ftp://127.0.0.1:2379", "http://127.0.0.1", "https://127.0.0.1:0",
                        "http://127.0.0.1:2379/v3"}) {
    const Status s = Load(std::string("[cluster]\netcd = [\"") + e + "\"]\nmember = \"a\"\n");
    EXPECT_EQ(s.code(), Status::Code::kInvalidArgument) << e;
    ASSERT_NE(s.violation(), nullptr) << s;
    EXPECT_EQ(s.violation()->field, "cluster.etcd[0]");
  }
  EXPECT_FALSE(Load("[cluster]\netcd = \"http://127.0.0.1:2379\"\nmember = \"a\"\n").ok());
}

TEST_F(ClusterConfigTest, RejectsPlaintextEtcdBeyondLoopback) {
  const Status s = Load("[cluster]\netcd = [\"http://10.1.2.3:2379\"]\nmember = \"a\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("tls.allow_plaintext"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, ReadsTheEtcdTlsFilesRelativeToTheConfigFile) {
  for (const char* f : {"ca.pem", "client.pem", "client.key"}) std::ofstream(dir_.path() / f) << f;
  ServerConfig c;
  const Status s = Load(R"([cluster]
etcd = ["https://10.1.2.3:2379", "https://etcd.example:2379"]
member = "a"
etcd_ca_file = "ca.pem"
etcd_cert_file = "client.pem"
etcd_key_file = "client.key"
)",
                        &c);
  ASSERT_TRUE(s.ok()) << s;  // beyond loopback is fine over TLS
  EXPECT_EQ(c.cluster.etcd_ca_file, (dir_.path() / "ca.pem").string());
  EXPECT_EQ(c.cluster.etcd_cert_file, (dir_.path() / "client.pem").string());
  EXPECT_EQ(c.cluster.etcd_key_file, (dir_.path() / "client.key").string());
  // No CA file: the system's store.
  EXPECT_TRUE(Load("[cluster]\netcd = [\"https://10.1.2.3:2379\"]\nmember = \"a\"\n").ok());
}

TEST_F(ClusterConfigTest, RejectsMixedEtcdSchemes) {
  const Status s = Load(
      "[cluster]\netcd = [\"https://127.0.0.1:2379\", \"http://127.0.0.1:22379\"]\n"
      "member = \"a\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  ASSERT_NE(s.violation(), nullptr) << s;
  EXPECT_EQ(s.violation()->field, "cluster.etcd[1]");
  EXPECT_NE(s.message().find("http://127.0.0.1:22379"), std::string::npos) << s;
  EXPECT_NE(s.message().find("https://HOST:PORT"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, RejectsBadEtcdTlsFiles) {
  std::ofstream(dir_.path() / "client.pem") << "x";
  const std::string https = "[cluster]\netcd = [\"https://127.0.0.1:2379\"]\nmember = \"a\"\n";
  // A file that is not there, named with its key and path.
  Status s = Load(https + "etcd_ca_file = \"missing.pem\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.etcd_ca_file=" + (dir_.path() / "missing.pem").string()),
            std::string::npos)
      << s;
  EXPECT_NE(s.message().find("not a readable file"), std::string::npos) << s;
  // Half a client certificate.
  s = Load(https + "etcd_cert_file = \"client.pem\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.etcd_key_file is empty"), std::string::npos) << s;
  // TLS files with http:// endpoints, and without a cluster.
  s = Load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\n"
      "etcd_cert_file = \"client.pem\"\netcd_key_file = \"client.pem\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.etcd_cert_file"), std::string::npos) << s;
  EXPECT_NE(s.message().find("https://"), std::string::npos) << s;
  s = Load("[cluster]\netcd_ca_file = \"client.pem\"\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.etcd_ca_file"), std::string::npos) << s;
  EXPECT_NE(s.message().find("cluster.etcd is empty"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, RejectsWildcardListenWithoutAdvertise) {
  const Status s = Load(R"([server]
listen = "0.0.0.0:7420"
sculptor_token = "a-sculptor-secret"
viewer_token = "a-viewer-secret"
[tls]
allow_plaintext = true
[cluster]
etcd = ["http://127.0.0.1:2379"]
member = "a"
)");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.advertise is empty"), std::string::npos) << s;
}

TEST_F(ClusterConfigTest, RejectsWildcardAdvertise) {
  const Status s = Load(
      "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\nadvertise = "
      "\"0.0.0.0:7420\"\n");
  ASSERT_NE(s.violation(), nullptr) << s;
  EXPECT_EQ(s.violation()->field, "cluster.advertise");
}

TEST_F(ClusterConfigTest, RejectsUnknownKey) {
  const Status s = Load("[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\nttl = 3\n");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("unknown key cluster.ttl"), std::string::npos) << s;
}

}  // namespace
}  // namespace sculpt::server
