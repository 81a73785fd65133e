/// @brief Client::learnt_members and Reconnect against FakeSculptd: the members' TCP addresses a
/// join's SceneInfo.cluster_members names are kept (valid HOST:PORT only, distinct, at most
/// kMaxLearntMembers, in order), and Reconnect goes through them when the server it joined is
/// gone, though ClientOptions::cluster_members is empty.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "sculpt/client/client.h"
#include "unit/client/fake_sculptd.h"

namespace sculpt::client {
namespace {

using std::chrono::seconds;
using testing_support::FakeSculptd;

v1::ClusterMember Member(const std::string& name, const std::string& tcp) {
  v1::ClusterMember m;
  m.set_name(name);
  m.set_tcp_address(tcp);
  m.set_http_address("127.0.0.1:1");
  return m;
}

ClientOptions Options() {
  ClientOptions o;
  o.timeout = seconds(5);
  o.skip_state = true;
  return o;
}

TEST(ClientMembersTest, KeepsValidDistinctMembersAtMost64AndReconnectsThroughThem) {
  auto first = std::make_unique<FakeSculptd>();
  FakeSculptd second;
  const std::string first_at = "127.0.0.1:" + std::to_string(first->port());
  const std::string second_at = "127.0.0.1:" + std::to_string(second.port());
  std::vector<v1::ClusterMember> listed{
      Member("a", first_at), Member("forged", "no-port"), Member("zero", "127.0.0.1:0"),
      Member("big", "127.0.0.1:65536"), Member("empty", ""),
      Member("long", std::string(400, 'h') + ":80"), Member("b", second_at),
      Member("b-again", second_at)};
  for (int i = 0; i < 80; ++i) {
    listed.push_back(Member("m" + std::to_string(i), "h" + std::to_string(i) + ":7000"));
  }
  first->set_cluster_members(listed);

  Client client(Options());
  ASSERT_TRUE(client.Connect("127.0.0.1", first->port()).ok());
  ASSERT_TRUE(client.Hello("t", v1::ROLE_SCULPTOR, "learner", 7).ok());
  ASSERT_TRUE(client.Join().ok());
  const std::vector<std::string> learnt = client.learnt_members();
  ASSERT_EQ(learnt.size(), kMaxLearntMembers);
  EXPECT_EQ(learnt[0], first_at);
  EXPECT_EQ(learnt[1], second_at);
  EXPECT_EQ(learnt[2], "h0:7000");
  EXPECT_EQ(learnt.back(), "h61:7000");

  // A join that lists no members keeps what was learnt.
  ASSERT_TRUE(client.Reconnect().ok());
  first->set_cluster_members({});
  ASSERT_TRUE(client.Reconnect().ok());
  EXPECT_EQ(client.learnt_members(), learnt);

  // The joined server goes: Reconnect finds the second through the learnt list alone.
  first.reset();
  ASSERT_TRUE(client.Reconnect().ok());
  EXPECT_TRUE(second.WaitFor([](const auto& r) {
    for (const auto& [c, m] : r) {
      if (m.has_join()) return true;
    }
    return false;
  }));
}

TEST(ClientMembersTest, WithoutLearntMembersReconnectFailsWhenTheServerIsGone) {
  auto only = std::make_unique<FakeSculptd>();
  Client client(Options());
  ASSERT_TRUE(client.Connect("127.0.0.1", only->port()).ok());
  ASSERT_TRUE(client.Hello("t", v1::ROLE_SCULPTOR, "alone", 8).ok());
  ASSERT_TRUE(client.Join().ok());
  EXPECT_TRUE(client.learnt_members().empty());
  only.reset();
  const Status s = client.Reconnect();
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
}

}  // namespace
}  // namespace sculpt::client
