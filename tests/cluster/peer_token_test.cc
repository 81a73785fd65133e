// The members' shared secret, cluster.peer_token (issue 17, docs/cluster.md "Standby sessions"):
// the configuration checks it; an owner takes a session for its standby (ReplicaProgress, the
// resend table with a region load) only when it presented the token and is named
// `standby-<the named standby>`, so a viewer-token holder claiming that name is refused; and a
// cluster of named users only follows, syncs and fails over with it.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>

#include "cluster/etcd_client.h"
#include "cluster/processes.h"
#include "cluster/records.h"
#include "cluster/scene_router.h"
#include "config/server_config.h"
#include "integration/in_process_server.h"
#include "integration/raw_client.h"
#include "net/users.h"
#include "sculpt/client/client.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::Member;
using sculpt::testing::RawClient;
using sculpt::testing::TempDir;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

constexpr const char* kPeerToken = "peer-secret-of-the-test-cluster";

// Reads until a message of the wanted case, for at most `limit` (presence keeps arriving, so
// RawClient::ReadUntil alone would wait forever for a message that never comes).
std::optional<v1::ServerMessage> ReadWithin(RawClient& c, v1::ServerMessage::BodyCase want,
                                            milliseconds limit = milliseconds(5000)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    auto m = c.Read();
    if (!m) return std::nullopt;
    if (m->body_case() == want) return m;
  }
  return std::nullopt;
}

// --- the configuration -----------------------------------------------------------------------

class PeerTokenConfigTest : public ::testing::Test {
 protected:
  Status Load(const std::string& toml, ServerConfig* c) {
    const auto path = dir_.path() / "sculptd.toml";
    std::ofstream(path) << toml;
    SCULPT_RETURN_IF_ERROR(LoadConfigFile(path.string(), c));
    return ValidateConfig(*c);
  }
  static std::string Cluster(const std::string& peer_line) {
    return "[cluster]\netcd = [\"http://127.0.0.1:2379\"]\nmember = \"a\"\n" + peer_line;
  }
  TempDir dir_{"sculpt-peer-config"};
};

TEST_F(PeerTokenConfigTest, UnsetByDefault) {
  ServerConfig c;
  ASSERT_TRUE(Load(Cluster(""), &c).ok());
  EXPECT_TRUE(c.cluster.peer_token.empty());
}

TEST_F(PeerTokenConfigTest, ReadsTheToken) {
  ServerConfig c;
  const Status s = Load(Cluster(std::string("peer_token = \"") + kPeerToken + "\"\n"), &c);
  ASSERT_TRUE(s.ok()) << s;
  EXPECT_EQ(c.cluster.peer_token, kPeerToken);
}

TEST_F(PeerTokenConfigTest, RejectsShortPeerToken) {
  ServerConfig c;
  const Status s = Load(Cluster("peer_token = \"fifteen-chars-x\"\n"), &c);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("cluster.peer_token"), std::string::npos) << s;
  EXPECT_NE(s.message().find("[16, 1024]"), std::string::npos) << s;
  EXPECT_EQ(s.message().find("fifteen-chars-x"), std::string::npos) << "the secret is printed: " << s;
  // Sixteen characters are enough.
  ServerConfig ok;
  EXPECT_TRUE(Load(Cluster("peer_token = \"sixteen-chars-xx\"\n"), &ok).ok());
}

TEST_F(PeerTokenConfigTest, RejectsPeerTokenEqualToTheViewerToken) {
  ServerConfig c;
  const Status s = Load("[server]\nviewer_token = \"the-same-secret-twice\"\n" +
                            Cluster("peer_token = \"the-same-secret-twice\"\n"),
                        &c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("cluster.peer_token"), std::string::npos) << s;
  EXPECT_EQ(s.message().find("the-same-secret-twice"), std::string::npos) << s;
}

TEST_F(PeerTokenConfigTest, RejectsPeerTokenWithoutCluster) {
  ServerConfig c;
  const Status s = Load(std::string("[cluster]\npeer_token = \"") + kPeerToken + "\"\n", &c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("cluster.peer_token"), std::string::npos) << s;
}

// --- the owner's sessions, in process with a fixed routing table ------------------------------

// This member owns its scene and named "b" its standby.
class StandbyIsB : public SceneRouter {
 public:
  Route RouteScene(const std::string& scene) const override {
    Route r;
    r.kind = Route::Kind::kLocal;
    r.scene = scene;
    r.member = "a";
    r.epoch = 1;
    r.standby = "b";
    return r;
  }
};

class PeerSessionTest : public ::testing::Test {
 protected:
  // Cluster settings with the peer token; `users`: named users only (no shared tokens).
  void Start(bool users = false) {
    ServerConfig& c = server_.config();
    c.cluster.etcd = {"http://127.0.0.1:9"};  // read by nobody: no agent runs here
    c.cluster.member = "a";
    c.cluster.peer_token = kPeerToken;
    if (users) {
      UserTable t;
      t.Put({"alice", UserRole::kSculptor, HashToken("alice-token-0123456789").value()});
      c.users_file = (dir_.path() / "users.toml").string();
      ASSERT_TRUE(t.Save(c.users_file).ok());
    }
    ASSERT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
    ASSERT_TRUE(server_.Start());
    server_.server().set_router(&router_);
  }
  static v1::ClientMessage Hello(const std::string& token, v1::Role role,
                                 const std::string& name, uint64_t client_id) {
    v1::ClientMessage h;
    h.mutable_hello()->set_protocol_version(1);
    h.mutable_hello()->set_token(token);
    h.mutable_hello()->set_role(role);
    h.mutable_hello()->set_client_name(name);
    h.mutable_hello()->set_client_id(client_id);
    return h;
  }
  // Hello as `name` with `token` (viewer), join, subscribe to the object in replay mode; the
  // region load's resend table size goes to `*resend_entries`.
  std::unique_ptr<RawClient> Follower(const std::string& token, const std::string& name,
                                      int* resend_entries) {
    auto c = std::make_unique<RawClient>(server_.port());
    EXPECT_TRUE(c->Send(Hello(token, v1::ROLE_VIEWER, name, 4242)));
    EXPECT_TRUE(ReadWithin(*c, v1::ServerMessage::kWelcome).has_value());
    v1::ClientMessage j;
    j.mutable_join()->set_skip_state(true);
    EXPECT_TRUE(c->Send(j));
    auto info = ReadWithin(*c, v1::ServerMessage::kSceneInfo);
    EXPECT_TRUE(info.has_value());
    if (info) object_ = info->scene_info().objects(0).name();
    v1::ClientMessage s;
    s.mutable_subscribe()->set_object(object_);
    s.mutable_subscribe()->set_mode(v1::REPLICA_MODE_REPLAY);
    EXPECT_TRUE(c->Send(s));
    auto load = ReadWithin(*c, v1::ServerMessage::kLeafDelta);
    EXPECT_TRUE(load.has_value());
    if (load) {
      EXPECT_TRUE(load->leaf_delta().replace_region());
      *resend_entries = load->leaf_delta().resend_table_size();
    }
    return c;
  }
  static v1::ClientMessage Progress(const std::string& object, uint64_t seq) {
    v1::ClientMessage m;
    m.mutable_replica_progress()->set_object(object);
    m.mutable_replica_progress()->set_durable_seq(seq);
    return m;
  }
  // One acknowledged stroke (async replication), so the scene has a resend table entry.
  void Sculpt(RawClient& s) {
    ASSERT_TRUE(s.Send(RawClient::PressStroke(1, {0, 0, 22.5}, 3)));
    auto ack = ReadWithin(s, v1::ServerMessage::kAck);
    ASSERT_TRUE(ack.has_value());
    ASSERT_EQ(ack->ack().client_seq(), 1u);
  }

  TempDir dir_{"sculpt-peer-session"};
  sculpt::testing_support::InProcessServer server_{"peer_session"};
  StandbyIsB router_;
  std::string object_;
};

TEST_F(PeerSessionTest, RejectsViewerClaimingTheStandbysName) {
  Start();
  RawClient s(server_.port());
  ASSERT_TRUE(s.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR));
  Sculpt(s);
  // The viewer token and the standby's name: a viewer, not the standby.
  int impostor_entries = -1;
  auto impostor = Follower("sculpt-dev-viewer", "standby-b", &impostor_entries);
  EXPECT_EQ(impostor_entries, 0) << "the owner's resend table went to a viewer";
  ASSERT_TRUE(impostor->Send(Progress(object_, server_.scene().global_seq())));
  auto err = ReadWithin(*impostor, v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value()) << "a viewer claiming the standby's name was not refused";
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
  EXPECT_EQ(err->error().field(), "Hello.token");
  EXPECT_NE(err->error().allowed_range().find("cluster.peer_token"), std::string::npos)
      << err->error().allowed_range();
  EXPECT_EQ(err->error().value(), "(hidden)");
  EXPECT_EQ(server_.scene().acks().standby_durable_seq(), 0u);

  // The same name with the peer token: the standby, with the resend table and its word taken.
  int peer_entries = -1;
  auto peer = Follower(kPeerToken, "standby-b", &peer_entries);
  EXPECT_GT(peer_entries, 0) << "the standby's region load came without the resend table";
  const uint64_t seq = server_.scene().global_seq();
  ASSERT_TRUE(peer->Send(Progress(object_, seq)));
  EXPECT_TRUE(WaitFor([&] { return server_.scene().acks().standby_durable_seq() == seq; },
                      milliseconds(5000)))
      << "the peer's ReplicaProgress was not taken";
}

TEST_F(PeerSessionTest, RejectsPeerWithAnotherMembersName) {
  Start();
  RawClient s(server_.port());
  ASSERT_TRUE(s.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR));
  Sculpt(s);
  int entries = -1;
  auto c = Follower(kPeerToken, "standby-c", &entries);
  EXPECT_EQ(entries, 0) << "a member that is not the named standby got the resend table";
  ASSERT_TRUE(c->Send(Progress(object_, 1)));
  auto err = ReadWithin(*c, v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
  EXPECT_EQ(err->error().field(), "Hello.client_name");
  EXPECT_EQ(err->error().allowed_range(), "standby-b");
}

TEST_F(PeerSessionTest, RejectsPeerTokenForTheSculptorRole) {
  Start();
  RawClient c(server_.port());
  ASSERT_TRUE(c.Send(Hello(kPeerToken, v1::ROLE_SCULPTOR, "standby-b", 77)));
  auto err = ReadWithin(c, v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_UNAUTHENTICATED);
  EXPECT_EQ(err->error().field(), "Hello.token");
}

TEST_F(PeerSessionTest, PeerIsAcceptedAmongNamedUsers) {
  Start(/*users=*/true);
  // The shared viewer token is no longer a way in.
  {
    RawClient v(server_.port());
    ASSERT_TRUE(v.Send(Hello("sculpt-dev-viewer", v1::ROLE_VIEWER, "standby-b", 78)));
    auto err = ReadWithin(v, v1::ServerMessage::kError);
    ASSERT_TRUE(err.has_value());
    EXPECT_EQ(err->error().code(), v1::ERROR_CODE_UNAUTHENTICATED);
  }
  RawClient s(server_.port());
  ASSERT_TRUE(s.Send(Hello("alice-token-0123456789", v1::ROLE_SCULPTOR, "alice", 79)));
  auto welcome = ReadWithin(s, v1::ServerMessage::kWelcome);
  ASSERT_TRUE(welcome.has_value());
  EXPECT_EQ(welcome->welcome().user(), "alice");
  ASSERT_TRUE(s.Join());
  ASSERT_TRUE(ReadWithin(s, v1::ServerMessage::kSceneInfo).has_value());
  Sculpt(s);
  // The standby is no user of the file: its peer token lets it in, under the name it claims.
  int entries = -1;
  auto peer = Follower(kPeerToken, "standby-b", &entries);
  EXPECT_GT(entries, 0);
  const uint64_t seq = server_.scene().global_seq();
  ASSERT_TRUE(peer->Send(Progress(object_, seq)));
  EXPECT_TRUE(WaitFor([&] { return server_.scene().acks().standby_durable_seq() == seq; },
                      milliseconds(5000)));
}

// --- a real cluster of named users only ------------------------------------------------------

class PeerClusterTest : public sculpt::testing::EtcdTest {
 protected:
  void TearDown() override {
    members_.clear();
    EtcdTest::TearDown();
  }
  Member& Start(const std::string& name, const std::string& extra) {
    members_.push_back(std::make_unique<Member>(name, etcd_->endpoint(), dir_.path(), extra,
                                                std::vector<std::string>{"--users", users_}));
    return *members_.back();
  }
  std::string Log(const std::string& member) {
    std::ifstream in(dir_.path() / (member + ".log"));
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }

  TempDir dir_{"sculpt-peer-cluster"};
  std::string users_ = (dir_.path() / "users.toml").string();
  std::vector<std::unique_ptr<Member>> members_;
};

// Named users only: the shared viewer token is refused, so before the peer token no member could
// follow another. With it, b follows a, its word releases a's synchronous acks (a never falls
// back), and when a is killed b takes the scene over with every acknowledged stroke.
TEST_F(PeerClusterTest, NamedUsersOnlyClusterFollowsSyncsAndFailsOver) {
  const std::string alice = "alice-token-0123456789";
  UserTable t;
  t.Put({"alice", UserRole::kSculptor, HashToken(alice).value()});
  ASSERT_TRUE(t.Save(users_).ok());
  const std::string peer = std::string("peer_token = \"") + kPeerToken + "\"\n";
  Member& a = Start("a", peer + "replication = \"sync\"\nsync_fallback_ms = 60000\n");
  ASSERT_NE(a.WaitPort(), 0) << "member a did not start; see " << dir_.path() / "a.log";
  const auto first_owner = AwaitOwner("default", "", milliseconds(5000));
  ASSERT_TRUE(first_owner.has_value());
  ASSERT_EQ(first_owner->member, "a");
  Member& b = Start("b", peer + "replication = \"sync\"\nsync_fallback_ms = 300\n");
  ASSERT_NE(b.WaitPort(), 0) << "member b did not start; see " << dir_.path() / "b.log";
  ASSERT_TRUE(WaitFor(
      [&] {
        auto s = StandbyOf("default");
        auto m = MemberOf("b");
        return s && s->member == "b" && m && m->follows == "default";
      },
      milliseconds(15000)))
      << "b's copy never completed; see " << dir_.path() / "b.log";

  sculpt::client::ClientOptions options;
  options.timeout = milliseconds(10000);
  sculpt::client::Client client(options);
  sculpt::testing::AckLog acks(client);
  ASSERT_TRUE(client.Connect("127.0.0.1", a.port()).ok());
  auto welcome = client.Hello(alice, v1::ROLE_SCULPTOR, "alice", 0);
  ASSERT_TRUE(welcome.ok()) << welcome.status();
  auto joined = client.Join("");
  ASSERT_TRUE(joined.ok()) << joined.status();
  for (int i = 0; i < 20; ++i) {
    sculpt::client::StrokeRequest stroke;
    const double x = -5.0 + i * 0.5;
    stroke.poses = {{{x, 0, 22.5}, 0}, {{x, 0.5, 22.5}, 10}};
    ASSERT_TRUE(client.SendStroke(stroke).ok());
  }
  // Each ack waited for b's ReplicaProgress (no fall-back for a minute).
  ASSERT_TRUE(WaitFor([&] { return acks.size() == 20; }, milliseconds(20000)))
      << "a did not acknowledge the strokes: b's progress was not taken; see "
      << dir_.path() / "a.log";
  acks.Stop();
  const uint64_t highest = acks.highest();
  {
    const std::string log = Log("a");
    EXPECT_EQ(log.find("acknowledging asynchronously"), std::string::npos)
        << "a fell back to async: its standby's word did not count";
    EXPECT_NE(log.find("cluster peer standby-b"), std::string::npos)
        << "b did not say Hello as a peer";
    EXPECT_EQ(log.find(kPeerToken), std::string::npos) << "the peer token is in a's log";
  }
  EXPECT_EQ(Log("b").find("came without the owner's resend table"), std::string::npos)
      << "b's region load came without a's resend table";

  a.process().Kill(SIGKILL);
  const auto owner = AwaitOwner("default", "b", milliseconds(25000));
  ASSERT_TRUE(owner.has_value()) << "b did not take the scene over; see " << dir_.path() / "b.log";
  EXPECT_EQ(owner->epoch, 2u);
  // alice on b (restarted on its copy; the same port file, rewritten): every acknowledged
  // stroke is there.
  uint64_t seq = 0;
  ASSERT_TRUE(WaitFor(
      [&] {
        std::ifstream in(dir_.path() / "b.ports");
        unsigned p = 0;
        if (!(in >> p) || p == 0) return false;
        try {
          RawClient probe(static_cast<uint16_t>(p));
          probe.SetTimeoutMs(2000);
          v1::ClientMessage h;
          h.mutable_hello()->set_protocol_version(1);
          h.mutable_hello()->set_token(alice);
          h.mutable_hello()->set_role(v1::ROLE_SCULPTOR);
          h.mutable_hello()->set_client_name("alice");
          h.mutable_hello()->set_client_id(99);
          if (!probe.Send(h) || !ReadWithin(probe, v1::ServerMessage::kWelcome)) return false;
          if (!probe.Join()) return false;
          auto info = ReadWithin(probe, v1::ServerMessage::kSceneInfo);
          if (!info) return false;
          seq = info->scene_info().global_seq();
          return true;
        } catch (const std::exception&) {
          return false;
        }
      },
      milliseconds(15000)))
      << "b does not serve the scene to alice; see " << dir_.path() / "b.log";
  EXPECT_GE(seq, highest) << "b's scene is behind what a acknowledged";
}

}  // namespace
}  // namespace sculpt::server::cluster
