// EtcdClient against a real etcd (Debian's etcd-server) started by the test on free ports.
#include "cluster/etcd_client.h"

#include <gtest/gtest.h>

#include "cluster/processes.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::EtcdProcess;
using sculpt::testing::WaitFor;

class EtcdClientTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!sculpt::testing::HaveEtcd()) return;
    etcd_ = new EtcdProcess();
    auto c = sculpt::testing::ConnectWhenReady(*etcd_);
    ASSERT_TRUE(c.ok()) << c.status();
    client_ = std::move(c).value().release();
  }
  static void TearDownTestSuite() {
    delete client_;
    client_ = nullptr;
    delete etcd_;
    etcd_ = nullptr;
  }
  void SetUp() override {
    if (!sculpt::testing::HaveEtcd()) GTEST_SKIP() << sculpt::testing::kNoEtcd;
  }
  EtcdClient& c() { return *client_; }

  static EtcdProcess* etcd_;
  static EtcdClient* client_;
};

EtcdProcess* EtcdClientTest::etcd_ = nullptr;
EtcdClient* EtcdClientTest::client_ = nullptr;

TEST_F(EtcdClientTest, PutGetPrefixDelete) {
  ASSERT_TRUE(c().Sync(c().Put({"t1/a", std::string("bytes\0\xff", 7)})).ok());
  ASSERT_TRUE(c().Sync(c().Put({"t1/b", "2"})).ok());
  ASSERT_TRUE(c().Sync(c().Put({"t10", "not in the prefix"})).ok());
  auto a = c().Sync(c().Get("t1/a"));
  ASSERT_TRUE(a.ok()) << a.status();
  ASSERT_TRUE(a->has_value());
  EXPECT_EQ((*a)->value, std::string("bytes\0\xff", 7));
  EXPECT_GT((*a)->create_revision, 0);
  auto all = c().Sync(c().GetPrefix("t1/"));
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), 2u);
  EXPECT_EQ((*all)[0].key, "t1/a");
  EXPECT_EQ((*all)[1].key, "t1/b");
  auto deleted = c().Sync(c().Delete("t1/a"));
  ASSERT_TRUE(deleted.ok()) << deleted.status();
  EXPECT_EQ(*deleted, 1);
  auto gone = c().Sync(c().Get("t1/a"));
  ASSERT_TRUE(gone.ok());
  EXPECT_FALSE(gone->has_value());
}

TEST_F(EtcdClientTest, TxnAcquiresOnceThenReadsTheHolder) {
  TxnRequest acquire;
  acquire.compares = {{"t2/owner", Compare::Target::kCreateRevision, 0}};
  acquire.success = {{"t2/owner", "a"}};
  acquire.failure_ranges = {"t2/owner"};
  auto first = c().Sync(c().Txn(acquire));
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_TRUE(first->succeeded);
  acquire.success = {{"t2/owner", "b"}};
  auto second = c().Sync(c().Txn(acquire));
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_FALSE(second->succeeded);
  ASSERT_EQ(second->read.size(), 1u);
  EXPECT_EQ(second->read[0].value, "a");
  // An epoch bump compares the mod revision it read: a stale one fails.
  auto owner = c().Sync(c().Get("t2/owner"));
  ASSERT_TRUE(owner.ok() && owner->has_value());
  TxnRequest bump;
  bump.compares = {{"t2/owner", Compare::Target::kModRevision, (*owner)->mod_revision}};
  bump.success = {{"t2/owner", "a2"}};
  auto bumped = c().Sync(c().Txn(bump));
  ASSERT_TRUE(bumped.ok());
  EXPECT_TRUE(bumped->succeeded);
  auto stale = c().Sync(c().Txn(bump));
  ASSERT_TRUE(stale.ok());
  EXPECT_FALSE(stale->succeeded);
}

TEST_F(EtcdClientTest, LeaseKeepsKeyUntilRevoked) {
  auto lease = c().Sync(c().Grant(std::chrono::milliseconds(1500)));
  ASSERT_TRUE(lease.ok()) << lease.status();
  EXPECT_GE(lease->ttl, std::chrono::milliseconds(2000));  // whole seconds, etcd's minimum 2 s
  ASSERT_TRUE(c().Sync(c().Put({"t3/k", "v", lease->id})).ok());
  auto kv = c().Sync(c().Get("t3/k"));
  ASSERT_TRUE(kv.ok() && kv->has_value());
  EXPECT_EQ((*kv)->lease, lease->id);
  auto ttl = c().Sync(c().KeepAlive(lease->id));
  ASSERT_TRUE(ttl.ok()) << ttl.status();
  EXPECT_EQ(*ttl, lease->ttl);
  ASSERT_TRUE(c().Sync(c().Revoke(lease->id)).ok());
  auto gone = c().Sync(c().Get("t3/k"));
  ASSERT_TRUE(gone.ok());
  EXPECT_FALSE(gone->has_value());
}

TEST_F(EtcdClientTest, RejectsKeepAliveOfUnknownLease) {
  auto ttl = c().Sync(c().KeepAlive(12345));
  EXPECT_EQ(ttl.status().code(), Status::Code::kNotFound) << ttl.status();
}

TEST_F(EtcdClientTest, RejectsPutUnderUnknownLease) {
  auto put = c().Sync(c().Put({"t4/k", "v", 12345}));
  EXPECT_EQ(put.status().code(), Status::Code::kNotFound) << put.status();
}

TEST_F(EtcdClientTest, FallsBackToTheNextEndpoint) {
  auto two = EtcdClient::Create(
      {{"http://127.0.0.1:" + std::to_string(sculpt::testing::FreePort()), etcd_->endpoint()},
       std::chrono::milliseconds(500)});
  ASSERT_TRUE(two.ok());
  EXPECT_TRUE((*two)->Sync((*two)->Put({"t5/k", "v"})).ok());
}

TEST(EtcdClientNoServer, RejectsUnreachableEndpointAsUnavailable) {
  auto c = EtcdClient::Create({{"127.0.0.1:" + std::to_string(sculpt::testing::FreePort())},
                               std::chrono::milliseconds(300)});
  ASSERT_TRUE(c.ok());
  auto r = (*c)->Sync((*c)->Get("x"));
  EXPECT_EQ(r.status().code(), Status::Code::kUnavailable) << r.status();
}

TEST(EtcdClientNoServer, RejectsMalformedEndpoints) {
  for (const char* bad : {"", "localhost", "http://h:0", "http://h:99999", "https://h:0",
                          "http://h:2379/path", "http://:2379"}) {
    auto c = EtcdClient::Create({{bad}, std::chrono::milliseconds(300)});
    EXPECT_EQ(c.status().code(), Status::Code::kInvalidArgument) << bad;
  }
  EXPECT_FALSE(EtcdClient::Create({{}, std::chrono::milliseconds(300)}).ok());
}

TEST(EtcdClientNoServer, PrefixEndIncrementsTheLastByte) {
  EXPECT_EQ(EtcdClient::PrefixEnd("scenes/"), "scenes0");
  EXPECT_EQ(EtcdClient::PrefixEnd(std::string("a\xff", 2)), "b");
  EXPECT_EQ(EtcdClient::PrefixEnd(""), std::string(1, '\0'));
}

}  // namespace
}  // namespace sculpt::server::cluster
