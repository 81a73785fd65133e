// The values members keep in etcd, and placement over them.
#include "cluster/records.h"

#include <gtest/gtest.h>

#include <map>

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
  EXPECT_FALSE(DecodeMember(R"({"name":"a","tcp":"h:1","sessions":0,"acks_async":"yes"})").ok());
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

namespace sculpt::server::cluster {
namespace {

// A member hosting several scenes lists each scene it follows and owns with its sequence; the
// first of each is also written under the one-scene names, and a record of a one-scene member
// (no lists) reads as lists of its one scene.
TEST(ClusterRecordsTest, SeveralScenesFollowedAndOwnedRoundTrip) {
  MemberRecord m{"a", "h:1", "", {"p", "q", "r", "s"}, {"p", "q"}, 2};
  m.owning = {{"p", 40, false}, {"q", 7, true}};
  m.following = {{"r", 12, false}, {"s", 3, false, 2}};
  m.scene_seq = 40;
  m.follows = "r";
  m.follow_seq = 12;
  auto back = DecodeMember(EncodeMember(m));
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->owning.size(), 2u);
  ASSERT_EQ(back->following.size(), 2u);
  ASSERT_NE(back->Owning("q"), nullptr);
  EXPECT_EQ(back->Owning("q")->seq, 7u);
  EXPECT_TRUE(back->Owning("q")->acks_async);
  EXPECT_FALSE(back->Owning("p")->acks_async);
  ASSERT_NE(back->Following("s"), nullptr);
  EXPECT_EQ(back->Following("s")->seq, 3u);
  EXPECT_EQ(back->Following("s")->divergences, 2u);  // the copy was loaded anew twice
  EXPECT_EQ(back->Following("r")->divergences, 0u);  // not written when 0
  const std::string encoded = EncodeMember(m);
  const size_t first = encoded.find("\"divergences\"");
  ASSERT_NE(first, std::string::npos) << encoded;
  EXPECT_EQ(encoded.find("\"divergences\"", first + 1), std::string::npos) << encoded;
  EXPECT_EQ(back->Following("p"), nullptr);
  EXPECT_EQ(back->Owning("r"), nullptr);
  EXPECT_EQ(back->follows, "r");
  EXPECT_EQ(back->follow_seq, 12u);

  auto old = DecodeMember(
      R"({"name":"b","tcp":"h:2","sessions":0,"owns":["v"],"scene_seq":9,"acks_async":true,)"
      R"("follows":"w","follow_seq":5})");
  ASSERT_TRUE(old.ok()) << old.status();
  ASSERT_NE(old->Owning("v"), nullptr);
  EXPECT_EQ(old->Owning("v")->seq, 9u);
  EXPECT_TRUE(old->Owning("v")->acks_async);
  ASSERT_NE(old->Following("w"), nullptr);
  EXPECT_EQ(old->Following("w")->seq, 5u);
  auto none = DecodeMember(R"({"name":"b","tcp":"h:2","sessions":0})");
  ASSERT_TRUE(none.ok()) << none.status();
  EXPECT_TRUE(none->owning.empty());
  EXPECT_TRUE(none->following.empty());
}

TEST(ClusterRecordsTest, RejectsMalformedSceneLists) {
  const std::string base = R"({"name":"a","tcp":"h:1","sessions":0,)";
  for (const std::string& bad :
       {base + R"("following":{"scene":"p","seq":1}})", base + R"("following":["p"]})",
        base + R"("following":[{"seq":1}]})", base + R"("owning":[{"scene":"p","seq":-1}]})",
        base + R"("owning":[{"scene":"p","seq":1,"acks_async":"no"}]})",
        base + R"("owning":[{"scene":"","seq":1}]})",
        base + R"("following":[{"scene":"p","seq":1,"divergences":-2}]})",
        base + R"("following":[{"scene":"p","seq":1,"divergences":"two"}]})"}) {
    EXPECT_EQ(DecodeMember(bad).status().code(), Status::Code::kInvalidArgument) << bad;
  }
}

std::map<std::string, int> CountPicks(const std::map<std::string, std::string>& picks) {
  std::map<std::string, int> per_member;
  for (const auto& [scene, member] : picks) ++per_member[member];
  return per_member;
}

const std::vector<std::string> kSix = {"s1", "s2", "s3", "s4", "s5", "s6"};

// Three idle members offering the same six new scenes: two each, and the same picks whatever
// order a member reads the records or lists the scenes in (every member must agree).
TEST(PlacementTest, SixNewScenesOverThreeMembersSpreadTwoEach) {
  const std::vector<MemberRecord> view = {M("a", {}, 0, kSix), M("b", {}, 0, kSix),
                                          M("c", {}, 0, kSix)};
  const auto picks = PlaceScenes(view, kSix);
  ASSERT_EQ(picks.size(), 6u);
  EXPECT_EQ(CountPicks(picks), (std::map<std::string, int>{{"a", 2}, {"b", 2}, {"c", 2}}));
  // Round robin in name order, the tie broken by name.
  EXPECT_EQ(picks.at("s1"), "a");
  EXPECT_EQ(picks.at("s2"), "b");
  EXPECT_EQ(picks.at("s3"), "c");
  std::vector<MemberRecord> reversed(view.rbegin(), view.rend());
  std::vector<std::string> shuffled = {"s4", "s1", "s6", "s2", "s5", "s3", "s1"};
  EXPECT_EQ(PlaceScenes(reversed, shuffled), picks);
  std::vector<MemberRecord> rotated = {view[1], view[2], view[0]};
  EXPECT_EQ(PlaceScenes(rotated, kSix), picks);
}

// Scenes already owned count: the new ones fill up the members with fewer first; sessions
// break ties before names; a scene nobody offers is left out.
TEST(PlacementTest, NewScenesFillUpTheLessLoadedMembersFirst) {
  const std::vector<MemberRecord> view = {M("a", {"x", "y"}, 0, kSix), M("b", {}, 5, kSix),
                                          M("c", {"z"}, 0, kSix)};
  const auto picks = PlaceScenes(view, {"s1", "s2", "s3", "s4", "nobody"});
  EXPECT_EQ(picks.count("nobody"), 0u);
  // b (0 owned); then c (1) before b (1 now, more sessions); then b (1); then all at 2: a and c
  // have fewer sessions than b, and a the smaller name.
  EXPECT_EQ(picks.at("s1"), "b");
  EXPECT_EQ(picks.at("s2"), "c");
  EXPECT_EQ(picks.at("s3"), "b");
  EXPECT_EQ(picks.at("s4"), "a");
  // Only members offering the scene.
  const auto only = PlaceScenes({M("a", {}, 0, {"s1"}), M("b", {}, 0, {"s2"})}, {"s1", "s2"});
  EXPECT_EQ(only.at("s1"), "a");
  EXPECT_EQ(only.at("s2"), "b");
  EXPECT_EQ(PickMember(view, "s1"), "b");
}

// An owner naming standbys for several scenes spreads the copies over the other members,
// counting the scenes they own and follow already.
TEST(PlacementTest, StandbysSpreadOverTheCandidates) {
  MemberRecord b = M("b", {"x"}, 0, kSix);
  MemberRecord c = M("c", {}, 0, kSix);
  c.following = {{"y", 1, false}, {"z", 1, false}};
  const auto picks = PickStandbys({b, c}, {"s1", "s2", "s3"});
  // b: 1 (owns x), c: 2 (follows y, z) → s1 to b; then 2/2 → b by name; then b 3, c 2 → c.
  EXPECT_EQ(picks.at("s1"), "b");
  EXPECT_EQ(picks.at("s2"), "b");
  EXPECT_EQ(picks.at("s3"), "c");
}

// `sculpt cluster rebalance`: a member that joined after the six scenes were placed on a owns
// nothing; the plan moves three of them, each to b, preferring the scenes whose standby b is.
TEST(RebalanceTest, ALateMemberTakesHalfOfTheScenesWarmCopiesFirst) {
  const std::vector<MemberRecord> view = {M("a", kSix, 0, kSix), M("b", {}, 0, kSix)};
  std::map<std::string, std::string> owners, standbys;
  for (const std::string& s : kSix) owners[s] = "a";
  standbys = {{"s4", "b"}, {"s6", "b"}};
  const std::vector<SceneMove> plan = PlanRebalance(view, owners, standbys);
  EXPECT_EQ(plan, (std::vector<SceneMove>{{"s4", "a", "b"}, {"s6", "a", "b"}, {"s1", "a", "b"}}));
  // The same plan whatever order the records come in.
  EXPECT_EQ(PlanRebalance({view[1], view[0]}, owners, standbys), plan);
}

// Donors from the most loaded, takers from the least; a difference of one is balanced; members
// that may not follow or do not offer a scene never take it; dead owners' scenes stay.
TEST(RebalanceTest, MovesOnlyWhereADifferenceOfTwoOrMoreCanBeEvenedOut) {
  std::map<std::string, std::string> owners = {{"s1", "a"}, {"s2", "a"}, {"s3", "a"},
                                               {"s4", "a"}, {"s5", "b"}, {"s6", "c"}};
  // a 4, b 1, c 1: two moves, to b then c (b first by name, then c has fewest).
  auto plan = PlanRebalance({M("a", {}, 0, kSix), M("b", {}, 0, kSix), M("c", {}, 0, kSix)},
                            owners, {});
  EXPECT_EQ(plan, (std::vector<SceneMove>{{"s1", "a", "b"}, {"s2", "a", "c"}}));
  // Already balanced within one.
  EXPECT_TRUE(PlanRebalance({M("a", {}, 0, kSix), M("b", {}, 0, kSix)},
                            {{"s1", "a"}, {"s2", "a"}, {"s3", "b"}}, {})
                  .empty());
  // b may not follow: nobody can take a's scenes.
  MemberRecord no_standby = M("b", {}, 0, kSix);
  no_standby.standby = false;
  EXPECT_TRUE(PlanRebalance({M("a", {}, 0, kSix), no_standby}, {{"s1", "a"}, {"s2", "a"}}, {})
                  .empty());
  // b offers s2 only: that is the scene it takes.
  EXPECT_EQ(PlanRebalance({M("a", {}, 0, kSix), M("b", {}, 0, {"s2"})},
                          {{"s1", "a"}, {"s2", "a"}, {"s3", "a"}}, {}),
            (std::vector<SceneMove>{{"s2", "a", "b"}}));
  // Scenes of an owner that is not live count for nobody and do not move.
  EXPECT_TRUE(PlanRebalance({M("b", {}, 0, kSix)}, {{"s1", "gone"}, {"s2", "gone"}}, {}).empty());
}

}  // namespace
}  // namespace sculpt::server::cluster
