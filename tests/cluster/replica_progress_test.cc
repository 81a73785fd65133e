// ReplicaProgress (issue 17, proto/README.md "Standby progress"): the owner's session accepts a
// standby's word on its copy only from the session of the standby it named, for an object of
// the scene and a sequence it has reached; every other sender is refused naming the field. The
// real server in-process with a fixed routing table instead of etcd.
#include <gtest/gtest.h>

#include "cluster/processes.h"
#include "cluster/scene_router.h"
#include "integration/in_process_server.h"
#include "integration/raw_client.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing::RawClient;
using std::chrono::milliseconds;

// This member owns its scene and named `standby` its standby.
class FixedRouter : public SceneRouter {
 public:
  explicit FixedRouter(std::string standby) : standby_(std::move(standby)) {}
  Route RouteScene(const std::string& scene) const override {
    Route r;
    r.kind = Route::Kind::kLocal;
    r.scene = scene;
    r.member = "a";
    r.epoch = 1;
    r.standby = standby_;
    return r;
  }

 private:
  std::string standby_;
};

class ReplicaProgressTest : public ::testing::Test {
 protected:
  void Start(bool cluster) {
    if (cluster) {
      auto& c = server_.config().cluster;
      c.etcd = {"http://127.0.0.1:9"};  // read by nobody: no agent runs here
      c.member = "a";
      c.replication = "sync";
      c.sync_fallback_ms = 0;
    }
    ASSERT_TRUE(server_.Start());
    if (cluster) server_.server().set_router(&router_);
  }
  // Hello as `name` (viewer), join, and subscribe to the scene's object in replay mode.
  std::unique_ptr<RawClient> Follower(const std::string& name, bool subscribe = true) {
    auto c = std::make_unique<RawClient>(server_.port());
    v1::ClientMessage h;
    h.mutable_hello()->set_protocol_version(1);
    h.mutable_hello()->set_token("sculpt-dev-viewer");
    h.mutable_hello()->set_role(v1::ROLE_VIEWER);
    h.mutable_hello()->set_client_name(name);
    h.mutable_hello()->set_client_id(4242);
    EXPECT_TRUE(c->Send(h));
    EXPECT_TRUE(c->ReadUntil(v1::ServerMessage::kWelcome).has_value());
    v1::ClientMessage j;
    j.mutable_join()->set_skip_state(true);
    EXPECT_TRUE(c->Send(j));
    auto info = c->ReadUntil(v1::ServerMessage::kSceneInfo);
    EXPECT_TRUE(info.has_value());
    if (info) object_ = info->scene_info().objects(0).name();
    if (subscribe) {
      v1::ClientMessage s;
      s.mutable_subscribe()->set_object(object_);
      s.mutable_subscribe()->set_mode(v1::REPLICA_MODE_REPLAY);
      EXPECT_TRUE(c->Send(s));
      EXPECT_TRUE(c->ReadUntil(v1::ServerMessage::kLeafDelta).has_value());
    }
    return c;
  }
  static v1::ClientMessage Progress(const std::string& object, uint64_t seq) {
    v1::ClientMessage m;
    m.mutable_replica_progress()->set_object(object);
    m.mutable_replica_progress()->set_durable_seq(seq);
    return m;
  }
  // One stroke through a sculptor, so the scene has a sequence to report on (not acked: sync
  // with no standby word and no fall-back).
  void Sculpt() {
    RawClient s(server_.port());
    ASSERT_TRUE(s.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR));
    ASSERT_TRUE(s.Send(RawClient::PressStroke(1, {0, 0, 22.5}, 3)));
    ASSERT_TRUE(sculpt::testing::WaitFor([&] { return server_.scene().global_seq() >= 3; },
                                         milliseconds(5000)));
  }

  sculpt::testing_support::InProcessServer server_{"replica_progress"};
  FixedRouter router_{"b"};
  std::string object_;
};

TEST_F(ReplicaProgressTest, RejectsProgressOnASingleProcess) {
  Start(/*cluster=*/false);
  auto c = Follower("standby-b");
  ASSERT_TRUE(c->Send(Progress(object_, 1)));
  auto err = c->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(err->error().field(), "ReplicaProgress");
}

TEST_F(ReplicaProgressTest, RejectsProgressBeforeSubscribe) {
  Start(/*cluster=*/true);
  auto c = Follower("standby-b", /*subscribe=*/false);
  ASSERT_TRUE(c->Send(Progress(object_, 1)));
  auto err = c->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(err->error().field(), "ReplicaProgress");
}

TEST_F(ReplicaProgressTest, RejectsProgressFromAMemberThatIsNotTheStandby) {
  Start(/*cluster=*/true);
  Sculpt();
  auto c = Follower("standby-c");
  ASSERT_TRUE(c->Send(Progress(object_, 1)));
  auto err = c->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
  EXPECT_EQ(err->error().field(), "Hello.client_name");
  EXPECT_EQ(err->error().value(), "standby-c");
  EXPECT_EQ(err->error().allowed_range(), "standby-b");
  EXPECT_EQ(server_.scene().acks().standby_durable_seq(), 0u);
}

TEST_F(ReplicaProgressTest, RejectsDurableSeqPastTheScene) {
  Start(/*cluster=*/true);
  Sculpt();
  auto c = Follower("standby-b");
  ASSERT_TRUE(c->Send(Progress(object_, server_.scene().global_seq() + 1)));
  auto err = c->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().code(), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(err->error().field(), "ReplicaProgress.durable_seq");
  EXPECT_EQ(server_.scene().acks().standby_durable_seq(), 0u);
}

TEST_F(ReplicaProgressTest, RejectsUnknownObjectAndZeroSeq) {
  Start(/*cluster=*/true);
  Sculpt();
  {
    auto c = Follower("standby-b");
    ASSERT_TRUE(c->Send(Progress("no-such-object", 1)));
    auto err = c->ReadUntil(v1::ServerMessage::kError);
    ASSERT_TRUE(err.has_value());
    EXPECT_EQ(err->error().field(), "ReplicaProgress.object");
  }
  auto c = Follower("standby-b");
  ASSERT_TRUE(c->Send(Progress(object_, 0)));
  auto err = c->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->error().field(), "ReplicaProgress.durable_seq");
  EXPECT_EQ(server_.scene().acks().standby_durable_seq(), 0u);
}

TEST_F(ReplicaProgressTest, TheNamedStandbysProgressReleasesTheAck) {
  Start(/*cluster=*/true);
  RawClient s(server_.port());
  ASSERT_TRUE(s.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR));
  auto c = Follower("standby-b");
  ASSERT_TRUE(s.Send(RawClient::PressStroke(1, {0, 0, 22.5}, 3)));
  ASSERT_TRUE(sculpt::testing::WaitFor([&] { return server_.scene().global_seq() >= 3; },
                                       milliseconds(5000)));
  // Held for the standby (sync, no fall-back), though the local log is durable by now.
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_EQ(server_.scene().acks_awaiting_durability(), 1u);
  ASSERT_TRUE(c->Send(Progress(object_, server_.scene().global_seq())));
  auto ack = s.ReadUntil(v1::ServerMessage::kAck);
  ASSERT_TRUE(ack.has_value()) << "the standby's progress did not release the ack";
  EXPECT_EQ(ack->ack().client_seq(), 1u);
  EXPECT_EQ(server_.scene().acks().standby_durable_seq(), server_.scene().global_seq());
}

}  // namespace
}  // namespace sculpt::server::cluster
