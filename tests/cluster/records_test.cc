// The values members keep in etcd, and placement over them.
#include "cluster/records.h"

#include <gtest/gtest.h>

#include "cluster/placement.h"

namespace sculpt::server::cluster {
namespace {

TEST(ClusterRecordsTest, MemberRoundTrips) {
  MemberRecord m{"a", "127.0.0.1:7420", "127.0.0.1:7421", {"default"}, {"default"}, 3};
  auto back = DecodeMember(EncodeMember(m));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->name, "a");
  EXPECT_EQ(back->tcp, "127.0.0.1:7420");
  EXPECT_EQ(back->http, "127.0.0.1:7421");
  EXPECT_EQ(back->offers, std::vector<std::string>{"default"});
  EXPECT_EQ(back->owns, std::vector<std::string>{"default"});
  EXPECT_EQ(back->sessions, 3u);
}

TEST(ClusterRecordsTest, OwnerAndEpochRoundTrip) {
  auto o = DecodeOwner(EncodeOwner({"b", "h:1", "", 7}));
  ASSERT_TRUE(o.ok()) << o.status();
  EXPECT_EQ(o->member, "b");
  EXPECT_EQ(o->epoch, 7u);
  auto e = DecodeEpoch(EncodeEpoch({7, "b"}));
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(e->epoch, 7u);
  EXPECT_EQ(e->member, "b");
}

TEST(ClusterRecordsTest, StandbyAndFollowRoundTrip) {
  auto s = DecodeStandby(EncodeStandby({"c", 4}));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->member, "c");
  EXPECT_EQ(s->epoch, 4u);
  EXPECT_FALSE(DecodeStandby(R"({"epoch":1})").ok());
  EXPECT_FALSE(DecodeStandby(R"({"member":"a","epoch":-1})").ok());
  MemberRecord m{"a", "h:1", "", {"default"}, {}, 0};
  m.follows = "default";
  m.follow_seq = 42;
  m.scene_seq = 57;
  m.acks_async = true;
  auto back = DecodeMember(EncodeMember(m));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_TRUE(back->standby);
  EXPECT_EQ(back->follows, "default");
  EXPECT_EQ(back->follow_seq, 42u);
  EXPECT_EQ(back->scene_seq, 57u);
  EXPECT_TRUE(back->acks_async);
  EXPECT_FALSE(
      DecodeMember(R"({"name":"a","tcp":"h:1","sessions":0,"acks_async":"yes"})").ok());
  // A record without the field (an older member) may not follow; a wrong type is refused.
  auto old = DecodeMember(R"({"name":"a","tcp":"h:1","sessions":0})");
  ASSERT_TRUE(old.ok()) << old.status();
  EXPECT_FALSE(old->standby);
  EXPECT_EQ(old->scene_seq, 0u);
  EXPECT_FALSE(old->acks_async);
  EXPECT_FALSE(DecodeMember(R"({"name":"a","tcp":"h:1","sessions":0,"standby":1})").ok());
  const Keys k{"p/"};
  std::string scene, kind;
  ASSERT_TRUE(k.ParseSceneKey(k.Standby("vase"), &scene, &kind));
  EXPECT_EQ(scene, "vase");
  EXPECT_EQ(kind, "standby");
}

TEST(ClusterRecordsTest, RejectsMalformedRecords) {
  EXPECT_EQ(DecodeMember("not json").status().code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(DecodeMember("[1]").status().code(), Status::Code::kInvalidArgument);
  const Status no_tcp = DecodeMember(R"({"name":"a","sessions":0})").status();
  ASSERT_NE(no_tcp.violation(), nullptr) << no_tcp;
  EXPECT_EQ(no_tcp.violation()->field, "tcp");
  const Status neg = DecodeMember(R"({"name":"a","tcp":"h:1","sessions":-1})").status();
  ASSERT_NE(neg.violation(), nullptr) << neg;
  EXPECT_EQ(neg.violation()->field, "sessions");
  const Status long_name =
      DecodeMember("{\"name\":\"" + std::string(300, 'x') + "\",\"tcp\":\"h:1\",\"sessions\":0}")
          .status();
  EXPECT_FALSE(long_name.ok());
  EXPECT_EQ(DecodeOwner(R"({"member":"a","tcp":"h:1","epoch":0})").status().code(),
            Status::Code::kInvalidArgument);
  EXPECT_EQ(DecodeOwner(R"({"member":"a","tcp":"h:1","epoch":"1"})").status().code(),
            Status::Code::kInvalidArgument);
  EXPECT_EQ(DecodeEpoch(R"({"epoch":1})").status().code(), Status::Code::kInvalidArgument);
}

TEST(ClusterRecordsTest, ParsesSceneKeys) {
  const Keys k{"p/"};
  std::string scene, kind;
  ASSERT_TRUE(k.ParseSceneKey("p/scenes/a/b/owner", &scene, &kind));
  EXPECT_EQ(scene, "a/b");
  EXPECT_EQ(kind, "owner");
  ASSERT_TRUE(k.ParseSceneKey(k.Epoch("vase"), &scene, &kind));
  EXPECT_EQ(scene, "vase");
  EXPECT_EQ(kind, "epoch");
  EXPECT_FALSE(k.ParseSceneKey("p/scenes//owner", &scene, &kind));
  EXPECT_FALSE(k.ParseSceneKey("p/members/a", &scene, &kind));
  EXPECT_FALSE(k.ParseSceneKey("q/scenes/a/owner", &scene, &kind));
}

MemberRecord M(std::string name, std::vector<std::string> owns, uint32_t sessions,
               std::vector<std::string> offers = {"s"}) {
  return {std::move(name), "h:1", "", std::move(offers), std::move(owns), sessions};
}

TEST(PlacementTest, PicksTheMemberWithFewestScenes) {
  EXPECT_EQ(PickMember({M("a", {"x", "y"}, 0), M("b", {"z"}, 50), M("c", {"w", "v"}, 0)}, "s"),
            "b");
}

TEST(PlacementTest, BreaksTiesBySessionsThenName) {
  EXPECT_EQ(PickMember({M("a", {}, 5), M("b", {}, 2)}, "s"), "b");
  EXPECT_EQ(PickMember({M("c", {}, 2), M("b", {}, 2)}, "s"), "b");
}

TEST(PlacementTest, OnlyMembersOfferingTheScene) {
  EXPECT_EQ(PickMember({M("a", {}, 0, {"other"}), M("b", {"q"}, 9)}, "s"), "b");
  EXPECT_EQ(PickMember({M("a", {}, 0, {"other"})}, "s"), std::nullopt);
  EXPECT_EQ(PickMember({}, "s"), std::nullopt);
}

}  // namespace
}  // namespace sculpt::server::cluster
