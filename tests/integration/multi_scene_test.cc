// One sculptd process hosting several scenes (docs/scenes.md): each scene its own sequence, state,
// data directory, presence and seats; a join naming no scene takes the first. The real Server
// with every hosted Scene in-process on 127.0.0.1:0, raw clients over loopback.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "config/server_config.h"
#include "integration/prometheus_text.h"
#include "integration/raw_client.h"
#include "net/http_server.h"
#include "net/server.h"
#include "scene/scene.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;

const char kSculptor[] = "multi-sculptor-1";
const char kViewer[] = "multi-viewer-22";

v1::JoinScene JoinOf(const std::string& scene) {
  v1::JoinScene j;
  j.set_scene(scene);
  return j;
}

class MultiSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculptd_multi_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    config_.listen = "127.0.0.1:0";
    config_.data_dir = (dir_ / "data").string();
    config_.sculptor_token = kSculptor;
    config_.viewer_token = kViewer;
    config_.scene.name = "a";
    config_.scene.also = {"b"};
    config_.scene.objects[0].radius = 12;
    config_.limits.violations_before_disconnect = 100;
  }
  void TearDown() override {
    Stop();
    fs::remove_all(dir_);
  }

  // Opens every hosted scene as sculptd does (ConfigForScene) and listens, HTTP port included.
  void Start() {
    ASSERT_TRUE(ValidateConfig(config_).ok()) << ValidateConfig(config_);
    std::vector<Scene*> hosted;
    for (const std::string& name : HostedScenes(config_)) {
      auto scene = Scene::Open(ConfigForScene(config_, name));
      ASSERT_TRUE(scene.ok()) << name << ": " << scene.status();
      scenes_.push_back(std::move(scene).value());
      hosted.push_back(scenes_.back().get());
    }
    server_ = std::make_unique<Server>(io_, config_, hosted);
    auto port = server_->Start();
    ASSERT_TRUE(port.ok()) << port.status();
    port_ = *port;
    HttpConfig hc;
    hc.listen = "127.0.0.1:0";
    hc.web_root = dir_;
    http_ = std::make_unique<HttpServer>(io_, hc, *server_);
    ASSERT_TRUE(http_->Start().ok());
    guard_.emplace(io_.get_executor());
    for (int i = 0; i < 2; ++i) threads_.emplace_back([this] { io_.run(); });
  }
  // Stops listening and snapshots every scene as sculptd's SIGTERM does.
  void Stop() {
    if (server_) server_->Stop();
    if (http_) http_->Stop();
    for (auto& s : scenes_) s->FlushAndSnapshot();
    guard_.reset();
    io_.stop();
    for (auto& t : threads_) t.join();
    threads_.clear();
    io_.restart();
    io_.poll();
    http_.reset();
    server_.reset();
    scenes_.clear();
    io_.restart();
  }
  Scene& SceneNamed(const std::string& name) {
    Scene* s = server_->FindScene(name);
    EXPECT_NE(s, nullptr) << name;
    return *s;
  }
  std::unique_ptr<RawClient> Entered(const std::string& scene, v1::Role role = v1::ROLE_SCULPTOR) {
    auto c = std::make_unique<RawClient>(port_);
    EXPECT_TRUE(c->Enter(role == v1::ROLE_SCULPTOR ? kSculptor : kViewer, role,
                         RawClient::kAutoId, JoinOf(scene)))
        << scene;
    return c;
  }
  // A Hello answered by its Welcome, then a join of `scene`: the first Error or SceneInfo.
  std::optional<v1::ServerMessage> TryJoin(RawClient& c, const std::string& scene,
                                           v1::Role role = v1::ROLE_SCULPTOR) {
    if (!c.Hello(role == v1::ROLE_SCULPTOR ? kSculptor : kViewer, role)) return std::nullopt;
    if (!c.ReadUntil(v1::ServerMessage::kWelcome)) return std::nullopt;
    c.Join(JoinOf(scene));
    for (;;) {
      auto m = c.Read();
      if (!m || m->has_error() || m->has_scene_info()) return m;
    }
  }
  // Each raw press stroke is this many poses, and each pose is an edit of the scene's sequence.
  static constexpr uint64_t kPoses = 4;

  // Sends `n` strokes and waits for their acks.
  static void Sculpt(RawClient& c, int n) {
    for (int i = 1; i <= n; ++i) {
      ASSERT_TRUE(c.Send(RawClient::PressStroke(i, {0, 0, 12.3}, kPoses)));
      ASSERT_TRUE(c.ReadUntil(v1::ServerMessage::kAck)) << "stroke " << i;
    }
  }
  // The next presence broadcast `c` gets: the session ids it lists.
  static std::set<uint64_t> NextPresence(RawClient& c) {
    auto m = c.ReadUntil(v1::ServerMessage::kPresence);
    std::set<uint64_t> ids;
    if (!m) return ids;
    for (const auto& u : m->presence().users()) ids.insert(u.session_id());
    return ids;
  }

  fs::path dir_;
  ServerConfig config_;
  asio::io_context io_;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> guard_;
  std::vector<std::thread> threads_;
  std::vector<std::unique_ptr<Scene>> scenes_;
  std::unique_ptr<Server> server_;
  std::unique_ptr<HttpServer> http_;
  uint16_t port_ = 0;
};

TEST_F(MultiSceneTest, WelcomeListsEveryHostedSceneAndAnEmptyJoinTakesTheFirst) {
  config_.scene.also = {"b", "c"};
  Start();
  ASSERT_EQ(server_->scenes().size(), 3u);
  EXPECT_EQ(&server_->scene(), server_->scenes().front());
  EXPECT_EQ(server_->FindScene("nope"), nullptr);
  RawClient c(port_);
  ASSERT_TRUE(c.Hello(kViewer, v1::ROLE_VIEWER));
  auto w = c.ReadUntil(v1::ServerMessage::kWelcome);
  ASSERT_TRUE(w);
  ASSERT_EQ(w->welcome().scenes_size(), 3);
  EXPECT_EQ(w->welcome().scenes(0), "a");
  EXPECT_EQ(w->welcome().scenes(1), "b");
  EXPECT_EQ(w->welcome().scenes(2), "c");
  c.Join();
  auto info = c.ReadUntil(v1::ServerMessage::kSceneInfo);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->scene_info().scene(), "a");
  auto in_c = Entered("c", v1::ROLE_VIEWER);
  EXPECT_EQ(in_c->info().scene(), "c");
}

TEST_F(MultiSceneTest, StrokesToOneSceneChangeItsSequenceAndHashAndNotTheOthers) {
  Start();
  Scene& a = SceneNamed("a");
  Scene& b = SceneNamed("b");
  const uint64_t a_hash = a.StateHash("clay");
  const uint64_t b_hash = b.StateHash("clay");
  ASSERT_EQ(a_hash, b_hash);  // the same [scene] settings build the same first state
  auto in_b = Entered("b");
  EXPECT_EQ(in_b->info().scene(), "b");
  Sculpt(*in_b, 3);
  EXPECT_EQ(b.global_seq(), 3 * kPoses);
  EXPECT_EQ(a.global_seq(), 0u);
  EXPECT_NE(b.StateHash("clay"), b_hash);
  EXPECT_EQ(a.StateHash("clay"), a_hash);
  // And the other way round: a's edits leave b where it was.
  const uint64_t b_after = b.StateHash("clay");
  auto in_a = Entered("a");
  Sculpt(*in_a, 2);
  EXPECT_EQ(a.global_seq(), 2 * kPoses);
  EXPECT_EQ(b.global_seq(), 3 * kPoses);
  EXPECT_EQ(b.StateHash("clay"), b_after);
  // A late joiner of b gets b's sequence in its SceneInfo.
  auto late = Entered("b", v1::ROLE_VIEWER);
  EXPECT_EQ(late->info().global_seq(), 3 * kPoses);
}

TEST_F(MultiSceneTest, PresenceListsOnlyTheSessionsOfTheSameScene) {
  config_.presence_hz = 50;
  Start();
  RawClient a1(port_), b1(port_), b2(port_);
  std::vector<uint64_t> ids;
  for (auto [c, scene] : {std::pair{&a1, "a"}, std::pair{&b1, "b"}, std::pair{&b2, "b"}}) {
    ASSERT_TRUE(c->Hello(kViewer, v1::ROLE_VIEWER));
    auto w = c->ReadUntil(v1::ServerMessage::kWelcome);
    ASSERT_TRUE(w);
    ids.push_back(w->welcome().session_id());
    c->Join(JoinOf(scene));
    ASSERT_TRUE(c->ReadUntil(v1::ServerMessage::kSceneInfo));
  }
  // b's two sessions see each other and not a's; a alone gets no presence at all.
  const std::set<uint64_t> b_ids{ids[1], ids[2]};
  EXPECT_EQ(NextPresence(b1), b_ids);
  EXPECT_EQ(NextPresence(b2), b_ids);
  // A second session in a: a's broadcast names a's two, b's still b's two. The first presence a1
  // ever reads is a's (alone in a it got none, and b's broadcasts never reach it).
  RawClient a2(port_);
  ASSERT_TRUE(a2.Hello(kViewer, v1::ROLE_VIEWER));
  auto w = a2.ReadUntil(v1::ServerMessage::kWelcome);
  ASSERT_TRUE(w);
  a2.Join(JoinOf("a"));
  ASSERT_TRUE(a2.ReadUntil(v1::ServerMessage::kSceneInfo));
  const std::set<uint64_t> a_ids{ids[0], w->welcome().session_id()};
  EXPECT_EQ(NextPresence(a1), a_ids);
  EXPECT_EQ(NextPresence(a2), a_ids);
  EXPECT_EQ(NextPresence(b1), b_ids);
}

TEST_F(MultiSceneTest, RefusesAnUnknownSceneNamingTheHostedOnes) {
  config_.scene.also = {"b", "c"};
  Start();
  RawClient c(port_);
  auto m = TryJoin(c, "d");
  ASSERT_TRUE(m && m->has_error());
  EXPECT_EQ(m->error().code(), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(m->error().field(), "JoinScene.scene");
  EXPECT_EQ(m->error().value(), "d");
  EXPECT_EQ(m->error().allowed_range(), "{a, b, c}");
  // Not joined: the session may still join a hosted scene.
  c.Join(JoinOf("c"));
  auto info = c.ReadUntil(v1::ServerMessage::kSceneInfo);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->scene_info().scene(), "c");
}

TEST_F(MultiSceneTest, AJoinedSessionCannotJoinAgainNorMoveToAnotherScene) {
  Start();
  auto c = Entered("a");
  for (const char* scene : {"a", "b", ""}) {
    c->Join(JoinOf(scene));
    auto e = c->ReadUntil(v1::ServerMessage::kError);
    ASSERT_TRUE(e) << scene;
    EXPECT_EQ(e->error().code(), v1::ERROR_CODE_FAILED_PRECONDITION) << scene;
    EXPECT_EQ(e->error().field(), "JoinScene") << scene;
    EXPECT_EQ(e->error().value(), "repeated") << scene;
  }
  // Its strokes still go to a.
  Sculpt(*c, 1);
  EXPECT_EQ(SceneNamed("a").global_seq(), kPoses);
  EXPECT_EQ(SceneNamed("b").global_seq(), 0u);
}

TEST_F(MultiSceneTest, SeatsAreCountedPerScene) {
  config_.limits.max_clients_per_scene = 2;
  config_.limits.reserved_sculptor_seats = 0;
  Start();
  auto a1 = Entered("a");
  auto a2 = Entered("a");
  EXPECT_EQ(server_->JoinedSeats(SceneNamed("a")).joined, 2u);
  EXPECT_EQ(server_->JoinedSeats(SceneNamed("b")).joined, 0u);
  RawClient a3(port_);
  auto refused = TryJoin(a3, "a");
  ASSERT_TRUE(refused && refused->has_error());
  EXPECT_EQ(refused->error().code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(refused->error().field(), "clients");
  EXPECT_EQ(refused->error().value(), "2");
  // a full leaves b's seats free: two join b, and the third is refused there too.
  auto b1 = Entered("b", v1::ROLE_VIEWER);
  auto b2 = Entered("b");
  EXPECT_EQ(server_->JoinedSeats(SceneNamed("b")).joined, 2u);
  EXPECT_EQ(server_->JoinedSeats(SceneNamed("b")).viewers, 1u);
  const Server::Seats all = server_->JoinedSeats();
  EXPECT_EQ(all.joined, 4u);
  EXPECT_EQ(all.viewers, 1u);
  RawClient b3(port_);
  refused = TryJoin(b3, "b");
  ASSERT_TRUE(refused && refused->has_error());
  EXPECT_EQ(refused->error().field(), "clients");
}

TEST_F(MultiSceneTest, RestartRecoversEverySceneFromItsOwnDataDirectory) {
  Start();
  {
    auto in_a = Entered("a");
    Sculpt(*in_a, 2);
    auto in_b = Entered("b");
    Sculpt(*in_b, 5);
  }
  const uint64_t a_hash = SceneNamed("a").StateHash("clay");
  const uint64_t b_hash = SceneNamed("b").StateHash("clay");
  Stop();
  // scene.name keeps the data directory itself; the others live under scenes/NAME.
  EXPECT_EQ(SceneDataDir(config_, "a"), config_.data_dir);
  EXPECT_EQ(fs::path(SceneDataDir(config_, "b")), fs::path(config_.data_dir) / "scenes" / "b");
  EXPECT_TRUE(fs::is_directory(fs::path(config_.data_dir) / "scenes" / "b" / "log"));
  EXPECT_FALSE(fs::exists(fs::path(config_.data_dir) / "scenes" / "a"));
  Start();
  EXPECT_EQ(SceneNamed("a").global_seq(), 2 * kPoses);
  EXPECT_EQ(SceneNamed("b").global_seq(), 5 * kPoses);
  EXPECT_EQ(SceneNamed("a").StateHash("clay"), a_hash);
  EXPECT_EQ(SceneNamed("b").StateHash("clay"), b_hash);
  // A process started with scene.name alone finds a's edits where a single-scene sculptd would.
  Stop();
  config_.scene.also.clear();
  Start();
  EXPECT_EQ(server_->scenes().size(), 1u);
  EXPECT_EQ(server_->scene().global_seq(), 2 * kPoses);
}

TEST_F(MultiSceneTest, MetricsLabelEachScenesFiguresAndReadinessChecksEveryLog) {
  Start();
  auto in_b = Entered("b");
  Sculpt(*in_b, 3);
  sculpt::testing::PromPage page;
  std::string error;
  const std::string text = http_->MetricsText();
  ASSERT_TRUE(sculpt::testing::ParsePrometheusText(text, &page, &error)) << error << "\n" << text;
  EXPECT_EQ(page.Value("sculpt_edits_total", {{"scene", "a"}}), 0);
  EXPECT_EQ(page.Value("sculpt_edits_total", {{"scene", "b"}}), 3 * kPoses);
  EXPECT_TRUE(std::isnan(page.Value("sculpt_edits_total")));  // no unlabelled sample beside them
  EXPECT_EQ(page.Value("sculpt_compute_queue_depth", {{"scene", "a"}}), 0);
  EXPECT_EQ(page.Value("sculpt_log_fsync_seconds_count", {{"scene", "a"}}), 0);
  EXPECT_GE(page.Value("sculpt_log_fsync_seconds_count", {{"scene", "b"}}), 1);
  EXPECT_EQ(page.Value("sculpt_replication_bytes_total", {{"scene", "b"}, {"kind", "broadcast"}}),
            0);
  // Process-wide figures stay unlabelled.
  EXPECT_EQ(page.Value("sculpt_strokes_accepted_total"), 3);
  EXPECT_TRUE(http_->Readiness().ok()) << http_->Readiness();
  // b's log directory gone (a lost volume) makes the process not ready, naming it.
  const fs::path b_log = fs::path(SceneDataDir(config_, "b")) / "log";
  fs::rename(b_log, b_log.string() + ".away");
  const Status ready = http_->Readiness();
  fs::rename(b_log.string() + ".away", b_log);
  EXPECT_FALSE(ready.ok());
  EXPECT_NE(ready.message().find(b_log.string()), std::string::npos) << ready;
}

}  // namespace
}  // namespace sculpt::server
