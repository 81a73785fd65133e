/// @brief sculpt::client::Client against the real server in-process over loopback: concurrent
/// sculptors, ordered acks, recovery by replay, resends without double application, viewer
/// permissions, late joiners, refusals that name field, value and range.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "integration/in_process_server.h"
#include "sculpt/client/client.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::client {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr char kViewerToken[] = "sculpt-dev-viewer";
constexpr int kPosesPerStroke = 4;

StrokeRequest Arc(double z, int i, int poses = kPosesPerStroke) {
  return testing_support::PressArc(z, i, poses);
}

/// The acks among `events`, in arrival order.
std::vector<v1::Ack> Acks(const std::vector<Event>& events) {
  std::vector<v1::Ack> out;
  for (const Event& e : events) {
    if (e.type == Event::Type::kAck) out.push_back(e.ack);
  }
  return out;
}

class ClientServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_ = &srv_.config();
    dir_ = srv_.dir();
    ASSERT_TRUE(srv_.Start());
    scene_ = &srv_.scene();
    port_ = srv_.port();
  }

  /// A client that has said Hello and joined the default scene.
  std::unique_ptr<Client> Joined(v1::Role role, const std::string& name, uint64_t client_id = 0) {
    return srv_.Joined(role, /*skip_state=*/false, name, client_id);
  }

  testing_support::InProcessServer srv_{"client_server"};
  server::ServerConfig* config_ = nullptr;
  fs::path dir_;
  server::Scene* scene_ = nullptr;
  uint16_t port_ = 0;
};

TEST_F(ClientServerTest, ConcurrentSculptorsAckedInOrderAndReplayMatches) {
  constexpr int kStrokes = 25;
  auto a = Joined(v1::ROLE_SCULPTOR, "a");
  auto b = Joined(v1::ROLE_SCULPTOR, "b");
  ASSERT_TRUE(a->joined() && b->joined());

  auto send = [](Client* c, double z) {
    for (int i = 0; i < kStrokes; ++i) EXPECT_TRUE(c->SendStroke(Arc(z, i)).ok());
  };
  std::thread ta(send, a.get(), 10.0);
  std::thread tb(send, b.get(), -10.0);
  ta.join();
  tb.join();
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  ASSERT_TRUE(b->WaitAllAcked(seconds(20)));

  std::set<uint64_t> seqs;
  for (Client* c : {a.get(), b.get()}) {
    const std::vector<v1::Ack> acks = Acks(c->DrainEvents());
    ASSERT_EQ(acks.size(), static_cast<size_t>(kStrokes));
    uint64_t previous = 0;
    for (const v1::Ack& ack : acks) {
      EXPECT_FALSE(ack.duplicate());
      EXPECT_EQ(ack.edits(), static_cast<uint32_t>(kPosesPerStroke));
      EXPECT_GT(ack.global_seq_first(), previous) << "acks of one client out of order";
      previous = ack.global_seq_first();
      for (uint32_t k = 0; k < ack.edits(); ++k) {
        EXPECT_TRUE(seqs.insert(ack.global_seq_first() + k).second) << "sequence given twice";
      }
    }
    const ClientStats st = c->stats();
    EXPECT_EQ(st.acks, static_cast<uint64_t>(kStrokes));
    EXPECT_EQ(st.acks_out_of_order, 0u);
    EXPECT_EQ(st.refused, 0u);
  }
  // Every global sequence 1..N was given to exactly one pose of one of the two clients.
  const uint64_t total = 2 * kStrokes * kPosesPerStroke;
  ASSERT_EQ(seqs.size(), total);
  EXPECT_EQ(*seqs.begin(), 1u);
  EXPECT_EQ(*seqs.rbegin(), total);
  EXPECT_EQ(scene_->global_seq(), total);

  // Recovery replays the edit log to the same state.
  scene_->Flush();
  const uint64_t live = scene_->StateHash("clay");
  const fs::path copy = dir_ / "copy";
  fs::copy(config_->data_dir, copy, fs::copy_options::recursive);
  server::ServerConfig replay_config = *config_;
  replay_config.data_dir = copy.string();
  auto replayed = server::Scene::Open(replay_config);
  ASSERT_TRUE(replayed.ok()) << replayed.status();
  EXPECT_EQ((*replayed)->global_seq(), total);
  EXPECT_EQ((*replayed)->StateHash("clay"), live);
}

TEST_F(ClientServerTest, ReconnectResendsUnackedStrokesWithoutApplyingTwice) {
  constexpr int kBeforeDrop = 10;
  constexpr int kWhileDown = 3;
  auto c = Joined(v1::ROLE_SCULPTOR, "resender", /*client_id=*/0x5eed);
  for (int i = 0; i < kBeforeDrop; ++i) ASSERT_TRUE(c->SendStroke(Arc(5, i)).ok());
  // The server reads every stroke before the end of stream, applies them, and drops the acks
  // of a closed session: they are un-acked here but applied there.
  c->DropConnection();
  EXPECT_FALSE(c->connected());
  scene_->Flush();
  EXPECT_EQ(scene_->global_seq(), static_cast<uint64_t>(kBeforeDrop * kPosesPerStroke));
  const size_t unacked_at_drop = c->unacked();
  EXPECT_GT(unacked_at_drop, 0u) << "every ack arrived before the drop: the resend is untested";

  // Strokes made while disconnected wait behind the resends.
  for (int i = kBeforeDrop; i < kBeforeDrop + kWhileDown; ++i) {
    ASSERT_TRUE(c->SendStroke(Arc(5, i)).ok());
  }
  ASSERT_TRUE(c->Reconnect().ok());
  ASSERT_TRUE(c->WaitAllAcked(seconds(20)));

  const ClientStats st = c->stats();
  EXPECT_EQ(st.acks, static_cast<uint64_t>(kBeforeDrop + kWhileDown));
  EXPECT_EQ(st.duplicate_acks, unacked_at_drop);
  EXPECT_EQ(st.strokes_resent, unacked_at_drop);
  EXPECT_EQ(st.acks_out_of_order, 0u);
  EXPECT_EQ(st.reconnects, 1u);
  // Distinct poses, each applied once.
  EXPECT_EQ(scene_->global_seq(),
            static_cast<uint64_t>((kBeforeDrop + kWhileDown) * kPosesPerStroke));
  std::vector<uint64_t> duplicates;
  for (const v1::Ack& ack : Acks(c->DrainEvents())) {
    if (ack.duplicate()) duplicates.push_back(ack.client_seq());
  }
  EXPECT_EQ(duplicates.size(), unacked_at_drop);
  for (uint64_t seq : duplicates) EXPECT_LE(seq, static_cast<uint64_t>(kBeforeDrop));
}

// After a failover a client has seconds of strokes to resend, more than the server's stroke
// burst (60 per connection by default): the client writes a burst and paces the rest under the
// rate the Welcome names, so none is refused, and the strokes made meanwhile follow in order.
TEST_F(ClientServerTest, ResendsMoreThanTheStrokeBurstArePacedNotRefused) {
  constexpr int kWhileDown = 150;  // 2.5 burst's worth, never written before the Reconnect
  auto c = Joined(v1::ROLE_SCULPTOR, "pacer", /*client_id=*/0x9ace);
  ASSERT_TRUE(c->SendStroke(Arc(5, 0)).ok());
  ASSERT_TRUE(c->WaitAllAcked(seconds(10)));
  c->DropConnection();
  for (int i = 1; i <= kWhileDown; ++i) ASSERT_TRUE(c->SendStroke(Arc(5, i % 24)).ok());
  ASSERT_TRUE(c->Reconnect().ok());
  // Made while the resends are still going out: they queue behind them.
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(c->SendStroke(Arc(5, i)).ok());
  ASSERT_TRUE(c->WaitAllAcked(seconds(30)));
  const ClientStats st = c->stats();
  EXPECT_EQ(st.refused, 0u) << "resends refused by the server's stroke limit";
  EXPECT_EQ(st.acks, static_cast<uint64_t>(1 + kWhileDown + 5));
  EXPECT_EQ(st.acks_out_of_order, 0u);
  EXPECT_EQ(scene_->global_seq(), static_cast<uint64_t>((1 + kWhileDown + 5) * kPosesPerStroke));
}

// A server whose stroke burst (8) is below the client's resend burst (24 written at once): the
// client declares its pending strokes in the JoinScene, so the server takes no tokens for them
// however fast it reads them, and none is refused; without the declaration 16 of the first 24
// would be.
class TightBurstClientServerTest : public ClientServerTest {
 protected:
  void SetUp() override {
    srv_.config().limits.stroke_burst = 8;
    ClientServerTest::SetUp();
  }
};

TEST_F(TightBurstClientServerTest, ResendsDeclaredInTheJoinAreNotRefusedBeyondTheStrokeBurst) {
  constexpr int kWhileDown = 100;
  auto c = Joined(v1::ROLE_SCULPTOR, "declarer", /*client_id=*/0xdec1);
  ASSERT_TRUE(c->SendStroke(Arc(5, 0)).ok());
  ASSERT_TRUE(c->WaitAllAcked(seconds(10)));
  c->DropConnection();
  for (int i = 1; i <= kWhileDown; ++i) ASSERT_TRUE(c->SendStroke(Arc(5, i % 24)).ok());
  ASSERT_TRUE(c->Reconnect().ok());
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(c->SendStroke(Arc(5, i)).ok());
  ASSERT_TRUE(c->WaitAllAcked(seconds(30)));
  const ClientStats st = c->stats();
  EXPECT_EQ(st.refused, 0u) << "declared resends refused by the server's stroke limit";
  EXPECT_EQ(st.acks, static_cast<uint64_t>(1 + kWhileDown + 5));
  EXPECT_EQ(st.acks_out_of_order, 0u);
  EXPECT_EQ(scene_->global_seq(), static_cast<uint64_t>((1 + kWhileDown + 5) * kPosesPerStroke));
}

TEST_F(ClientServerTest, ViewerStrokeIsPermissionDeniedWhileSculptorKeepsWorking) {
  constexpr int kStrokes = 20;
  auto sculptor = Joined(v1::ROLE_SCULPTOR, "sculptor");
  auto viewer = Joined(v1::ROLE_VIEWER, "viewer");
  std::thread work([&] {
    for (int i = 0; i < kStrokes; ++i) EXPECT_TRUE(sculptor->SendStroke(Arc(-4, i)).ok());
  });
  auto seq = viewer->SendStroke(Arc(12, 0));
  ASSERT_TRUE(seq.ok()) << seq.status();
  std::optional<Event> refusal;
  while (auto e = viewer->NextEvent(seconds(10))) {
    if (e->type == Event::Type::kError) {
      refusal = std::move(e);
      break;
    }
  }
  work.join();
  ASSERT_TRUE(refusal.has_value()) << "no Error for the viewer's stroke";
  EXPECT_EQ(refusal->error.code(), v1::ERROR_CODE_PERMISSION_DENIED);
  EXPECT_EQ(refusal->error.client_seq(), *seq);
  EXPECT_TRUE(refusal->refused);
  EXPECT_EQ(viewer->unacked(), 0u);
  EXPECT_TRUE(viewer->connected());

  ASSERT_TRUE(sculptor->WaitAllAcked(seconds(20)));
  EXPECT_EQ(sculptor->stats().acks, static_cast<uint64_t>(kStrokes));
  EXPECT_EQ(sculptor->stats().refused, 0u);
  EXPECT_EQ(scene_->global_seq(), static_cast<uint64_t>(kStrokes * kPosesPerStroke));
}

TEST_F(ClientServerTest, LateJoinerStateHashEqualsScene) {
  constexpr int kStrokes = 15;
  auto sculptor = Joined(v1::ROLE_SCULPTOR, "early");
  for (int i = 0; i < kStrokes; ++i) ASSERT_TRUE(sculptor->SendStroke(Arc(16, i)).ok());
  ASSERT_TRUE(sculptor->WaitAllAcked(seconds(20)));

  ClientOptions options;
  Client late(options);
  ASSERT_TRUE(late.Connect("127.0.0.1", port_).ok());
  ASSERT_TRUE(late.Hello(kViewerToken, v1::ROLE_VIEWER, "late", 0).ok());
  auto joined = late.Join();
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_EQ(joined->info.global_seq(), static_cast<uint64_t>(kStrokes * kPosesPerStroke));
  ASSERT_EQ(joined->info.objects_size(), 1);
  ASSERT_EQ(joined->state.count("clay"), 1u);
  auto sculpture = levelset::Sculpture::DeserializeVdb(joined->state.at("clay"));
  ASSERT_TRUE(sculpture.ok()) << sculpture.status();
  const uint64_t live = scene_->StateHash("clay");
  EXPECT_EQ(sculpture->StateHash(), live);
  EXPECT_EQ(joined->info.objects(0).state_hash(), live);
}

TEST_F(ClientServerTest, RefusedStrokeNamesFieldValueAndRangeAndConnectionStays) {
  auto c = Joined(v1::ROLE_SCULPTOR, "careless");
  StrokeRequest too_big = Arc(0, 0);
  too_big.tool_size = {40, 0, 0};
  auto bad = c->SendStroke(too_big);
  ASSERT_TRUE(bad.ok());
  auto good = c->SendStroke(Arc(0, 1));
  ASSERT_TRUE(good.ok());
  ASSERT_TRUE(c->WaitAllAcked(seconds(10)));

  const std::vector<Event> events = c->DrainEvents();
  const auto error = std::find_if(events.begin(), events.end(),
                                  [](const Event& e) { return e.type == Event::Type::kError; });
  ASSERT_NE(error, events.end());
  EXPECT_EQ(error->error.code(), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(error->error.client_seq(), *bad);
  EXPECT_EQ(error->error.field(), "Stroke.tool_size.x");
  EXPECT_EQ(error->error.value(), "40");
  EXPECT_EQ(error->error.allowed_range(), "[0.5, 16]");
  const std::vector<v1::Ack> acks = Acks(events);
  ASSERT_EQ(acks.size(), 1u);
  EXPECT_EQ(acks[0].client_seq(), *good);
  EXPECT_EQ(c->stats().refused, 1u);
  EXPECT_TRUE(c->connected());
  const Status as_status = ErrorToStatus(error->error);
  EXPECT_EQ(as_status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(as_status.message().find("Stroke.tool_size.x=40 outside [0.5, 16]"), std::string::npos);
}

TEST_F(ClientServerTest, WrongTokenIsUnauthenticated) {
  Client c;
  ASSERT_TRUE(c.Connect("127.0.0.1", port_).ok());
  auto welcome = c.Hello("not-the-token", v1::ROLE_SCULPTOR, "intruder", 0);
  ASSERT_FALSE(welcome.ok());
  EXPECT_EQ(welcome.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(welcome.status().message().find("ERROR_CODE_UNAUTHENTICATED Hello.token="),
            std::string::npos)
      << welcome.status();
}

TEST_F(ClientServerTest, UnknownSceneIsNotFound) {
  Client c;
  ASSERT_TRUE(c.Connect("127.0.0.1", port_).ok());
  ASSERT_TRUE(c.Hello(kViewerToken, v1::ROLE_VIEWER, "lost", 0).ok());
  auto joined = c.Join("no-such-scene");
  ASSERT_FALSE(joined.ok());
  EXPECT_EQ(joined.status().code(), Status::Code::kNotFound);
  EXPECT_FALSE(c.SendStroke(Arc(0, 0)).ok()) << "a stroke needs a joined scene";
}

TEST_F(ClientServerTest, ConnectToClosedPortIsUnavailable) {
  server::asio::io_context io;
  server::tcp::acceptor probe(
      io, server::tcp::endpoint(server::asio::ip::make_address("127.0.0.1"), 0));
  const uint16_t closed = probe.local_endpoint().port();
  probe.close();
  Client c;
  const Status s = c.Connect("127.0.0.1", closed);
  EXPECT_EQ(s.code(), Status::Code::kUnavailable) << s;
}

/// Runs the `sculpt` binary; returns its exit code, stdout in `out`.
int RunSculpt(const std::string& args, const fs::path& out) {
  const std::string cmd = std::string(SCULPT_BIN_DIR) + "/sculpt " + args + " > " + out.string() +
                          " 2> " + out.string() + ".err";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

nlohmann::json ArcScript(int strokes, double tool_size) {
  nlohmann::json script = {{"object", "clay"}, {"kind", "press"},
                           {"tool", "sphere"}, {"size", {tool_size, 0, 0}},
                           {"speed", 60},      {"strokes", nlohmann::json::array()}};
  for (int i = 0; i < strokes; ++i) {
    const StrokeRequest s = Arc(-16, i);
    nlohmann::json poses = nlohmann::json::array();
    for (const codec::Pose& p : s.poses) {
      poses.push_back({p.position.x, p.position.y, p.position.z, p.t_ms});
    }
    script["strokes"].push_back({{"t_ms", i * 5}, {"poses", poses}});
  }
  return script;
}

TEST_F(ClientServerTest, PlayScriptIsAckedAndExportFetchesTheServerState) {
  constexpr int kStrokes = 8;
  const fs::path script = dir_ / "strokes.json";
  std::ofstream(script) << ArcScript(kStrokes, 2.5).dump();
  const std::string server = "--server 127.0.0.1:" + std::to_string(port_);
  ASSERT_EQ(RunSculpt("play " + server + " --script " + script.string(), dir_ / "play.json"), 0);
  const nlohmann::json summary = nlohmann::json::parse(std::ifstream(dir_ / "play.json"));
  EXPECT_EQ(summary["acked"].get<int>(), kStrokes);
  EXPECT_EQ(summary["refused"].get<int>(), 0);
  EXPECT_EQ(summary["unacked"].get<int>(), 0);
  EXPECT_EQ(summary["poses_applied"].get<int>(), kStrokes * kPosesPerStroke);
  EXPECT_TRUE(summary["acks_in_order"].get<bool>());
  EXPECT_EQ(scene_->global_seq(), static_cast<uint64_t>(kStrokes * kPosesPerStroke));

  const fs::path vdb = dir_ / "fetched.vdb";
  ASSERT_EQ(RunSculpt("export " + server + " --out " + vdb.string(), dir_ / "export.txt"), 0);
  auto fetched = levelset::Sculpture::LoadVdb(vdb.string());
  ASSERT_TRUE(fetched.ok()) << fetched.status();
  EXPECT_EQ(fetched->StateHash(), scene_->StateHash("clay"));
  const fs::path mesh = dir_ / "fetched";
  ASSERT_EQ(RunSculpt("export " + server + " --format obj --out " + mesh.string(),
                      dir_ / "export-obj.txt"),
            0);
  EXPECT_GT(fs::file_size(dir_ / "fetched.obj"), 1000u);
  EXPECT_EQ(RunSculpt("export " + server + " --format ply --out " + (dir_ / "x.obj").string(),
                      dir_ / "export-bad.txt"),
            2)
      << "a --format that contradicts the --out extension is a usage error";
}

TEST_F(ClientServerTest, PlayExitsNonZeroWhenAStrokeIsRefused) {
  const fs::path script = dir_ / "too-big.json";
  std::ofstream(script) << ArcScript(2, 40).dump();
  EXPECT_EQ(
      RunSculpt("play --server 127.0.0.1:" + std::to_string(port_) + " --script " + script.string(),
                dir_ / "play.json"),
      1);
  const nlohmann::json summary = nlohmann::json::parse(std::ifstream(dir_ / "play.json"));
  EXPECT_EQ(summary["refused"].get<int>(), 2);
  ASSERT_EQ(summary["errors"].size(), 2u);
  EXPECT_EQ(summary["errors"][0]["code"], "INVALID_ARGUMENT");
  EXPECT_EQ(summary["errors"][0]["field"], "Stroke.tool_size.x");
  EXPECT_EQ(summary["errors"][0]["allowed_range"], "[0.5, 16]");
  EXPECT_EQ(scene_->global_seq(), 0u);

  std::ofstream(dir_ / "broken.json") << R"({"strokes": [{"t_ms": 0, "poses": [[1, 2]]}]})";
  EXPECT_EQ(RunSculpt("play --server 127.0.0.1:" + std::to_string(port_) + " --script " +
                          (dir_ / "broken.json").string(),
                      dir_ / "broken.txt"),
            2);
}

TEST(ParseServerAddressTest, AcceptsHostPortAndRejectsTheRest) {
  std::string host;
  uint16_t port = 0;
  ASSERT_TRUE(ParseServerAddress("127.0.0.1:7420", &host, &port).ok());
  EXPECT_EQ(host, "127.0.0.1");
  EXPECT_EQ(port, 7420);
  ASSERT_TRUE(ParseServerAddress("[::1]:9", &host, &port).ok());
  EXPECT_EQ(host, "::1");
  for (const char* bad : {"", "host", "host:", ":80", "h:0", "h:65536", "h:8x", "[::1:80"}) {
    EXPECT_EQ(ParseServerAddress(bad, &host, &port).code(), Status::Code::kInvalidArgument) << bad;
  }
}

}  // namespace
}  // namespace sculpt::client
