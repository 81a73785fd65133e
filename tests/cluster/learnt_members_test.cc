// SceneInfo.cluster_members (issue 17): a member answering a join lists the live members, and
// the C++ client reconnects through them after the member it joined dies, without having been
// given any (ClientOptions::cluster_members empty).
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "cluster/processes.h"
#include "cluster/records.h"
#include "net/wire_info.h"
#include "sculpt/client/client.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::Member;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

const Keys kKeys{"t/"};

TEST(WireClusterMembers, KeepsTheOrderAndAtMost64) {
  std::vector<MemberAddress> members;
  for (int i = 0; i < 70; ++i) {
    members.push_back({"m" + std::to_string(i), "127.0.0.1:" + std::to_string(1000 + i),
                       i % 2 ? "" : "127.0.0.1:" + std::to_string(2000 + i)});
  }
  v1::SceneInfo info;
  SetWireClusterMembers(members, &info);
  ASSERT_EQ(info.cluster_members_size(), 64);
  EXPECT_EQ(info.cluster_members(0).name(), "m0");
  EXPECT_EQ(info.cluster_members(0).tcp_address(), "127.0.0.1:1000");
  EXPECT_EQ(info.cluster_members(0).http_address(), "127.0.0.1:2000");
  EXPECT_EQ(info.cluster_members(63).name(), "m63");
  EXPECT_EQ(info.cluster_members(63).http_address(), "");
  // Filled anew, not appended to.
  SetWireClusterMembers({members[5]}, &info);
  ASSERT_EQ(info.cluster_members_size(), 1);
  EXPECT_EQ(info.cluster_members(0).name(), "m5");
  SetWireClusterMembers({}, &info);
  EXPECT_EQ(info.cluster_members_size(), 0);
}

class LearntMembersTest : public sculpt::testing::EtcdTest {
 protected:
  void TearDown() override {
    members_.clear();
    EtcdTest::TearDown();
  }
  // Fixed ports: a promoted standby runs again with the same command line and keeps its address.
  Member& Start(const std::string& name) {
    if (ports_.count(name) == 0) ports_[name] = sculpt::testing::FreePort();
    members_[name] = std::make_unique<Member>(
        name, etcd_->endpoint(), dir_.path(), "replication = \"sync\"\n",
        std::vector<std::string>{"--http", "127.0.0.1:0"}, 2000,
        "127.0.0.1:" + std::to_string(ports_[name]));
    return *members_[name];
  }
  template <typename T>
  std::optional<T> Read(const std::string& key, StatusOr<T> (*decode)(const std::string&)) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(key));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto v = decode((*kv)->value);
    return v.ok() ? std::optional<T>(*v) : std::nullopt;
  }
  std::optional<OwnerRecord> Owner() {
    return Read<OwnerRecord>(kKeys.Owner("default"), DecodeOwner);
  }
  std::optional<MemberRecord> MemberOf(const std::string& name) {
    return Read<MemberRecord>(kKeys.Member(name), DecodeMember);
  }

  sculpt::testing::TempDir dir_{"sculpt-learnt-members"};
  std::map<std::string, uint16_t> ports_;
  std::map<std::string, std::unique_ptr<Member>> members_;
};

TEST_F(LearntMembersTest, ClientReconnectsThroughAMemberItWasNotGiven) {
  ASSERT_NE(Start("a").WaitPort(), 0) << "see " << dir_.path();
  ASSERT_TRUE(WaitFor([&] { auto o = Owner(); return o && o->member == "a"; },
                      milliseconds(15000)))
      << "a did not take the scene; see " << dir_.path();
  ASSERT_NE(Start("b").WaitPort(), 0) << "see " << dir_.path();
  // b follows a as its standby: a has read b's record by then.
  ASSERT_TRUE(WaitFor([&] { auto m = MemberOf("b"); return m && m->follows == "default"; },
                      milliseconds(20000)))
      << "b does not follow; see " << dir_.path();
  const auto a = MemberOf("a");
  const auto b = MemberOf("b");
  ASSERT_TRUE(a && b);

  sculpt::client::ClientOptions options;  // no cluster_members
  options.timeout = milliseconds(3000);
  sculpt::client::Client client(options);
  ASSERT_TRUE(client.Connect("127.0.0.1", ports_["a"]).ok());
  ASSERT_TRUE(client.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "learner", 0).ok());
  auto joined = client.Join("");
  ASSERT_TRUE(joined.ok()) << joined.status();
  // The owner lists both members, itself included, with their HTTP addresses.
  std::map<std::string, v1::ClusterMember> listed;
  for (const v1::ClusterMember& m : joined->info.cluster_members()) listed[m.name()] = m;
  ASSERT_EQ(listed.size(), 2u) << joined->info.ShortDebugString();
  EXPECT_EQ(listed["a"].tcp_address(), a->tcp);
  EXPECT_EQ(listed["a"].http_address(), a->http);
  EXPECT_EQ(listed["b"].tcp_address(), b->tcp);
  EXPECT_EQ(listed["b"].http_address(), b->http);
  EXPECT_FALSE(b->http.empty());
  std::vector<std::string> learnt = client.learnt_members();
  std::sort(learnt.begin(), learnt.end());
  std::vector<std::string> expected{a->tcp, b->tcp};
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(learnt, expected);

  sculpt::client::StrokeRequest stroke;
  stroke.poses = {{{0, 0, 22.5}, 0}, {{0, 0.2, 22.5}, 8}};
  ASSERT_TRUE(client.SendStroke(stroke).ok());
  ASSERT_TRUE(client.WaitAllAcked(milliseconds(5000)));

  members_["a"]->process().Kill(SIGKILL);
  // A stroke drawn after the owner died waits for the reconnect.
  (void)client.SendStroke(stroke);
  Status r = Status(Status::Code::kUnavailable, "not tried");
  ASSERT_TRUE(WaitFor(
      [&] {
        r = client.Reconnect();
        if (!r.ok()) std::this_thread::sleep_for(milliseconds(200));
        return r.ok();
      },
      milliseconds(20000)))
      << "no reconnect through b: " << r << "; see " << dir_.path();
  const auto owner = Owner();
  ASSERT_TRUE(owner.has_value());
  EXPECT_EQ(owner->member, "b");
  EXPECT_TRUE(client.WaitAllAcked(milliseconds(5000)));
  EXPECT_EQ(client.unacked(), 0u);
  EXPECT_EQ(client.stats().refused, 0u);
  // b's SceneInfo lists b (a is gone from etcd once its lease expired).
  const v1::SceneInfo rejoined = client.scene_info();
  bool b_listed = false;
  for (const v1::ClusterMember& m : rejoined.cluster_members()) {
    b_listed = b_listed || m.name() == "b";
  }
  EXPECT_TRUE(b_listed) << rejoined.ShortDebugString();
  // Both strokes applied exactly once on b: 2 poses each.
  auto fetched = sculpt::client::FetchScene(b->tcp, "sculpt-dev-viewer", v1::ROLE_VIEWER, "",
                                            milliseconds(5000), {});
  ASSERT_TRUE(fetched.ok()) << fetched.status();
  EXPECT_EQ(fetched->info.global_seq(), 4u);
}

}  // namespace
}  // namespace sculpt::server::cluster
