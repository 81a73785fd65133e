/// @brief Per-user undo of paints, sweeps, ball edits and model intents end to end (issue 15): two
/// sculptors on the real server in-process, over loopback. A's undo takes back A's newest edit
/// as if never made (a fresh server that only got B's edit has the same hashes), B's stays, redo
/// returns the exact state, and a restart after the undo recovers it.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "integration/in_process_server.h"
#include "integration/raw_client.h"
#include "scene/scene.h"
#include "sculpt/client/replica.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/hyperpatch.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"
#include "sculpt/levelset/materials.h"

namespace sculpt::server {
namespace {

using testing_support::InProcessServer;
constexpr uint64_t kA = 501, kB = 502;

v1::Vec3f F(double x, double y, double z) {
  v1::Vec3f v;
  v.set_x(static_cast<float>(x));
  v.set_y(static_cast<float>(y));
  v.set_z(static_cast<float>(z));
  return v;
}

// The scene the tests share: the default sphere "clay" with three materials, a skin "profile"
// and a hyperpatch model object "part" (two glued boxes).
void Configure(InProcessServer& srv) {
  ServerConfig& c = srv.config();
  c.scene.materials = {{"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}};
  SkinConfig skin;
  skin.name = "profile";
  skin.chord_tolerance = 0.02;
  skin.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
  // A bar in the plane z = 8, x in about [11, 29]: swept 4 along +z it grows out of the sphere
  // (radius 24) at +x, where PressArc's strokes at z = 10 press.
  SkinConfig bar;
  bar.name = "bar";
  bar.origin = {0, 0, 8};
  bar.chord_tolerance = 0.02;
  bar.balls = {{14, 0, 3, 0}, {20, 0, 3, 0}, {26, 0, 3, 0}};
  c.scene.skins = {skin, bar};
  auto model =
      hetero::CompositeModel::Create({{"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}});
  ASSERT_TRUE(model.ok()) << model.status();
  hetero::ValidityChecker checker;
  const std::vector<double> clay{1, 0}, gold{0, 1};
  auto a = hetero::LibraryBox({30, 0, 0}, {34, 4, 4}, clay);
  auto b = hetero::LibraryBox({34, 0, 0}, {38, 4, 4}, gold);
  ASSERT_TRUE(a.ok() && b.ok());
  for (const auto* p : {&*a, &*b}) {
    auto r = hetero::AddCellChecked(&*model, &checker, *p, hetero::CellSource::kLibrary);
    ASSERT_TRUE(r.ok() && r->added);
  }
  const std::string path = (srv.dir() / "two_boxes.json").string();
  ASSERT_TRUE(hetero::SaveModel(*model, path, "two boxes").ok());
  ObjectConfig o;
  o.name = "part";
  o.primitive = "model";
  o.model = path;
  c.scene.objects.push_back(o);
}

class UndoKindsClientTest : public ::testing::Test {
 protected:
  void SetUp() override {
    Configure(srv_);
    ASSERT_TRUE(srv_.Start());
    a_.emplace(srv_.port());
    b_.emplace(srv_.port());
    ASSERT_TRUE(a_->Enter(srv_.config().sculptor_token, v1::ROLE_SCULPTOR, kA));
    ASSERT_TRUE(b_->Enter(srv_.config().sculptor_token, v1::ROLE_SCULPTOR, kB));
  }

  static v1::PaintAck Paint(testing::RawClient& c, uint64_t seq, double x, uint32_t material) {
    v1::ClientMessage m;
    v1::PaintEdit* p = m.mutable_paint();
    p->set_client_seq(seq);
    p->set_object("clay");
    p->set_tool(v1::TOOL_KIND_SPHERE);
    *p->mutable_tool_size() = F(3, 0, 0);
    *p->mutable_position() = F(x, 0, 24);
    p->set_material(material);
    p->set_weight(0.75);
    EXPECT_TRUE(c.Send(m));
    auto a = c.ReadUntil(v1::ServerMessage::kPaintAck);
    EXPECT_TRUE(a.has_value());
    return a ? a->paint_ack() : v1::PaintAck{};
  }
  static v1::SkinAck Ball(testing::RawClient& c, uint64_t seq, v1::SkinBallOp op, uint32_t index,
                          double x, double y, double r, double theta) {
    v1::ClientMessage m;
    v1::SkinBallEdit* e = m.mutable_skin_ball_edit();
    e->set_client_seq(seq);
    e->set_skin("profile");
    e->set_op(op);
    e->set_index(index);
    e->mutable_ball()->set_x(x);
    e->mutable_ball()->set_y(y);
    e->mutable_ball()->set_r(r);
    e->mutable_ball()->set_theta(theta);
    EXPECT_TRUE(c.Send(m));
    auto a = c.ReadUntil(v1::ServerMessage::kSkinAck);
    EXPECT_TRUE(a.has_value());
    return a ? a->skin_ack() : v1::SkinAck{};
  }
  static v1::ModelAck Intent(testing::RawClient& c, uint64_t seq, uint32_t corner, Vec3 d) {
    v1::ClientMessage m;
    v1::ModelIntent* i = m.mutable_model_intent();
    i->set_client_seq(seq);
    i->set_object("part");
    i->set_corner(corner);
    for (int k = 0; k < 3; ++k) i->add_offset(0);
    i->set_displacement_x(d.x);
    i->set_displacement_y(d.y);
    i->set_displacement_z(d.z);
    i->set_cell(-1);
    EXPECT_TRUE(c.Send(m));
    auto a = c.ReadUntil(v1::ServerMessage::kModelAck);
    EXPECT_TRUE(a.has_value());
    return a ? a->model_ack() : v1::ModelAck{};
  }
  static v1::UndoAck Undo(testing::RawClient& c, uint64_t seq, const std::string& object,
                          bool redo = false) {
    v1::ClientMessage m;
    m.mutable_undo()->set_client_seq(seq);
    m.mutable_undo()->set_object(object);
    m.mutable_undo()->set_redo(redo);
    EXPECT_TRUE(c.Send(m));
    auto a = c.ReadUntil(v1::ServerMessage::kUndoAck);
    EXPECT_TRUE(a.has_value());
    return a ? a->undo_ack() : v1::UndoAck{};
  }
  static v1::HistoryAnswer History(testing::RawClient& c, const std::string& object) {
    v1::ClientMessage m;
    m.mutable_history()->set_request_id(7);
    m.mutable_history()->set_object(object);
    EXPECT_TRUE(c.Send(m));
    auto a = c.ReadUntil(v1::ServerMessage::kHistory);
    EXPECT_TRUE(a.has_value());
    return a ? a->history() : v1::HistoryAnswer{};
  }

  static std::pair<uint64_t, uint64_t> Hashes(Scene& scene) {
    uint64_t fractions = 0;
    EXPECT_TRUE(scene.Inspect(
        "clay", [&](const levelset::Sculpture& s) { fractions = levelset::MaterialStateHash(s); }));
    return {scene.StateHash("clay"), fractions};
  }
  static std::vector<double> Balls(Scene& scene) {
    std::vector<double> out;
    auto sk = scene.SkinCopy("profile");
    EXPECT_TRUE(sk.ok());
    if (!sk.ok()) return out;
    for (const skin::OrientedBall& b : sk->balls())
      out.insert(out.end(), {b.c.x, b.c.y, b.r, b.theta});
    return out;
  }
  static uint64_t ModelHash(Scene& scene) {
    auto m = scene.ModelInfo("part");
    EXPECT_TRUE(m.ok()) << m.status();
    return m.ok() ? m->hash : 0;
  }
  uint32_t FirstCorner(Scene& scene) {
    auto m = scene.ModelInfo("part");
    EXPECT_TRUE(m.ok());
    auto model = hetero::ModelFromJson(m->json);
    EXPECT_TRUE(model.ok());
    return model->cell(0).coef[static_cast<size_t>(hetero::Hyperpatch::Index(0, 0, 0))];
  }
  uint32_t LastCorner(Scene& scene) {
    auto m = scene.ModelInfo("part");
    auto model = hetero::ModelFromJson(m->json);
    return model->cell(1).coef[static_cast<size_t>(hetero::Hyperpatch::Index(3, 3, 3))];
  }

  InProcessServer srv_{"undo_kinds"};
  std::optional<testing::RawClient> a_, b_;
};

// A paints, B paints overlapping, A undoes: equal to a fresh server that only got B's paint,
// fractions included; redo returns the exact hashes; undo/redo/undo keeps them; a restart after
// the undo recovers the same object.
TEST_F(UndoKindsClientTest, PaintUndoOfTwoSculptorsEqualsAFreshReplayAndSurvivesARestart) {
  ASSERT_TRUE(Paint(*a_, 1, 0, 1).accepted());
  ASSERT_TRUE(Paint(*b_, 1, 2, 1).accepted());
  const auto both = Hashes(srv_.scene());
  const v1::UndoAck u = Undo(*a_, 2, "clay");
  ASSERT_TRUE(u.accepted()) << u.DebugString();
  EXPECT_EQ(u.replayed(), 1u);
  const auto undone = Hashes(srv_.scene());
  EXPECT_NE(undone, both);
  {
    InProcessServer fresh("undo_kinds_fresh");
    Configure(fresh);
    ASSERT_TRUE(fresh.Start());
    testing::RawClient b(fresh.port());
    ASSERT_TRUE(b.Enter(fresh.config().sculptor_token, v1::ROLE_SCULPTOR, kB));
    ASSERT_TRUE(Paint(b, 1, 2, 1).accepted());
    EXPECT_EQ(Hashes(fresh.scene()), undone) << "differs from a server that never had A's paint";
  }
  ASSERT_TRUE(Undo(*a_, 3, "clay", /*redo=*/true).accepted());
  EXPECT_EQ(Hashes(srv_.scene()), both);
  ASSERT_TRUE(Undo(*a_, 4, "clay").accepted());
  EXPECT_EQ(Hashes(srv_.scene()), undone);
  const v1::HistoryAnswer h = History(*b_, "clay");
  ASSERT_EQ(h.entries_size(), 2);
  EXPECT_EQ(h.entries(0).kind_name(), "paint");
  EXPECT_TRUE(h.entries(1).undone());

  a_.reset();
  b_.reset();
  srv_.Stop();
  ASSERT_TRUE(srv_.Start());
  EXPECT_EQ(Hashes(srv_.scene()), undone) << "recovered after the undo";
  testing::RawClient a(srv_.port());
  ASSERT_TRUE(a.Enter(srv_.config().sculptor_token, v1::ROLE_SCULPTOR, kA));
  ASSERT_TRUE(Undo(a, 5, "clay", /*redo=*/true).accepted());
  EXPECT_EQ(Hashes(srv_.scene()), both) << "redo after the restart";
}

// A sweeps the bar into the sphere, B presses across it, A undoes and redoes: replicas get the
// changed leaves of the undo (B's press replayed without the sweep) as for strokes, and a
// replica whose interest box holds only part of the region converges on each.
TEST_F(UndoKindsClientTest, SweepUndoAndRedoConvergeOnAPartialReplica) {
  auto watcher = srv_.Joined(v1::ROLE_VIEWER, /*skip_state=*/true, "watcher");
  ASSERT_TRUE(watcher);
  client::ReplicaOptions part;
  // y >= 8: the replica holds about 8 more around it (down to y = 0), half the bar.
  part.interest = levelset::Aabb{{18, 8, 6}, {30, 14, 14}};
  client::Replica replica(*watcher, part);
  ASSERT_TRUE(replica.Start().ok());
  ASSERT_TRUE(replica.WaitLoaded(1, std::chrono::seconds(20)));
  const levelset::VoxelBox held = replica.held();
  ASSERT_FALSE(held.Empty());
  // Where the bar and the press reach below the held region (y < held.min.y), in voxels.
  const levelset::VoxelBox outside{{held.min.x, held.min.y - 24, held.min.z},
                                   {held.max.x, held.min.y - 1, held.max.z}};
  auto converged = [&](const char* what) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (replica.RegionHash(held) != srv_.scene().RegionHash("clay", held) &&
           std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_EQ(replica.RegionHash(held), srv_.scene().RegionHash("clay", held))
        << "the partial replica did not converge after " << what;
  };

  v1::ClientMessage sweep;
  v1::SkinSweep* w = sweep.mutable_skin_sweep();
  w->set_client_seq(1);
  w->set_skin("bar");
  w->set_object("clay");
  w->set_mode(v1::SKIN_SWEEP_MODE_EXTRUDE);
  w->set_kind(v1::EDIT_KIND_ADD);
  w->set_depth(4);
  ASSERT_TRUE(a_->Send(sweep));
  auto swept = a_->ReadUntil(v1::ServerMessage::kSkinAck);
  ASSERT_TRUE(swept && swept->skin_ack().accepted()) << (swept ? swept->DebugString() : "");
  ASSERT_TRUE(b_->Send(testing::RawClient::PressStroke(1, {20.7, -1, 10}, 4, 2.5)));
  ASSERT_TRUE(b_->ReadUntil(v1::ServerMessage::kAck));
  const uint64_t both = srv_.scene().StateHash("clay");
  const uint64_t inside_both = srv_.scene().RegionHash("clay", held);
  const uint64_t outside_both = srv_.scene().RegionHash("clay", outside);
  converged("the sweep and the press");

  const v1::UndoAck u = Undo(*a_, 2, "clay");
  ASSERT_TRUE(u.accepted()) << u.DebugString();
  EXPECT_EQ(u.target_seq(), swept->skin_ack().global_seq());
  EXPECT_EQ(u.replayed(), 1u) << "B's press, across the bar";
  EXPECT_NE(srv_.scene().RegionHash("clay", held), inside_both) << "the undo missed the box";
  EXPECT_NE(srv_.scene().RegionHash("clay", outside), outside_both)
      << "the undone region does not reach beyond the replica's box (y >= " << held.min.y
      << " voxels): the case is not exercised";
  converged("the undo of the sweep");
  const v1::HistoryAnswer h = History(*b_, "clay");
  ASSERT_EQ(h.entries_size(), 2);
  EXPECT_TRUE(h.entries(1).sweep());
  EXPECT_EQ(h.entries(1).kind_name(), "sweep-add");
  EXPECT_TRUE(h.entries(1).undone());

  ASSERT_TRUE(Undo(*a_, 3, "clay", /*redo=*/true).accepted());
  EXPECT_EQ(srv_.scene().StateHash("clay"), both) << "redo returns the exact state";
  converged("the redo of the sweep");
  EXPECT_EQ(replica.stats().hash_mismatches, 0u);
  EXPECT_EQ(replica.stats().errors, 0u);
  EXPECT_EQ(srv_.scene().replication_stats().divergences.load(), 0u);
}

// A moves a ball, B orients another, A undoes through UndoRequest.object = the skin: B's edit
// stays; redo puts A's back exactly.
TEST_F(UndoKindsClientTest, BallEditUndoAndRedoKeepTheOtherSculptorsEdit) {
  const std::vector<double> initial = Balls(srv_.scene());
  ASSERT_TRUE(Ball(*a_, 1, v1::SKIN_BALL_OP_MOVE, 2, 0.5, 1.5, 3.0, 0).accepted());
  ASSERT_TRUE(Ball(*b_, 1, v1::SKIN_BALL_OP_ORIENT, 3, 0, 0, 0, 0.25).accepted());
  const std::vector<double> both = Balls(srv_.scene());
  const v1::UndoAck u = Undo(*a_, 2, "profile");
  ASSERT_TRUE(u.accepted()) << u.DebugString();
  EXPECT_EQ(u.replayed(), 1u);
  EXPECT_EQ(u.redo_depth(), 1u);
  const std::vector<double> undone = Balls(srv_.scene());
  std::vector<double> want = initial;
  want[3 * 4 + 3] = both[3 * 4 + 3];  // B's orientation, A's move gone
  EXPECT_EQ(undone, want);
  const v1::UndoAck nothing = Undo(*b_, 2, "profile", /*redo=*/true);
  EXPECT_FALSE(nothing.accepted()) << "B undid nothing";
  ASSERT_TRUE(Undo(*a_, 3, "profile", /*redo=*/true).accepted());
  EXPECT_EQ(Balls(srv_.scene()), both);
  ASSERT_TRUE(Undo(*a_, 4, "profile").accepted());
  EXPECT_EQ(Balls(srv_.scene()), undone);
  const v1::HistoryAnswer h = History(*a_, "profile");
  ASSERT_EQ(h.entries_size(), 2);
  EXPECT_EQ(h.entries(0).kind_name(), "ball edit");
}

// A's intent, B's intent, A undoes: the model hash equals a fresh server's with B's intent only;
// redo returns the exact hash.
TEST_F(UndoKindsClientTest, ModelIntentUndoAndRedoKeepTheOtherSculptorsIntent) {
  const uint32_t first = FirstCorner(srv_.scene()), last = LastCorner(srv_.scene());
  ASSERT_TRUE(Intent(*a_, 1, first, {-0.25, 0, 0}).accepted());
  ASSERT_TRUE(Intent(*b_, 1, last, {0.25, 0.25, 0.25}).accepted());
  const uint64_t both = ModelHash(srv_.scene());
  const v1::UndoAck u = Undo(*a_, 2, "part");
  ASSERT_TRUE(u.accepted()) << u.DebugString();
  const uint64_t undone = ModelHash(srv_.scene());
  EXPECT_NE(undone, both);
  {
    InProcessServer fresh("undo_kinds_fresh");
    Configure(fresh);
    ASSERT_TRUE(fresh.Start());
    testing::RawClient b(fresh.port());
    ASSERT_TRUE(b.Enter(fresh.config().sculptor_token, v1::ROLE_SCULPTOR, kB));
    ASSERT_TRUE(Intent(b, 1, last, {0.25, 0.25, 0.25}).accepted());
    EXPECT_EQ(ModelHash(fresh.scene()), undone) << "differs from a server without A's intent";
  }
  ASSERT_TRUE(Undo(*a_, 3, "part", /*redo=*/true).accepted());
  EXPECT_EQ(ModelHash(srv_.scene()), both);
  ASSERT_TRUE(Undo(*a_, 4, "part").accepted());
  EXPECT_EQ(ModelHash(srv_.scene()), undone);
  const v1::HistoryAnswer h = History(*b_, "part");
  ASSERT_GE(h.entries_size(), 2);
  EXPECT_EQ(h.entries(0).kind_name(), "model intent");
}

}  // namespace
}  // namespace sculpt::server
