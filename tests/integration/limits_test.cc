// The limits an operator sets against one client starving the others (docs/limits.md): caps on
// sessions per address and in all, reserved sculptor seats, timeouts after authentication,
// request costs, budgets shared per address and per named user, bounded untrusted text. The
// real server in-process on 127.0.0.1:0, raw clients over loopback.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <thread>

#include "integration/raw_client.h"
#include "integration/raw_server.h"
#include "net/server.h"
#include "net/users.h"
#include "scene/scene.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;
using Ms = std::chrono::milliseconds;

const char kSculptor[] = "limits-sculptor-1";
const char kViewer[] = "limits-viewer-22";

class LimitsTest : public sculpt::testing::RawServerTest {
 protected:
  void SetUp() override {
    Prepare("sculptd_limits", kSculptor, kViewer);
    config_.limits.auth_timeout_ms = 2000;
    config_.limits.violations_before_disconnect = 100;
  }
  std::unique_ptr<RawClient> Entered(v1::Role role) {
    auto c = std::make_unique<RawClient>(port_);
    EXPECT_TRUE(c->Enter(role == v1::ROLE_SCULPTOR ? kSculptor : kViewer, role));
    return c;
  }
  // The first Error on `c` (skipping other messages), or an empty one.
  static v1::Error NextError(RawClient& c) {
    auto m = c.ReadUntil(v1::ServerMessage::kError);
    return m ? m->error() : v1::Error{};
  }
  // Reads the answers to `n` strokes: acks and the errors with `field`.
  static std::pair<int, int> CountAcks(RawClient& c, int n, const std::string& field,
                                       std::string* range = nullptr) {
    int acks = 0, refused = 0;
    while (acks + refused < n) {
      auto m = c.Read();
      if (!m) break;
      if (m->has_ack()) ++acks;
      if (m->has_error() && m->error().field() == field) {
        ++refused;
        if (range) *range = m->error().allowed_range();
      }
    }
    return {acks, refused};
  }
  bool SculptorStillServed() {
    auto c = Entered(v1::ROLE_SCULPTOR);
    c->Send(RawClient::PressStroke(1, {0, 0, 13.3}));
    return c->ReadUntil(v1::ServerMessage::kAck).has_value();
  }
};

TEST_F(LimitsTest, RefusesConnectionsBeyondThePerSourceCap) {
  config_.limits.max_connections_per_source = 3;
  Start();
  std::vector<std::unique_ptr<RawClient>> held;
  for (int i = 0; i < 3; ++i) {
    held.push_back(std::make_unique<RawClient>(port_));
    ASSERT_TRUE(held.back()->Hello(kViewer, v1::ROLE_VIEWER));
    ASSERT_TRUE(held.back()->ReadUntil(v1::ServerMessage::kWelcome));
  }
  RawClient extra(port_);
  const v1::Error e = NextError(extra);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(e.field(), "limits.max_connections_per_source");
  EXPECT_EQ(e.value(), "3");
  EXPECT_TRUE(extra.WaitClosed());
  EXPECT_EQ(server_->stats().connections_refused.load(), 1u);
  // A seat freed is a seat again.
  held.back()->Close();
  held.pop_back();
  for (int i = 0; i < 100 && server_->SessionsFrom("127.0.0.1") > 2; ++i) {
    std::this_thread::sleep_for(Ms(10));
  }
  RawClient again(port_);
  ASSERT_TRUE(again.Hello(kViewer, v1::ROLE_VIEWER));
  EXPECT_TRUE(again.ReadUntil(v1::ServerMessage::kWelcome));
}

TEST_F(LimitsTest, RefusesSessionsBeyondTheTotalCap) {
  config_.limits.max_sessions = 2;
  config_.limits.max_connections_per_source = 2;
  Start();
  RawClient a(port_), b(port_);
  ASSERT_TRUE(a.Hello(kViewer, v1::ROLE_VIEWER));
  ASSERT_TRUE(a.ReadUntil(v1::ServerMessage::kWelcome));
  ASSERT_TRUE(b.Hello(kViewer, v1::ROLE_VIEWER));
  ASSERT_TRUE(b.ReadUntil(v1::ServerMessage::kWelcome));
  RawClient c(port_);
  const v1::Error e = NextError(c);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(e.field(), "limits.max_sessions");
  EXPECT_TRUE(c.WaitClosed());
}

TEST_F(LimitsTest, ViewersCannotTakeTheSeatsReservedForSculptors) {
  config_.limits.max_clients_per_scene = 4;
  config_.limits.reserved_sculptor_seats = 2;
  Start();
  auto v1c = Entered(v1::ROLE_VIEWER);
  auto v2c = Entered(v1::ROLE_VIEWER);
  RawClient v3(port_);
  ASSERT_TRUE(v3.Hello(kViewer, v1::ROLE_VIEWER));
  ASSERT_TRUE(v3.ReadUntil(v1::ServerMessage::kWelcome));
  v3.Join();
  const v1::Error e = NextError(v3);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(e.field(), "viewers");
  EXPECT_EQ(e.value(), "2");
  EXPECT_NE(e.allowed_range().find("2 of 4 seats reserved for sculptors"), std::string::npos)
      << e.allowed_range();
  EXPECT_TRUE(v3.WaitClosed());
  // Both reserved seats take sculptors; then the scene is full for everyone.
  auto s1 = Entered(v1::ROLE_SCULPTOR);
  auto s2 = Entered(v1::ROLE_SCULPTOR);
  s2->Send(RawClient::PressStroke(1, {0, 0, 13.3}));
  EXPECT_TRUE(s2->ReadUntil(v1::ServerMessage::kAck));
  RawClient s3(port_);
  ASSERT_TRUE(s3.Hello(kSculptor, v1::ROLE_SCULPTOR));
  ASSERT_TRUE(s3.ReadUntil(v1::ServerMessage::kWelcome));
  s3.Join();
  EXPECT_EQ(NextError(s3).field(), "clients");
}

TEST_F(LimitsTest, ClosesAnAuthenticatedSessionThatNeverJoins) {
  config_.limits.join_timeout_ms = 200;
  Start();
  RawClient c(port_);
  ASSERT_TRUE(c.Hello(kViewer, v1::ROLE_VIEWER));
  ASSERT_TRUE(c.ReadUntil(v1::ServerMessage::kWelcome));
  const auto t0 = std::chrono::steady_clock::now();
  const v1::Error e = NextError(c);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(e.field(), "JoinScene");
  EXPECT_TRUE(c.WaitClosed());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(2));
  EXPECT_EQ(server_->stats().sessions_timed_out.load(), 1u);
  // One that joins in time stays.
  auto joined = Entered(v1::ROLE_SCULPTOR);
  std::this_thread::sleep_for(Ms(400));
  joined->Send(RawClient::PressStroke(1, {0, 0, 13.3}));
  EXPECT_TRUE(joined->ReadUntil(v1::ServerMessage::kAck));
}

// Post-authentication slowloris: a frame begun and trickled a byte at a time never completes.
TEST_F(LimitsTest, ClosesASessionWhoseFrameNeverCompletes) {
  config_.limits.frame_timeout_ms = 300;
  Start();
  auto c = Entered(v1::ROLE_SCULPTOR);
  std::string frame;
  codec::AppendMessage(RawClient::PressStroke(1, {0, 0, 13.3}), &frame);
  const auto t0 = std::chrono::steady_clock::now();
  bool cut = false;
  for (size_t i = 0; i + 1 < frame.size() && !cut; ++i) {
    cut = !c->SendBytes(frame.substr(i, 1));
    std::this_thread::sleep_for(Ms(40));
    if (std::chrono::steady_clock::now() - t0 > std::chrono::seconds(2)) break;
  }
  const v1::Error e = NextError(*c);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_MALFORMED);
  EXPECT_EQ(e.field(), "frame");
  EXPECT_TRUE(c->WaitClosed());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(3));
  EXPECT_TRUE(SculptorStillServed());
}

TEST_F(LimitsTest, ClosesAnIdleJoinedSessionButNotOneThatSpeaks) {
  // Long enough that entering (Hello, JoinScene and the scene's first answer, read without
  // speaking) stays well inside it on a loaded machine under the sanitizers.
  config_.limits.idle_timeout_ms = 1500;
  Start();
  auto idle = Entered(v1::ROLE_VIEWER);
  auto busy = Entered(v1::ROLE_VIEWER);
  v1::ClientMessage hover;
  hover.mutable_hover()->set_radius(1);
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(busy->Send(hover));
    std::this_thread::sleep_for(Ms(250));
  }
  // The idle one was closed at ~1.5 s; the one that spoke every 250 ms is still in.
  EXPECT_EQ(server_->stats().sessions_timed_out.load(), 1u);
  EXPECT_EQ(server_->JoinedSeats().joined, 1u);
  const v1::Error e = NextError(*idle);
  EXPECT_EQ(e.field(), "idle");
  EXPECT_TRUE(idle->WaitClosed());
}

// SetInterest, joins and subscriptions cost tokens too: a flood of cheap requests is refused
// by the same rule as a flood of strokes.
TEST_F(LimitsTest, ChargesEveryRequestKind) {
  config_.limits.requests_per_second = 1;
  config_.limits.request_burst = 10;
  Start();
  auto c = Entered(v1::ROLE_VIEWER);  // the join took 4 of the 10
  v1::ClientMessage si;
  si.mutable_set_interest()->set_object("clay");
  // A small box: the base cost of 1 and a sliver for its 64 voxels.
  si.mutable_set_interest()->mutable_interest()->mutable_max()->set_x(2);
  si.mutable_set_interest()->mutable_interest()->mutable_max()->set_y(2);
  si.mutable_set_interest()->mutable_interest()->mutable_max()->set_z(2);
  for (int i = 0; i < 12; ++i) ASSERT_TRUE(c->Send(si));
  int charged = 0, others = 0;
  for (int n = 0; n < 12; ++n) {
    auto m = c->ReadUntil(v1::ServerMessage::kError);
    if (!m) break;
    if (m->error().field() == "requests_per_second") {
      ++charged;
      EXPECT_EQ(m->error().value().rfind("SetInterest costs 1.000", 0), 0u) << m->error().value();
      EXPECT_NE(m->error().allowed_range().find("per connection"), std::string::npos);
    } else {
      ++others;  // not subscribed: the scene's own refusal
    }
  }
  EXPECT_GE(charged, 5);
  EXPECT_LE(charged, 7);
  EXPECT_EQ(charged + others, 12);
}

// A region request is charged by the voxels it may make the server send: the whole object
// (radius 12, voxel 0.5: about 60^3 voxels in its bounds) costs almost twice a small box.
TEST_F(LimitsTest, ChargesARegionRequestByItsSize) {
  config_.limits.requests_per_second = 1;
  config_.limits.request_burst = 10;
  Start();
  auto c = Entered(v1::ROLE_VIEWER);
  v1::ClientMessage whole;
  whole.mutable_set_interest()->set_object("clay");  // no box: the whole object
  for (int i = 0; i < 6; ++i) ASSERT_TRUE(c->Send(whole));
  int passed = 0;
  double cost = 0;
  for (int n = 0; n < 6; ++n) {
    auto m = c->ReadUntil(v1::ServerMessage::kError);
    ASSERT_TRUE(m);
    if (m->error().field() != "requests_per_second") {
      ++passed;
      continue;
    }
    const std::string v = m->error().value();
    cost = std::stod(v.substr(v.find("costs ") + 6));
  }
  EXPECT_GT(cost, 1.5);
  EXPECT_LT(cost, 2.5);
  EXPECT_LE(passed, 4);  // 6 tokens left after the join, almost 2 each
}

// Several connections from one address share its budget: neither more connections nor
// reconnecting buys more strokes than source_rate_factor clients' worth.
TEST_F(LimitsTest, ReconnectingDoesNotEvadeTheStrokeLimit) {
  config_.limits.strokes_per_second = 1;
  config_.limits.stroke_burst = 6;
  config_.limits.source_rate_factor = 1;
  Start();
  {
    auto a = Entered(v1::ROLE_SCULPTOR);
    for (int i = 1; i <= 6; ++i) a->Send(RawClient::PressStroke(i, {0, 0, 13.3}));
    EXPECT_EQ(CountAcks(*a, 6, "strokes_per_second").first, 6);
  }
  // A new connection from the same address, with a fresh per-connection bucket.
  auto b = Entered(v1::ROLE_SCULPTOR);
  for (int i = 1; i <= 3; ++i) b->Send(RawClient::PressStroke(100 + i, {0, 0, 13.3}));
  std::string range;
  const auto [acks, refused] = CountAcks(*b, 3, "strokes_per_second", &range);
  EXPECT_LE(acks, 1);  // at most the token refilled meanwhile
  EXPECT_GE(refused, 2);
  EXPECT_NE(range.find("per source address"), std::string::npos) << range;
}

// A client that reconnects resends what it has not seen acknowledged, at once (after a failover,
// seconds of strokes). What the scene had already committed is answered as a duplicate without
// tokens, so the burst is not refused; replaying those sequences again is charged as usual.
TEST_F(LimitsTest, ResendsOfCommittedStrokesAfterAReconnectTakeNoTokensButReplaysDo) {
  config_.limits.strokes_per_second = 1;
  config_.limits.stroke_burst = 6;
  config_.limits.source_rate_factor = 1;
  Start();
  const uint64_t id = 0x5eed0000u + static_cast<uint64_t>(::getpid());
  {
    RawClient a(port_);
    ASSERT_TRUE(a.Enter(kSculptor, v1::ROLE_SCULPTOR, id));
    for (int i = 1; i <= 6; ++i) a.Send(RawClient::PressStroke(i, {0, 0, 13.3}));
    ASSERT_EQ(CountAcks(a, 6, "strokes_per_second").first, 6);
  }
  // Same client, new connection, same address: the address's bucket is empty.
  RawClient b(port_);
  ASSERT_TRUE(b.Enter(kSculptor, v1::ROLE_SCULPTOR, id));
  for (int i = 1; i <= 6; ++i) b.Send(RawClient::PressStroke(i, {0, 0, 13.3}));
  int duplicates = 0, refused = 0;
  for (int answers = 0; answers < 6;) {
    auto m = b.Read();
    ASSERT_TRUE(m.has_value()) << "after " << answers << " answers";
    if (m->has_ack()) duplicates += m->ack().duplicate() ? 1 : 0;
    if (m->has_error()) {
      ++refused;
      ADD_FAILURE() << m->error().ShortDebugString();
    }
    answers += (m->has_ack() || m->has_error()) ? 1 : 0;
  }
  EXPECT_EQ(duplicates, 6);
  EXPECT_EQ(refused, 0);
  // The same sequences once more on this connection are no longer resends of a reconnect.
  for (int i = 1; i <= 6; ++i) b.Send(RawClient::PressStroke(i, {0, 0, 13.3}));
  const auto [acks, replays_refused] = CountAcks(b, 6, "strokes_per_second");
  EXPECT_LE(acks, 1);  // at most the token refilled meanwhile
  EXPECT_GE(replays_refused, 5);
}

// After a failover the client resends strokes the new owner never committed: they must be
// applied, not refused by the rate limit. Declared in JoinScene.resends, a burst far above
// stroke_burst is all applied; strokes beyond the declared range are charged as usual.
TEST_F(LimitsTest, DeclaredResendsAfterAReconnectAreAllAppliedButLaterStrokesAreCharged) {
  config_.limits.strokes_per_second = 1;
  config_.limits.stroke_burst = 4;
  config_.limits.source_rate_factor = 1;
  Start();
  // Allowance 4 + 5 s x 1/s = 9 free edits per connection.
  const uint64_t id = 0x5eed1000u + static_cast<uint64_t>(::getpid());
  v1::JoinScene join;
  v1::ResendRange* r = join.add_resends();
  r->set_stream(v1::EDIT_STREAM_STROKES);
  r->set_first_seq(1);
  r->set_last_seq(9);
  RawClient a(port_);
  ASSERT_TRUE(a.Enter(kSculptor, v1::ROLE_SCULPTOR, id, join));
  for (int i = 1; i <= 17; ++i) a.Send(RawClient::PressStroke(i, {0, 0, 13.3}, 1));
  int applied = 0, refused = 0;
  std::vector<uint64_t> refused_seqs;
  for (int answers = 0; answers < 17;) {
    auto m = a.Read();
    ASSERT_TRUE(m.has_value()) << "after " << answers << " answers";
    if (m->has_ack()) {
      EXPECT_FALSE(m->ack().duplicate());
      ++applied;
      ++answers;
    } else if (m->has_error() && m->error().field() == "strokes_per_second") {
      ++refused;
      refused_seqs.push_back(m->error().client_seq());
      ++answers;
    } else if (m->has_error()) {
      ADD_FAILURE() << m->error().ShortDebugString();
      ++answers;
    }
  }
  // The 9 declared ones all; of the 8 after them the 4-token burst (the declared ones took
  // none) and at most one token refilled meanwhile.
  EXPECT_GE(applied, 9 + 4);
  EXPECT_LE(applied, 9 + 5);
  EXPECT_GE(refused, 3);
  for (uint64_t seq : refused_seqs) EXPECT_GT(seq, 9u + 4u);
  EXPECT_EQ(applied + refused, 17);
}

// Declared resends and undeclared ones on the same tight limits: without the declaration the
// same burst is refused past the bucket; with a declaration larger than the allowance the join
// is refused naming the field.
TEST_F(LimitsTest, UndeclaredResendsAreChargedAndATooLargeDeclarationIsRefused) {
  config_.limits.strokes_per_second = 1;
  config_.limits.stroke_burst = 4;
  config_.limits.source_rate_factor = 1;
  Start();
  {
    RawClient a(port_);
    ASSERT_TRUE(a.Enter(kSculptor, v1::ROLE_SCULPTOR));
    for (int i = 1; i <= 9; ++i) a.Send(RawClient::PressStroke(i, {0, 0, 13.3}, 1));
    const auto [acks, refused] = CountAcks(a, 9, "strokes_per_second");
    EXPECT_LE(acks, 5);  // the burst of 4 and at most one token refilled meanwhile
    EXPECT_GE(refused, 4);
  }
  RawClient b(port_);
  ASSERT_TRUE(b.Hello(kSculptor, v1::ROLE_SCULPTOR));
  ASSERT_TRUE(b.ReadUntil(v1::ServerMessage::kWelcome));
  v1::JoinScene join;
  v1::ResendRange* r = join.add_resends();
  r->set_stream(v1::EDIT_STREAM_STROKES);
  r->set_first_seq(100);
  r->set_last_seq(109);  // 10 > 4 + 5 s x 1/s
  ASSERT_TRUE(b.Join(join));
  const v1::Error e = NextError(b);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(e.field(), "JoinScene.resends");
  EXPECT_EQ(e.value(), "10 client_seqs");
  EXPECT_EQ(e.allowed_range().rfind("[0, 9]", 0), 0u) << e.allowed_range();
  // Not joined: a stroke is refused as before JoinScene.
  b.Send(RawClient::PressStroke(100, {0, 0, 13.3}, 1));
  EXPECT_EQ(NextError(b).field(), "Stroke");
}

// A job on the compute thread is never interrupted, so a stroke's kernel work is bounded: a
// long stroke is refused naming the limit and how many of its poses fit, those poses are
// accepted, one more is not, and a single pose of any allowed tool is always accepted.
TEST_F(LimitsTest, AStrokeAskingMoreKernelWorkThanTheLimitIsRefusedSayingHowManyPosesFit) {
  config_.limits.max_stroke_work = 1 << 19;
  Start();
  auto a = Entered(v1::ROLE_SCULPTOR);
  a->Send(RawClient::PressStroke(1, {0, 0, 13.3}, 32));
  const v1::Error e = NextError(*a);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(e.field(), "Stroke.pose_count");
  EXPECT_EQ(e.value().rfind("32 poses asking ", 0), 0u) << e.value();
  const std::string& range = e.allowed_range();
  EXPECT_NE(range.find("<= 524288 (limits.max_stroke_work)"), std::string::npos) << range;
  const size_t at = range.find("its first ");
  ASSERT_NE(at, std::string::npos) << range;
  const int fit = std::stoi(range.substr(at + 10));
  EXPECT_GE(fit, 2);
  EXPECT_LT(fit, 32);
  a->Send(RawClient::PressStroke(2, {0, 0, 13.3}, fit));
  EXPECT_EQ(CountAcks(*a, 1, "Stroke.pose_count"), std::make_pair(1, 0));
  a->Send(RawClient::PressStroke(3, {0, 0, 13.3}, fit + 1));
  EXPECT_EQ(CountAcks(*a, 1, "Stroke.pose_count"), std::make_pair(0, 1));
  // One pose of a tool whose block alone is over the limit.
  a->Send(RawClient::PressStroke(4, {0, 0, 13.3}, 1, 8));
  EXPECT_EQ(CountAcks(*a, 1, "Stroke.pose_count"), std::make_pair(1, 0));
  EXPECT_TRUE(SculptorStillServed());
}

// A re-join flood: each reconnection costs the address a connection and a join; past its
// budget connections are refused at once, before any state is serialised.
TEST_F(LimitsTest, ARejoinFloodIsRefusedPerSource) {
  config_.limits.requests_per_second = 1;
  config_.limits.request_burst = 10;
  config_.limits.source_rate_factor = 1;
  Start();
  int entered = 0, refused = 0;
  for (int i = 0; i < 6; ++i) {
    RawClient c(port_);
    c.Hello(kViewer, v1::ROLE_VIEWER);
    auto m = c.Read();
    while (m && !m->has_welcome() && !m->has_error()) m = c.Read();
    if (m && m->has_error()) {
      EXPECT_EQ(m->error().field(), "requests_per_second");
      EXPECT_NE(m->error().allowed_range().find("per source address"), std::string::npos);
      ++refused;
      continue;
    }
    c.Join();
    auto r = c.Read();
    while (r && !r->has_scene_info() && !r->has_error()) r = c.Read();
    if (r && r->has_scene_info()) ++entered;
    if (r && r->has_error()) ++refused;
  }
  EXPECT_EQ(entered, 2);  // 2 x (1 connection + 4 join) = the burst of 10
  EXPECT_EQ(refused, 4);
}

TEST_F(LimitsTest, ANamedUsersSessionsShareOneBudgetWhereverTheyConnectFrom) {
  const std::string token = NewToken();
  UserTable t;
  t.Put({"mallory", UserRole::kSculptor, HashToken(token).value()});
  fs::create_directories(dir_);
  config_.users_file = (dir_ / "users.toml").string();
  ASSERT_TRUE(t.Save(config_.users_file).ok());
  config_.limits.strokes_per_second = 1;
  config_.limits.stroke_burst = 4;
  config_.limits.source_rate_factor = 100;  // the address would allow far more
  Start();
  auto enter = [&](RawClient& c, uint64_t client_id) {
    v1::ClientMessage m;
    auto* h = m.mutable_hello();
    h->set_protocol_version(1);
    h->set_token(token);
    h->set_role(v1::ROLE_SCULPTOR);
    h->set_client_name("mallory");
    h->set_client_id(client_id);
    c.Send(m);
    ASSERT_TRUE(c.ReadUntil(v1::ServerMessage::kWelcome));
    c.Join();
    ASSERT_TRUE(c.ReadUntil(v1::ServerMessage::kSceneInfo));
  };
  RawClient a(port_), b(port_);
  enter(a, 1);
  enter(b, 2);
  for (int i = 1; i <= 4; ++i) a.Send(RawClient::PressStroke(i, {0, 0, 13.3}));
  EXPECT_EQ(CountAcks(a, 4, "strokes_per_second").first, 4);
  for (int i = 1; i <= 3; ++i) b.Send(RawClient::PressStroke(i, {0, 0, 13.3}));
  std::string range;
  const auto [acks, refused] = CountAcks(b, 3, "strokes_per_second", &range);
  EXPECT_LE(acks, 1);
  EXPECT_GE(refused, 2);
  EXPECT_NE(range.find("per user"), std::string::npos) << range;
}

// Untrusted text: a Bye before Hello with a long reason full of line breaks becomes one short,
// escaped log line; a long name in a request is not echoed back at length.
TEST_F(LimitsTest, UntrustedTextIsBoundedAndEscapedInLogsAndErrors) {
  auto out = std::make_shared<std::ostringstream>();
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(*out);
  auto previous = spdlog::default_logger();
  spdlog::set_default_logger(std::make_shared<spdlog::logger>("capture", sink));
  Start();
  {
    RawClient c(port_);
    std::string reason;
    for (int i = 0; i < 20000; ++i) reason += "\n[2026-11-23 00:00:00.000] [error] forged line";
    v1::ClientMessage bye;
    bye.mutable_bye()->set_reason(reason);
    ASSERT_TRUE(c.Send(bye));
    EXPECT_TRUE(c.WaitClosed());
  }
  auto c = Entered(v1::ROLE_VIEWER);
  const std::string name(1 << 19, 'n');
  v1::ClientMessage join;
  join.mutable_join()->set_scene(name);
  ASSERT_TRUE(c->Send(join));
  auto m = c->ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(m);
  EXPECT_EQ(m->error().field(), "JoinScene.scene");
  EXPECT_LT(m->ByteSizeLong(), 2048u);
  EXPECT_NE(m->error().value().find("(524288 bytes)"), std::string::npos);
  for (int i = 0; i < 100 && out->str().find("client said bye") == std::string::npos; ++i) {
    std::this_thread::sleep_for(Ms(10));
  }
  spdlog::set_default_logger(previous);
  const std::string log = out->str();
  EXPECT_NE(log.find("client said bye: \\x0a[2026"), std::string::npos) << log.substr(0, 2000);
  EXPECT_EQ(log.find("\n[2026-11-23 00:00:00.000] [error] forged"), std::string::npos);
  EXPECT_LT(log.size(), 8192u);
}

}  // namespace
}  // namespace sculpt::server
