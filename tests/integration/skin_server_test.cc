/// @brief Ball skins on the real server in-process (issue 6): two sculptors edit one skin's
/// balls, a contour subscriber's decoded skin equals the server's within the quantisation step,
/// a ball move re-sends only the changed sections, bad ball fields are refused with field, value
/// and range while the others keep being served, a slice follows the sculpture, and a sweep
/// changes the volume by about the outline's area x depth and survives a restart, and ball edits
/// survive restarts (replayed from the log, or from the skin saved at a snapshot) while resent
/// edits are applied once.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "config/server_config.h"
#include "net/server.h"
#include "net/wire_info.h"
#include "scene/scene.h"
#include "sculpt/client/client.h"
#include "sculpt/client/skin_client.h"
#include "sculpt/skin/contour_codec.h"

namespace sculpt::client {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr char kSkin[] = "chain";
constexpr double kPlaneZ = 30;  // above the default sphere (radius 24): a sweep there is disjoint

double Area(const skin::Polyline2& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) a += p[i].Cross(p[(i + 1) % p.size()]);
  return 0.5 * std::abs(a);
}

// A slice through the sphere's equator (the plane z = 0), every half unit.
v1::ContourSlice EquatorSlice() {
  v1::ContourSlice slice;
  slice.set_object("clay");
  slice.mutable_u()->set_x(1);
  slice.mutable_v()->set_y(1);
  slice.set_half_extent(30);
  slice.set_step(0.5);
  return slice;
}

class SkinServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_skin_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    config_.data_dir = (dir_ / "data").string();
    config_.listen = "127.0.0.1:0";
    server::SkinConfig skin;
    skin.name = kSkin;
    skin.origin = {0, 0, kPlaneZ};
    skin.chord_tolerance = 0.02;
    skin.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
    config_.scene.skins = {skin};
    config_.scene.effects.contours = true;
    StartServer();
  }

  void StartServer() {
    auto scene = server::Scene::Open(config_);
    ASSERT_TRUE(scene.ok()) << scene.status();
    scene_ = std::move(scene).value();
    io_ = std::make_unique<server::asio::io_context>();
    server_ = std::make_unique<server::Server>(*io_, config_, *scene_);
    auto port = server_->Start();
    ASSERT_TRUE(port.ok()) << port.status();
    port_ = *port;
    io_thread_ = std::thread([this] { io_->run(); });
  }

  void StopServer() {
    if (server_) server_->Stop();
    if (io_) io_->stop();
    if (io_thread_.joinable()) io_thread_.join();
    server_.reset();
    scene_.reset();
    io_.reset();
  }

  void TearDown() override {
    StopServer();
    fs::remove_all(dir_);
  }

  std::unique_ptr<Client> Joined(v1::Role role = v1::ROLE_SCULPTOR) {
    ClientOptions options;
    options.timeout = seconds(10);
    auto c = std::make_unique<Client>(options);
    EXPECT_TRUE(c->Connect("127.0.0.1", port_).ok());
    auto w = c->Hello(role == v1::ROLE_SCULPTOR ? "sculpt-dev-sculptor" : "sculpt-dev-viewer",
                      role, "t", 0);
    EXPECT_TRUE(w.ok()) << w.status();
    auto j = c->Join();
    EXPECT_TRUE(j.ok()) << j.status();
    return c;
  }

  v1::SkinAck Ack(SkinClient& sc, StatusOr<uint64_t> seq) {
    EXPECT_TRUE(seq.ok()) << seq.status();
    auto a = sc.WaitAck(*seq, seconds(10));
    EXPECT_TRUE(a.ok()) << a.status();
    return a.ok() ? *a : v1::SkinAck{};
  }

  // Every section of the view matches the server's skin point for point within the codec's
  // bound, step / sqrt(2).
  void ExpectViewMatches(const skin::ContourView& view) {
    auto server_skin = scene_->SkinCopy(kSkin);
    ASSERT_TRUE(server_skin.ok()) << server_skin.status();
    const auto& sections = server_skin->sections();
    ASSERT_EQ(view.sections().size(), sections.size());
    const double bound = std::sqrt(0.5) * view.step() * (1 + 1e-9);
    EXPECT_LE(view.step(), server_skin->chord_tolerance());
    for (size_t k = 0; k < sections.size(); ++k) {
      EXPECT_EQ(view.sections()[k].id, sections[k].id) << "section " << k;
      EXPECT_EQ(view.sections()[k].version, sections[k].version) << "section " << k;
      const skin::Polyline2* mine[2] = {&view.sections()[k].plus, &view.sections()[k].minus};
      const skin::Polyline2* theirs[2] = {&sections[k].plus, &sections[k].minus};
      for (int s = 0; s < 2; ++s) {
        ASSERT_EQ(mine[s]->size(), theirs[s]->size()) << "section " << k << " side " << s;
        for (size_t i = 0; i < mine[s]->size(); ++i) {
          ASSERT_LE(((*mine[s])[i] - (*theirs[s])[i]).Length(), bound);
        }
      }
    }
  }

  // The chain each ContourUpdate carries is the server's, ball for ball.
  void ExpectBallsMatch(const std::vector<skin::OrientedBall>& balls) {
    auto server_skin = scene_->SkinCopy(kSkin);
    ASSERT_TRUE(server_skin.ok()) << server_skin.status();
    ASSERT_EQ(balls.size(), server_skin->balls().size());
    for (size_t i = 0; i < balls.size(); ++i) {
      EXPECT_EQ(balls[i].c.x, server_skin->balls()[i].c.x) << "ball " << i;
      EXPECT_EQ(balls[i].c.y, server_skin->balls()[i].c.y) << "ball " << i;
      EXPECT_EQ(balls[i].r, server_skin->balls()[i].r) << "ball " << i;
      EXPECT_EQ(balls[i].theta, server_skin->balls()[i].theta) << "ball " << i;
    }
  }

  fs::path dir_;
  server::ServerConfig config_;
  std::unique_ptr<server::asio::io_context> io_;
  std::unique_ptr<server::Scene> scene_;
  std::unique_ptr<server::Server> server_;
  std::thread io_thread_;
  uint16_t port_ = 0;
};

/// The sections an edit rebuilds past `last` (the last of its own): with the codec's sampler
/// (the default) those up to the next codec restart (Skin::CodecRestart), a function of the
/// balls after the edit.
size_t Followers(const std::vector<skin::OrientedBall>& balls, size_t last) {
  auto s = skin::Skin::Build(balls);
  if (!s.ok()) return 0;
  size_t n = 0;
  for (size_t k = last + 1; k + 1 < balls.size() && !s->CodecRestart(k); ++k) ++n;
  return n;
}

TEST_F(SkinServerTest, TwoSculptorsEditOneSkinAndASubscriberFollowsOnlyChangedSections) {
  auto viewer = Joined(v1::ROLE_VIEWER);
  SkinClient follower(*viewer);
  ASSERT_TRUE(follower.FollowSkin(kSkin).ok());
  ASSERT_TRUE(follower.WaitSkinVersion(kSkin, 0, seconds(10)));
  ExpectViewMatches(follower.View(kSkin));
  ExpectBallsMatch(follower.Balls(kSkin));
  ASSERT_EQ(follower.UpdateSections(kSkin).size(), 1u);
  EXPECT_EQ(follower.UpdateSections(kSkin)[0], 4u);  // the snapshot: every section

  auto a = Joined();
  auto b = Joined();
  SkinClient sa(*a), sb(*b);
  // A moves a middle ball: its two sections (and those up to the next codec restart), nothing
  // else, are rebuilt and re-sent.
  const v1::SkinAck move = Ack(sa, sa.MoveBall(kSkin, 2, {0.5, 1.0}, 3.2));
  ASSERT_TRUE(move.accepted()) << move.error().message();
  ASSERT_TRUE(follower.WaitSkinVersion(kSkin, 1, seconds(10)));
  EXPECT_EQ(move.changed_sections(), 2u + Followers(follower.Balls(kSkin), 2));
  EXPECT_EQ(follower.UpdateSections(kSkin).back(), move.changed_sections());
  ExpectViewMatches(follower.View(kSkin));
  ExpectBallsMatch(follower.Balls(kSkin));
  EXPECT_EQ(follower.Balls(kSkin)[2].c.y, 1.0);

  // B re-orients the end ball: one section.
  const v1::SkinAck orient = Ack(sb, sb.OrientBall(kSkin, 4, 0.3));
  ASSERT_TRUE(orient.accepted()) << orient.error().message();
  EXPECT_EQ(orient.changed_sections(), 1u);
  ASSERT_TRUE(follower.WaitSkinVersion(kSkin, 2, seconds(10)));
  EXPECT_EQ(follower.UpdateSections(kSkin).back(), 1u);

  // B appends a ball and A removes one: the splice reaches the subscriber too.
  const v1::SkinAck add = Ack(sb, sb.AddBall(kSkin, 5, {{18, 0}, 2.5, 0}));
  ASSERT_TRUE(add.accepted()) << add.error().message();
  EXPECT_EQ(add.balls(), 6u);
  const v1::SkinAck remove = Ack(sa, sa.RemoveBall(kSkin, 1));
  ASSERT_TRUE(remove.accepted()) << remove.error().message();
  EXPECT_EQ(remove.balls(), 5u);
  ASSERT_TRUE(follower.WaitSkinVersion(kSkin, 4, seconds(10)));
  ASSERT_EQ(follower.UpdateSections(kSkin).size(), 5u);
  EXPECT_EQ(follower.UpdateSections(kSkin)[3], 1u);  // the appended ball's section, the last
  // The removal joins balls 0 and 2 into section 0, then its followers.
  EXPECT_EQ(follower.UpdateSections(kSkin)[4], 1u + Followers(follower.Balls(kSkin), 0));
  ExpectViewMatches(follower.View(kSkin));
  ExpectBallsMatch(follower.Balls(kSkin));
  EXPECT_EQ(follower.Balls(kSkin).size(), 5u);
  EXPECT_EQ(follower.decode_errors(), 0u);
  // The thin client's contours are far smaller than the float32 points they stand for.
  size_t points = 0;
  const skin::ContourView view = follower.View(kSkin);
  for (const auto& s : view.sections()) points += s.plus.size() + s.minus.size();
  EXPECT_GT(points, 0u);
}

TEST_F(SkinServerTest, SceneInfoListsTheSkinsWithTheirPlanes) {
  ClientOptions options;
  options.timeout = seconds(10);
  Client c(options);
  ASSERT_TRUE(c.Connect("127.0.0.1", port_).ok());
  ASSERT_TRUE(c.Hello("sculpt-dev-viewer", v1::ROLE_VIEWER, "t", 0).ok());
  auto j = c.Join();
  ASSERT_TRUE(j.ok()) << j.status();
  ASSERT_EQ(j->info.skins_size(), 1);
  const v1::SkinInfo& k = j->info.skins(0);
  EXPECT_EQ(k.name(), kSkin);
  EXPECT_EQ(k.origin().z(), static_cast<float>(kPlaneZ));
  EXPECT_EQ(k.u().x(), 1.f);
  EXPECT_EQ(k.v().y(), 1.f);
  EXPECT_TRUE(j->info.effects().contours());
}

TEST_F(SkinServerTest, RejectsBadBallFieldsAndKeepsServing) {
  auto viewer = Joined(v1::ROLE_VIEWER);
  SkinClient follower(*viewer);
  ASSERT_TRUE(follower.FollowSkin(kSkin).ok());
  ASSERT_TRUE(follower.WaitSkinVersion(kSkin, 0, seconds(10)));
  auto a = Joined();
  SkinClient sa(*a);

  const v1::SkinAck nan = Ack(sa, sa.MoveBall(kSkin, 1, {std::nan(""), 0}, 2));
  EXPECT_FALSE(nan.accepted());
  EXPECT_EQ(nan.error().code(), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(nan.error().field(), "SkinBallEdit.ball.x");
  EXPECT_EQ(nan.error().value(), "nan");
  EXPECT_EQ(nan.error().allowed_range(), "finite numbers");

  const v1::SkinAck radius = Ack(sa, sa.MoveBall(kSkin, 1, {-6, 1}, -1));
  EXPECT_FALSE(radius.accepted());
  EXPECT_EQ(radius.error().field(), "SkinBallEdit.ball.r");
  EXPECT_EQ(radius.error().value(), "-1");
  EXPECT_EQ(radius.error().allowed_range(), "[0.001, 1e+06]");

  const v1::SkinAck far = Ack(sa, sa.MoveBall(kSkin, 1, {5e6, 0}, 2));
  EXPECT_FALSE(far.accepted());
  EXPECT_EQ(far.error().field(), "SkinBallEdit.ball.x");
  EXPECT_EQ(far.error().allowed_range(), "[-1e+06, 1e+06]");

  const v1::SkinAck index = Ack(sa, sa.OrientBall(kSkin, 9, 0));
  EXPECT_FALSE(index.accepted());
  EXPECT_EQ(index.error().field(), "SkinBallEdit.index");
  EXPECT_EQ(index.error().value(), "9");
  EXPECT_EQ(index.error().allowed_range(), "[0, 4]");

  // Ball 1 moved inside ball 0 (nested): the pair is not admissible.
  const v1::SkinAck nested = Ack(sa, sa.MoveBall(kSkin, 1, {-11.5, 0.2}, 1));
  EXPECT_FALSE(nested.accepted());
  EXPECT_EQ(nested.error().field(), "SkinBallEdit.ball");
  EXPECT_NE(nested.error().value().find("index 1"), std::string::npos) << nested.error().value();
  EXPECT_NE(nested.error().allowed_range().find("admissible"), std::string::npos);
  EXPECT_NE(nested.error().message().find("inside"), std::string::npos)
      << nested.error().message();

  const v1::SkinAck unknown = Ack(sa, sa.OrientBall("nope", 0, 0));
  EXPECT_EQ(unknown.error().code(), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(unknown.error().field(), "SkinBallEdit.skin");

  // Viewers may not edit.
  v1::SkinBallEdit e;
  e.set_skin(kSkin);
  e.set_op(v1::SKIN_BALL_OP_ORIENT);
  e.set_index(0);
  ASSERT_TRUE(follower.SendEdit(e).ok());
  bool denied = false;
  for (int i = 0; i < 50 && !denied; ++i) {
    auto ev = viewer->NextEvent(milliseconds(200));
    denied = ev && ev->type == Event::Type::kError &&
             ev->error.code() == v1::ERROR_CODE_PERMISSION_DENIED;
  }
  EXPECT_TRUE(denied);

  // Nothing refused reached the skin; a good edit is still served and followed.
  EXPECT_EQ(follower.UpdateSections(kSkin).size(), 1u);
  const v1::SkinAck ok = Ack(sa, sa.MoveBall(kSkin, 1, {-6, 1.5}, 2.5));
  ASSERT_TRUE(ok.accepted()) << ok.error().message();
  ASSERT_TRUE(follower.WaitSkinVersion(kSkin, 1, seconds(10)));
  ExpectViewMatches(follower.View(kSkin));
}

// A scene that does not ask for contours computes none: subscriptions to a skin or a slice are
// refused naming the setting, and SceneInfo says so.
TEST_F(SkinServerTest, SceneWithoutContoursRefusesContourAndSliceSubscriptions) {
  StopServer();
  config_.scene.effects.contours = false;
  StartServer();
  auto viewer = Joined(v1::ROLE_VIEWER);
  EXPECT_FALSE(server::ToWireSceneInfo(scene_->Info()).effects().contours());
  SkinClient follower(*viewer);
  ASSERT_TRUE(follower.FollowSkin(kSkin).ok());
  v1::ContourSlice slice = EquatorSlice();
  ASSERT_TRUE(follower.FollowSlice(slice).ok());
  int refused = 0;
  for (int i = 0; i < 15 && refused < 2; ++i) {
    auto ev = viewer->NextEvent(milliseconds(200));
    if (!ev) continue;
    if (ev->type == Event::Type::kError && ev->error.field() == "scene.effects.contours" &&
        ev->error.value() == "false" && ev->error.code() == v1::ERROR_CODE_FAILED_PRECONDITION) {
      ++refused;
    }
  }
  EXPECT_EQ(refused, 2);
  EXPECT_FALSE(follower.WaitSlice("clay", 0, milliseconds(300)));
}

TEST_F(SkinServerTest, SliceFollowsTheSculpture) {
  auto viewer = Joined(v1::ROLE_VIEWER);
  SkinClient follower(*viewer);
  v1::ContourSlice slice = EquatorSlice();
  ASSERT_TRUE(follower.FollowSlice(slice).ok());
  ASSERT_TRUE(follower.WaitSlice("clay", 0, seconds(10)));
  const auto lines = follower.Slice("clay");
  ASSERT_EQ(lines.size(), 1u);  // the equator of the sphere: one closed loop
  EXPECT_EQ(lines[0].front(), lines[0].back());
  for (const skin::Vec2& p : lines[0]) EXPECT_NEAR(p.Length(), 24.0, 0.25);

  // A bad slice is refused with field, value and range.
  slice.mutable_v()->set_x(1);
  ASSERT_TRUE(follower.FollowSlice(slice).ok());
  bool refused = false;
  for (int i = 0; i < 50 && !refused; ++i) {
    auto ev = viewer->NextEvent(milliseconds(200));
    refused = ev && ev->type == Event::Type::kError &&
              ev->error.field() == "ContourSubscribe.slice.v";
  }
  EXPECT_TRUE(refused);
}

TEST_F(SkinServerTest, SweepAddsAreaTimesDepthAndSurvivesRestart) {
  auto a = Joined();
  SkinClient sa(*a);
  auto server_skin = scene_->SkinCopy(kSkin);
  ASSERT_TRUE(server_skin.ok());
  const double area = Area(server_skin->Outline());
  const double volume_before = server::ToWireSceneInfo(scene_->Info()).objects(0).volume();
  constexpr double kDepth = 4;

  v1::SkinSweep sweep;
  sweep.set_skin(kSkin);
  sweep.set_object("clay");
  sweep.set_mode(v1::SKIN_SWEEP_MODE_EXTRUDE);
  sweep.set_kind(v1::EDIT_KIND_ADD);
  sweep.set_depth(kDepth);
  const v1::SkinAck ack = Ack(sa, sa.Sweep(sweep));
  ASSERT_TRUE(ack.accepted()) << ack.error().message();
  EXPECT_GT(ack.global_seq(), 0u);
  const double added = ack.volume_after() - volume_before;
  // The prism's volume within 3% (voxel 0.5, smoothed Heaviside at the sharp rims).
  EXPECT_NEAR(added, area * kDepth, 0.03 * area * kDepth) << "outline area " << area;
  RecordProperty("outline_area", std::to_string(area));
  RecordProperty("added_volume", std::to_string(added));

  // A refused sweep names its field.
  sweep.set_depth(-1);
  const v1::SkinAck bad = Ack(sa, sa.Sweep(sweep));
  EXPECT_FALSE(bad.accepted());
  EXPECT_EQ(bad.error().field(), "SkinSweep.depth");

  const uint64_t hash = scene_->StateHash("clay");
  const double volume = server::ToWireSceneInfo(scene_->Info()).objects(0).volume();
  a->Close();
  StopServer();
  StartServer();  // recovery replays the logged sweep
  EXPECT_EQ(scene_->StateHash("clay"), hash);
  EXPECT_NEAR(server::ToWireSceneInfo(scene_->Info()).objects(0).volume(), volume, 1e-6 * volume);
}

// The same sections (count, ids when `ids`) with the same decoded points, point for point.
void ExpectSameContours(const skin::ContourView& a, const skin::ContourView& b, bool ids) {
  ASSERT_EQ(a.sections().size(), b.sections().size());
  for (size_t k = 0; k < a.sections().size(); ++k) {
    if (ids) {
      EXPECT_EQ(a.sections()[k].id, b.sections()[k].id) << "section " << k;
      EXPECT_EQ(a.sections()[k].version, b.sections()[k].version) << "section " << k;
    }
    const skin::Polyline2* pa[2] = {&a.sections()[k].plus, &a.sections()[k].minus};
    const skin::Polyline2* pb[2] = {&b.sections()[k].plus, &b.sections()[k].minus};
    for (int s = 0; s < 2; ++s) {
      ASSERT_EQ(pa[s]->size(), pb[s]->size()) << "section " << k << " side " << s;
      for (size_t i = 0; i < pa[s]->size(); ++i) {
        EXPECT_EQ((*pa[s])[i].x, (*pb[s])[i].x) << "section " << k << " point " << i;
        EXPECT_EQ((*pa[s])[i].y, (*pb[s])[i].y) << "section " << k << " point " << i;
      }
    }
  }
}

TEST_F(SkinServerTest, BallEditsSurviveRestartsAndResendsApplyOnce) {
  auto a = Joined();
  auto b = Joined();
  SkinClient sa(*a), sb(*b);
  ASSERT_TRUE(Ack(sa, sa.MoveBall(kSkin, 2, {0.5, 1.0}, 3.2)).accepted());
  ASSERT_TRUE(Ack(sb, sb.OrientBall(kSkin, 4, 0.3)).accepted());
  const StatusOr<uint64_t> add_seq = sb.AddBall(kSkin, 5, {{18, 0}, 2.5, 0});
  const v1::SkinAck add = Ack(sb, add_seq);
  ASSERT_TRUE(add.accepted()) << add.error().message();
  EXPECT_GT(add.global_seq(), 0u);  // logged
  EXPECT_FALSE(add.duplicate());
  ASSERT_TRUE(Ack(sa, sa.RemoveBall(kSkin, 1)).accepted());
  ASSERT_EQ(scene_->SkinCopy(kSkin)->balls().size(), 5u);

  // B resends its add (same client_seq): acknowledged as a duplicate, not applied again.
  v1::ClientMessage resend;
  v1::SkinBallEdit* e = resend.mutable_skin_ball_edit();
  e->set_client_seq(*add_seq);
  e->set_skin(kSkin);
  e->set_op(v1::SKIN_BALL_OP_ADD);
  e->set_index(5);
  e->mutable_ball()->set_x(24);
  e->mutable_ball()->set_r(2.5);
  ASSERT_TRUE(b->SendMessage(resend).ok());
  // Acks arrive in order: once the next edit's is here, the resend's has replaced the first.
  ASSERT_TRUE(Ack(sb, sb.OrientBall(kSkin, 0, -0.2)).accepted());
  auto dup = sb.WaitAck(*add_seq, seconds(10));
  ASSERT_TRUE(dup.ok()) << dup.status();
  EXPECT_TRUE(dup->accepted());
  EXPECT_TRUE(dup->duplicate());
  EXPECT_EQ(dup->balls(), 5u);
  ASSERT_EQ(scene_->SkinCopy(kSkin)->balls().size(), 5u);

  auto viewer = Joined(v1::ROLE_VIEWER);
  SkinClient before(*viewer);
  ASSERT_TRUE(before.FollowSkin(kSkin).ok());
  ASSERT_TRUE(before.WaitSkinVersion(kSkin, 5, seconds(10)));
  const skin::ContourView view_before = before.View(kSkin);
  const uint64_t b_id = b->client_id();
  a->Close();
  b->Close();
  viewer->Close();

  StopServer();
  StartServer();  // recovery replays the logged ball edits on the scene file's skin
  {
    auto v = Joined(v1::ROLE_VIEWER);
    SkinClient after(*v);
    ASSERT_TRUE(after.FollowSkin(kSkin).ok());
    ASSERT_TRUE(after.WaitSkinVersion(kSkin, 5, seconds(10)));
    ExpectSameContours(after.View(kSkin), view_before, /*ids=*/true);
    ExpectViewMatches(after.View(kSkin));

    // The resend after the restart (B again, by its id) is still recognised.
    ClientOptions options;
    options.timeout = seconds(10);
    Client again(options);
    ASSERT_TRUE(again.Connect("127.0.0.1", port_).ok());
    ASSERT_TRUE(again.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "t", b_id).ok());
    ASSERT_TRUE(again.Join().ok());
    SkinClient sagain(again);
    ASSERT_TRUE(again.SendMessage(resend).ok());
    auto dup2 = sagain.WaitAck(*add_seq, seconds(10));
    ASSERT_TRUE(dup2.ok()) << dup2.status();
    EXPECT_TRUE(dup2->duplicate());
    EXPECT_EQ(scene_->SkinCopy(kSkin)->balls().size(), 5u);
    again.Close();
    v->Close();
  }

  // With a snapshot after every edit the skin is saved beside it and the log past it replayed.
  StopServer();
  config_.snapshot_every_edits = 1;
  StartServer();
  {
    auto c = Joined();
    SkinClient sc(*c);
    ASSERT_TRUE(Ack(sc, sc.MoveBall(kSkin, 0, {-13, 0.5}, 3)).accepted());
    ASSERT_TRUE(Ack(sc, sc.OrientBall(kSkin, 3, 0.1)).accepted());
    EXPECT_TRUE(fs::exists(fs::path(config_.data_dir) / "skins" / (std::string(kSkin) + ".pb")));
    auto v = Joined(v1::ROLE_VIEWER);
    SkinClient f(*v);
    ASSERT_TRUE(f.FollowSkin(kSkin).ok());
    ASSERT_TRUE(f.WaitSkinVersion(kSkin, 7, seconds(10)));
    const skin::ContourView saved_view = f.View(kSkin);
    c->Close();
    v->Close();
    StopServer();
    // The log gone entirely (as segments a snapshot let go): only the saved skin holds the edits.
    fs::remove_all(fs::path(config_.data_dir) / "log");
    config_.snapshot_every_edits = 5000;
    StartServer();
    auto v2 = Joined(v1::ROLE_VIEWER);
    SkinClient f2(*v2);
    ASSERT_TRUE(f2.FollowSkin(kSkin).ok());
    ASSERT_TRUE(f2.WaitSkinVersion(kSkin, 7, seconds(10)));
    // Rebuilt from the saved balls: the same geometry (section ids are the rebuild's own).
    ExpectSameContours(f2.View(kSkin), saved_view, /*ids=*/false);
    ExpectViewMatches(f2.View(kSkin));
    // B's resend is still recognised with no log record left to show it: the file keeps it.
    ClientOptions options;
    options.timeout = seconds(10);
    Client again(options);
    ASSERT_TRUE(again.Connect("127.0.0.1", port_).ok());
    ASSERT_TRUE(again.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "t", b_id).ok());
    ASSERT_TRUE(again.Join().ok());
    SkinClient sagain(again);
    ASSERT_TRUE(again.SendMessage(resend).ok());
    auto dup3 = sagain.WaitAck(*add_seq, seconds(10));
    ASSERT_TRUE(dup3.ok()) << dup3.status();
    EXPECT_TRUE(dup3->duplicate());
    EXPECT_EQ(scene_->SkinCopy(kSkin)->balls().size(), 5u);
    again.Close();
    v2->Close();
  }
}

}  // namespace
}  // namespace sculpt::client
