// Per-author undo and redo of paints, sweeps, ball edits and model intents through the scene's
// commit pipeline (issue 15): the author's newest edit of any kind is taken back as if never
// made while the others' later edits stay, redo returns the exact state, and a restart after the
// undo (the log replayed) gives the same state and the same next undo.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <future>
#include <optional>
#include <string>
#include <vector>

#include "integration/raw_client.h"
#include "scene/scene.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/hyperpatch.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"
#include "sculpt/levelset/materials.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kA = 11, kB = 22;

class UndoKindsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() /
            ("sculpt_undo_kinds_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(base_);
    fs::create_directories(base_);
    config_.fsync = "group";
    config_.group_commit_ms = 2;
    config_.scene.objects.front().radius = 12;
    config_.scene.materials = {
        {"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}, {"jade", {0.1, 0.7, 0.4}}};
    SkinConfig skin;
    skin.name = "profile";
    skin.origin = {0, 0, 0};
    skin.chord_tolerance = 0.02;
    skin.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
    config_.scene.skins = {skin};
  }
  void TearDown() override {
    scene_.reset();
    fs::remove_all(base_);
  }

  // A second object "part": two glued boxes as a hyperpatch model (models.h).
  void AddModelObject() {
    auto model = hetero::CompositeModel::Create(
        {{"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}, {"jade", {0.1, 0.7, 0.4}}});
    ASSERT_TRUE(model.ok()) << model.status();
    model_ = std::move(model).value();
    hetero::ValidityChecker checker;
    const std::vector<double> clay{1, 0, 0}, gold{0, 1, 0};
    auto a = hetero::LibraryBox({20, 0, 0}, {24, 4, 4}, clay);
    auto b = hetero::LibraryBox({24, 0, 0}, {28, 4, 4}, gold);
    ASSERT_TRUE(a.ok() && b.ok());
    for (const auto* p : {&*a, &*b}) {
      auto r = hetero::AddCellChecked(&*model_, &checker, *p, hetero::CellSource::kLibrary);
      ASSERT_TRUE(r.ok()) << r.status();
      ASSERT_TRUE(r->added) << r->rejection.ToString();
    }
    const std::string path = (base_ / "two_boxes.json").string();
    ASSERT_TRUE(hetero::SaveModel(*model_, path, "two boxes").ok());
    ObjectConfig o;
    o.name = "part";
    o.primitive = "model";
    o.model = path;
    config_.scene.objects.push_back(o);
  }
  uint32_t Corner(int cell, int i, int j, int k) const {
    return model_->cell(cell).coef[static_cast<size_t>(hetero::Hyperpatch::Index(i, j, k))];
  }

  std::unique_ptr<Scene> Open(const std::string& dir) {
    ServerConfig c = config_;
    c.data_dir = (base_ / dir).string();
    auto s = Scene::Open(c);
    EXPECT_TRUE(s.ok()) << s.status();
    return s.ok() ? std::move(s).value() : nullptr;
  }

  static PaintOutcome Paint(Scene& scene, uint64_t client, uint64_t seq, Vec3 at,
                            uint32_t material) {
    codec::Paint p;
    p.client_seq = seq;
    p.object = "clay";
    p.tool = levelset::ToolKind::kSphere;
    p.tool_size = {3, 3, 3};
    p.position = at;
    p.material = material;
    p.weight = 0.75;
    std::promise<PaintOutcome> done;
    scene.Paint(client, p, [&done](PaintOutcome o) { done.set_value(std::move(o)); });
    PaintOutcome out = done.get_future().get();
    EXPECT_TRUE(out.status.ok()) << out.status;
    return out;
  }
  static SkinOutcome Ball(Scene& scene, uint64_t client, uint64_t seq, codec::BallOp op,
                          uint32_t index, double x, double y, double r, double theta = 0) {
    codec::BallEdit e;
    e.client_seq = seq;
    e.skin = "profile";
    e.op = op;
    e.index = index;
    e.x = x;
    e.y = y;
    e.r = r;
    e.theta = theta;
    std::promise<SkinOutcome> done;
    scene.EditSkin(client, e, [&done](SkinOutcome o) { done.set_value(std::move(o)); });
    SkinOutcome out = done.get_future().get();
    EXPECT_TRUE(out.status.ok()) << out.status;
    return out;
  }
  static ModelOutcome Intent(Scene& scene, uint64_t client, uint64_t seq, uint32_t corner, Vec3 d) {
    codec::ModelEdit e;
    e.client_seq = seq;
    e.object = "part";
    e.intent.corner = corner;
    e.intent.displacement = d;
    std::promise<ModelOutcome> done;
    scene.EditModel(client, e, [&done](ModelOutcome o) { done.set_value(std::move(o)); });
    ModelOutcome out = done.get_future().get();
    EXPECT_TRUE(out.status.ok()) << out.status;
    return out;
  }
  static UndoCommandOutcome Undo(Scene& scene, uint64_t client, uint64_t seq,
                                 const std::string& object, bool redo = false) {
    codec::UndoCommand c;
    c.client_seq = seq;
    c.object = object;
    c.redo = redo;
    std::promise<UndoCommandOutcome> done;
    scene.Undo(client, c, [&done](UndoCommandOutcome o) { done.set_value(std::move(o)); });
    return done.get_future().get();
  }
  // The skin "profile" (in the plane z = 0, x in about [-15, 15], |y| <= 3) extruded `depth`
  // along +z into "clay": an add grows a slab out of the sphere at both ends of x.
  static SkinOutcome Sweep(Scene& scene, uint64_t client, uint64_t seq, bool add, double depth) {
    codec::SkinSweepRequest s;
    s.client_seq = seq;
    s.skin = "profile";
    s.object = "clay";
    s.mode = levelset::SweepRequest::Mode::kExtrude;
    s.add = add;
    s.depth = depth;
    std::promise<SkinOutcome> done;
    scene.SweepSkin(client, s, [&done](SkinOutcome o) { done.set_value(std::move(o)); });
    SkinOutcome out = done.get_future().get();
    EXPECT_TRUE(out.status.ok()) << out.status;
    return out;
  }
  // A 3-pose press stroke at `at` (moving along +x, +y), as a client sends it.
  static StrokeOutcome Press(Scene& scene, uint64_t client, uint64_t seq, Vec3 at) {
    const v1::ClientMessage m = testing::RawClient::PressStroke(seq, at, 3, 2.0);
    auto limits = scene.LimitsFor("clay");
    EXPECT_TRUE(limits.ok());
    auto stroke = codec::DecodeStroke(m.stroke(), *limits);
    EXPECT_TRUE(stroke.ok()) << stroke.status();
    std::promise<StrokeOutcome> p;
    scene.Submit(client, std::move(stroke).value(),
                 [&p](const StrokeOutcome& o) { p.set_value(o); });
    StrokeOutcome out = p.get_future().get();
    EXPECT_TRUE(out.status.ok()) << out.status;
    return out;
  }
  // The object's tracked volume and reference volume.
  static std::pair<double, double> Volumes(Scene& scene) {
    std::pair<double, double> v;
    EXPECT_TRUE(scene.Inspect("clay", [&](const levelset::Sculpture& s) {
      v = {s.volume(), s.reference_volume()};
    }));
    return v;
  }
  static HistoryOutcome History(Scene& scene, const std::string& object) {
    codec::HistoryQuery q;
    q.object = object;
    q.limit = 50;
    std::promise<HistoryOutcome> done;
    scene.History(q, [&done](HistoryOutcome o) { done.set_value(std::move(o)); });
    return done.get_future().get();
  }

  // The object's voxels and fractions, both hashed.
  static std::pair<uint64_t, uint64_t> Hashes(Scene& scene) {
    uint64_t fractions = 0;
    EXPECT_TRUE(scene.Inspect(
        "clay", [&](const levelset::Sculpture& s) { fractions = levelset::MaterialStateHash(s); }));
    return {scene.StateHash("clay"), fractions};
  }
  static std::vector<skin::OrientedBall> Balls(Scene& scene) {
    auto sk = scene.SkinCopy("profile");
    EXPECT_TRUE(sk.ok()) << sk.status();
    return sk.ok() ? sk->balls() : std::vector<skin::OrientedBall>{};
  }
  static void ExpectSameBalls(const std::vector<skin::OrientedBall>& a,
                              const std::vector<skin::OrientedBall>& b, const char* where) {
    ASSERT_EQ(a.size(), b.size()) << where;
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].c.x, b[i].c.x) << where << " ball " << i;
      EXPECT_EQ(a[i].c.y, b[i].c.y) << where << " ball " << i;
      EXPECT_EQ(a[i].r, b[i].r) << where << " ball " << i;
      EXPECT_EQ(a[i].theta, b[i].theta) << where << " ball " << i;
    }
  }
  static uint64_t ModelHash(Scene& scene) {
    auto m = scene.ModelInfo("part");
    EXPECT_TRUE(m.ok()) << m.status();
    return m.ok() ? m->hash : 0;
  }

  fs::path base_;
  ServerConfig config_;
  std::unique_ptr<Scene> scene_;
  std::optional<hetero::CompositeModel> model_;
};

// A paints, B paints over it, A undoes: B's paint stays, A's is gone, and the object (voxels and
// fractions) equals a scene that only ever got B's paint. Redo returns the exact state; the
// alternation does not drift; a restart after the undo recovers it and redoes exactly.
TEST_F(UndoKindsTest, UndoOfAPaintUnderAnotherSculptorsPaintEqualsAReplayWithoutIt) {
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const auto blank = Hashes(*scene_);
  Paint(*scene_, kA, 1, {0, 0, 12}, 1);
  Paint(*scene_, kB, 1, {1.5, 0, 12}, 2);
  const auto both = Hashes(*scene_);
  const UndoCommandOutcome u = Undo(*scene_, kA, 1, "clay");
  ASSERT_TRUE(u.status.ok()) << u.status;
  EXPECT_EQ(u.target_seq, 1u);
  EXPECT_EQ(u.replayed, 1u) << "B's overlapping paint is replayed without A's";
  ASSERT_EQ(u.replayed_by.count(std::to_string(kB)), 1u);
  const auto undone = Hashes(*scene_);
  EXPECT_NE(undone.second, both.second);
  EXPECT_NE(undone.second, blank.second);

  auto fresh = Open("fresh");
  ASSERT_TRUE(fresh);
  Paint(*fresh, kB, 1, {1.5, 0, 12}, 2);
  EXPECT_EQ(Hashes(*fresh), undone) << "differs from a replay without A's paint";
  fresh.reset();

  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(Undo(*scene_, kA, 2 + 2 * i, "clay", /*redo=*/true).status.ok()) << i;
    EXPECT_EQ(Hashes(*scene_), both) << "redo " << i;
    ASSERT_TRUE(Undo(*scene_, kA, 3 + 2 * i, "clay").status.ok()) << i;
    EXPECT_EQ(Hashes(*scene_), undone) << "undo " << i;
  }
  const HistoryOutcome h = History(*scene_, "clay");
  ASSERT_TRUE(h.status.ok()) << h.status;
  ASSERT_EQ(h.entries.size(), 2u);
  EXPECT_EQ(h.entries[0].kind_name, "paint");
  EXPECT_TRUE(h.entries[1].undone) << "A's paint, oldest";

  // kill -9 is a restart without a snapshot: the log replays the paints and the undos.
  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  EXPECT_EQ(Hashes(*scene_), undone) << "recovery after the undo";
  ASSERT_TRUE(Undo(*scene_, kA, 20, "clay", /*redo=*/true).status.ok());
  EXPECT_EQ(Hashes(*scene_), both) << "redo after the restart";
}

// Strokes on a painted object stay undoable (the pre-images hold the fractions the stroke
// carried), and A's newest edit of either kind is what its undo takes back.
TEST_F(UndoKindsTest, StrokesOnAPaintedObjectAndPaintsUndoNewestFirst) {
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  Paint(*scene_, kB, 1, {0, 0, 12}, 1);
  const auto painted = Hashes(*scene_);
  codec::DecodedStroke stroke;
  stroke.client_seq = 1;
  stroke.object = "clay";
  levelset::EditRequest r;
  r.kind = levelset::EditKind::kAdd;
  r.tool = levelset::ToolShape::Sphere({0, 0, 12}, 2.0);
  r.speed = 30;
  r.dt = 1.0 / 120;
  r.amount = 0.5;
  stroke.edits = {r};
  std::promise<StrokeOutcome> done;
  scene_->Submit(kA, stroke, [&done](const StrokeOutcome& o) { done.set_value(o); });
  ASSERT_TRUE(done.get_future().get().status.ok());
  const auto stroked = Hashes(*scene_);
  EXPECT_NE(stroked.second, painted.second) << "the add carried the paint outwards";
  Paint(*scene_, kA, 2, {3, 0, 12}, 2);
  const UndoCommandOutcome first = Undo(*scene_, kA, 1, "clay");
  ASSERT_TRUE(first.status.ok()) << first.status;
  EXPECT_EQ(first.target_seq, 3u) << "A's paint, its newest edit";
  EXPECT_EQ(Hashes(*scene_), stroked);
  const UndoCommandOutcome second = Undo(*scene_, kA, 2, "clay");
  ASSERT_TRUE(second.status.ok()) << second.status;
  EXPECT_EQ(second.target_seq, 2u) << "then A's stroke";
  EXPECT_EQ(Hashes(*scene_), painted) << "voxels and fractions as before the stroke";
}

// Where B presses: on the sphere near +x, inside the slab a sweep-add grows there (z in [0, 3]),
// so B's stroke reads and writes voxels the sweep wrote; without the sweep it presses the sphere.
constexpr Vec3 kOnTheSlab{12.5, 0, 2.5};

// A sweeps a skin into the object, B presses overlapping, A undoes: B's stroke stays (replayed
// without the sweep), A's sweep is gone, and the object equals a scene whose log never had the
// sweep (hash and tracked volumes bit for bit).
TEST_F(UndoKindsTest, UndoOfASweepUnderAnotherSculptorsPressEqualsAReplayWithoutIt) {
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const auto blank = Hashes(*scene_);
  const SkinOutcome sweep = Sweep(*scene_, kA, 1, /*add=*/true, 3.0);
  ASSERT_GT(sweep.dirty_leaves, 0u) << "the sweep changed nothing";
  Press(*scene_, kB, 1, kOnTheSlab);
  const auto both = Hashes(*scene_);

  const UndoCommandOutcome u = Undo(*scene_, kA, 1, "clay");
  ASSERT_TRUE(u.status.ok()) << u.status;
  EXPECT_EQ(u.target_seq, sweep.global_seq) << "A's sweep";
  EXPECT_EQ(u.replayed, 1u) << "B's overlapping press is replayed without the sweep";
  EXPECT_EQ(u.replayed_by.count(std::to_string(kB)), 1u);
  EXPECT_EQ(u.undo_depth, 0u);
  EXPECT_EQ(u.redo_depth, 1u);
  const auto undone = Hashes(*scene_);
  EXPECT_NE(undone, both);
  EXPECT_NE(undone, blank) << "B's press is gone too";

  auto fresh = Open("fresh");
  ASSERT_TRUE(fresh);
  Press(*fresh, kB, 1, kOnTheSlab);
  EXPECT_EQ(Hashes(*fresh), undone) << "differs from a replay of the log without A's sweep";
  EXPECT_EQ(Volumes(*fresh), Volumes(*scene_)) << "volume bookkeeping as without the sweep";
  // B can still undo its press: the sweep did not clear the history.
  const UndoCommandOutcome b = Undo(*scene_, kB, 2, "clay");
  ASSERT_TRUE(b.status.ok()) << b.status;
  EXPECT_EQ(Hashes(*scene_), blank);
}

// Redo of an undone sweep with nothing between returns exactly (hash, volume within 1e-6
// relative), also alternated; the history names it a sweep, undone or not.
TEST_F(UndoKindsTest, RedoOfASweepIsExactAndTheHistoryNamesItASweep) {
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  Press(*scene_, kB, 1, kOnTheSlab);
  const SkinOutcome sweep = Sweep(*scene_, kA, 1, /*add=*/false, 2.0);  // cuts a slot
  ASSERT_GT(sweep.dirty_leaves, 0u);
  Press(*scene_, kB, 2, {11.5, 0, 1});  // in the slot's wall
  const auto before = Hashes(*scene_);
  const auto before_volumes = Volumes(*scene_);

  auto entry = [](const HistoryOutcome& h, uint64_t seq) -> const HistoryEntry* {
    for (const HistoryEntry& e : h.entries) {
      if (e.seq == seq) return &e;
    }
    return nullptr;
  };
  {
    const HistoryOutcome h = History(*scene_, "clay");
    ASSERT_TRUE(h.status.ok()) << h.status;
    EXPECT_EQ(h.cleared, "") << "a sweep no longer clears the history";
    ASSERT_EQ(h.entries.size(), 3u);
    const HistoryEntry* e = entry(h, sweep.global_seq);
    ASSERT_NE(e, nullptr);
    EXPECT_TRUE(e->sweep);
    EXPECT_EQ(e->kind_name, "sweep-subtract");
    EXPECT_EQ(e->author, std::to_string(kA));
    EXPECT_FALSE(e->undone);
    EXPECT_TRUE(e->undoable);
    EXPECT_GT(e->wall_ms, 0u);
  }
  const UndoCommandOutcome u = Undo(*scene_, kA, 1, "clay");
  ASSERT_TRUE(u.status.ok()) << u.status;
  EXPECT_EQ(u.target_seq, sweep.global_seq);
  const auto undone = Hashes(*scene_);
  EXPECT_NE(undone, before);
  {
    const HistoryOutcome h = History(*scene_, "clay");
    const HistoryEntry* e = entry(h, sweep.global_seq);
    ASSERT_NE(e, nullptr);
    EXPECT_TRUE(e->sweep);
    EXPECT_TRUE(e->undone);
    EXPECT_FALSE(e->undoable) << "on the redo stack";
  }
  for (int i = 0; i < 3; ++i) {
    const UndoCommandOutcome r = Undo(*scene_, kA, 2 + 2 * i, "clay", /*redo=*/true);
    ASSERT_TRUE(r.status.ok()) << r.status;
    EXPECT_EQ(r.target_seq, sweep.global_seq);
    EXPECT_EQ(Hashes(*scene_), before) << "redo " << i;
    const auto v = Volumes(*scene_);
    EXPECT_NEAR(v.first, before_volumes.first, 1e-6 * before_volumes.first) << "redo " << i;
    EXPECT_NEAR(v.second, before_volumes.second, 1e-6 * before_volumes.second) << "redo " << i;
    ASSERT_TRUE(Undo(*scene_, kA, 3 + 2 * i, "clay").status.ok()) << i;
    EXPECT_EQ(Hashes(*scene_), undone) << "undo " << i;
  }
  ASSERT_TRUE(Undo(*scene_, kA, 10, "clay", /*redo=*/true).status.ok());
  const HistoryOutcome h = History(*scene_, "clay");
  const HistoryEntry* e = entry(h, sweep.global_seq);
  ASSERT_NE(e, nullptr);
  EXPECT_FALSE(e->undone);
}

// The undo of a sweep after a restart (the log replayed through the history; and from a
// snapshot whose history file holds the sweep, with B's press in the log tail) equals the same
// undo without a restart, and the undo itself survives the next restart.
TEST_F(UndoKindsTest, UndoOfASweepAfterARestartEqualsNoRestart) {
  config_.snapshot_every_edits = 0;  // snapshots only when asked
  config_.snapshot_every_seconds = 0;
  scene_ = Open("a");
  auto snap = Open("snap");
  auto control = Open("control");
  ASSERT_TRUE(scene_ && snap && control);
  for (Scene* s : {scene_.get(), snap.get(), control.get()}) Sweep(*s, kA, 1, true, 3.0);
  snap->FlushAndSnapshot();
  for (Scene* s : {scene_.get(), snap.get(), control.get()}) Press(*s, kB, 1, kOnTheSlab);
  const auto both = Hashes(*control);
  scene_->Flush();
  snap->Flush();

  scene_.reset();  // a restart without a snapshot: the whole log replays
  snap.reset();
  scene_ = Open("a");
  snap = Open("snap");
  ASSERT_TRUE(scene_ && snap);
  EXPECT_EQ(Hashes(*scene_), both) << "recovered from the log";
  EXPECT_EQ(Hashes(*snap), both) << "recovered from the snapshot and the tail";
  EXPECT_EQ(scene_->UndoDepth("clay", kA), std::make_pair(size_t{1}, size_t{0}));
  EXPECT_EQ(snap->UndoDepth("clay", kA), std::make_pair(size_t{1}, size_t{0}));

  Scene* all[3] = {scene_.get(), snap.get(), control.get()};
  UndoCommandOutcome acks[3];
  for (int i = 0; i < 3; ++i) acks[i] = Undo(*all[i], kA, 1, "clay");
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(acks[i].status.ok()) << i << " " << acks[i].status;
    EXPECT_EQ(acks[i].target_seq, acks[2].target_seq) << i;
    EXPECT_EQ(acks[i].replayed, acks[2].replayed) << i;
  }
  const auto undone = Hashes(*control);
  EXPECT_NE(undone, both);
  EXPECT_EQ(Hashes(*scene_), undone) << "undo after a restart from the log";
  EXPECT_EQ(Hashes(*snap), undone) << "undo after a restart from the snapshot";
  EXPECT_EQ(Volumes(*scene_), Volumes(*control));
  EXPECT_EQ(Volumes(*snap), Volumes(*control));

  scene_->Flush();
  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  EXPECT_EQ(Hashes(*scene_), undone) << "the undo of the sweep recovered";
  ASSERT_TRUE(Undo(*scene_, kA, 2, "clay", /*redo=*/true).status.ok());
  EXPECT_EQ(Hashes(*scene_), both) << "redo after the second restart";
}

// A moves a ball, B orients another, A undoes: B's edit stays, A's is gone (the chain equals a
// scene that only had B's edit); redo and undo alternate exactly; a restart replays the same.
TEST_F(UndoKindsTest, UndoAndRedoOfABallEditKeepTheOtherSculptorsEdit) {
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const auto initial = Balls(*scene_);
  Ball(*scene_, kA, 1, codec::BallOp::kMove, 2, 0.5, 1.5, 3.0);
  Ball(*scene_, kB, 1, codec::BallOp::kOrient, 3, 0, 0, 0, 0.25);
  const auto both = Balls(*scene_);
  const UndoCommandOutcome u = Undo(*scene_, kA, 1, "profile");
  ASSERT_TRUE(u.status.ok()) << u.status;
  EXPECT_EQ(u.target_seq, 1u);
  EXPECT_EQ(u.replayed, 1u) << "B's later ball edit re-applied";
  EXPECT_EQ(u.undo_depth, 0u);
  EXPECT_EQ(u.redo_depth, 1u);
  const auto undone = Balls(*scene_);
  EXPECT_EQ(undone[2].c.x, initial[2].c.x) << "A's move is gone";
  EXPECT_EQ(undone[3].theta, both[3].theta) << "B's orientation stays";

  auto fresh = Open("fresh");
  ASSERT_TRUE(fresh);
  Ball(*fresh, kB, 1, codec::BallOp::kOrient, 3, 0, 0, 0, 0.25);
  ExpectSameBalls(Balls(*fresh), undone, "fresh replay without A's move");
  fresh.reset();

  // Nothing of B's to take back for A; B's own undo takes only B's.
  EXPECT_EQ(Undo(*scene_, kA, 2, "profile").status.code(), Status::Code::kFailedPrecondition);
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(Undo(*scene_, kA, 3 + 2 * i, "profile", /*redo=*/true).status.ok()) << i;
    ExpectSameBalls(Balls(*scene_), both, "redo");
    ASSERT_TRUE(Undo(*scene_, kA, 4 + 2 * i, "profile").status.ok()) << i;
    ExpectSameBalls(Balls(*scene_), undone, "undo");
  }
  const HistoryOutcome h = History(*scene_, "profile");
  ASSERT_TRUE(h.status.ok()) << h.status;
  ASSERT_EQ(h.entries.size(), 2u);
  EXPECT_EQ(h.entries[0].kind_name, "ball edit");
  EXPECT_EQ(h.entries[0].author, std::to_string(kB));
  EXPECT_TRUE(h.entries[1].undone);

  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  ExpectSameBalls(Balls(*scene_), undone, "recovered after the undo");
  ASSERT_TRUE(Undo(*scene_, kA, 30, "profile", /*redo=*/true).status.ok());
  ExpectSameBalls(Balls(*scene_), both, "redo after the restart");
}

// A's intent, then B's, A undoes: the model equals one that only had B's intent; redo returns
// the exact model hash; A's newest edit on the object, a stroke or an intent, goes first; a
// restart replays the same.
TEST_F(UndoKindsTest, UndoAndRedoOfAModelIntentKeepTheOtherSculptorsIntent) {
  AddModelObject();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const uint64_t initial = ModelHash(*scene_);
  ASSERT_TRUE(Intent(*scene_, kA, 1, Corner(0, 0, 0, 0), {-0.25, 0, 0}).status.ok());
  ASSERT_TRUE(Intent(*scene_, kB, 1, Corner(1, 3, 3, 3), {0.25, 0.25, 0.25}).status.ok());
  const uint64_t both = ModelHash(*scene_);
  const UndoCommandOutcome u = Undo(*scene_, kA, 1, "part");
  ASSERT_TRUE(u.status.ok()) << u.status;
  EXPECT_EQ(u.target_seq, 1u);
  EXPECT_EQ(u.replayed, 1u);
  const uint64_t undone = ModelHash(*scene_);
  EXPECT_NE(undone, both);
  EXPECT_NE(undone, initial);

  auto fresh = Open("fresh");
  ASSERT_TRUE(fresh);
  ASSERT_TRUE(Intent(*fresh, kB, 1, Corner(1, 3, 3, 3), {0.25, 0.25, 0.25}).status.ok());
  EXPECT_EQ(ModelHash(*fresh), undone) << "differs from a replay without A's intent";
  fresh.reset();

  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(Undo(*scene_, kA, 2 + 2 * i, "part", /*redo=*/true).status.ok()) << i;
    EXPECT_EQ(ModelHash(*scene_), both) << "redo " << i;
    ASSERT_TRUE(Undo(*scene_, kA, 3 + 2 * i, "part").status.ok()) << i;
    EXPECT_EQ(ModelHash(*scene_), undone) << "undo " << i;
  }
  const HistoryOutcome h = History(*scene_, "part");
  ASSERT_TRUE(h.status.ok()) << h.status;
  ASSERT_GE(h.entries.size(), 2u);
  EXPECT_EQ(h.entries[0].kind_name, "model intent");

  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  EXPECT_EQ(ModelHash(*scene_), undone) << "recovered after the undo";
  ASSERT_TRUE(Undo(*scene_, kA, 30, "part", /*redo=*/true).status.ok());
  EXPECT_EQ(ModelHash(*scene_), both) << "redo after the restart";
}

// The skin's and the model's histories are saved with their files at a snapshot round: a
// restart from that round undoes the edits made before it as the live server would have.
TEST_F(UndoKindsTest, BallEditsAndIntentsAreUndoneAcrossASnapshotAndARestart) {
  AddModelObject();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const auto initial = Balls(*scene_);
  const uint64_t model = ModelHash(*scene_);
  Ball(*scene_, kA, 1, codec::BallOp::kMove, 2, 0.5, 1.5, 3.0);
  Ball(*scene_, kB, 1, codec::BallOp::kOrient, 3, 0, 0, 0, 0.25);
  ASSERT_TRUE(Intent(*scene_, kA, 1, Corner(0, 0, 0, 0), {-0.25, 0, 0}).status.ok());
  scene_->FlushAndSnapshot();
  scene_.reset();
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const UndoCommandOutcome model_undo = Undo(*scene_, kA, 1, "part");
  ASSERT_TRUE(model_undo.status.ok()) << model_undo.status;
  EXPECT_EQ(ModelHash(*scene_), model);
  const UndoCommandOutcome ball_undo = Undo(*scene_, kA, 2, "profile");
  ASSERT_TRUE(ball_undo.status.ok()) << ball_undo.status;
  EXPECT_EQ(ball_undo.replayed, 1u);
  const auto undone = Balls(*scene_);
  EXPECT_EQ(undone[2].c.x, initial[2].c.x) << "A's move is gone after the restart";
  EXPECT_EQ(undone[3].theta, 0.25) << "B's orientation stays";
}

TEST_F(UndoKindsTest, UndoOfAnUnknownObjectOrSkinIsNotFound) {
  scene_ = Open("a");
  ASSERT_TRUE(scene_);
  const UndoCommandOutcome u = Undo(*scene_, kA, 1, "nothing");
  EXPECT_EQ(u.status.code(), Status::Code::kNotFound) << u.status;
  EXPECT_EQ(History(*scene_, "nothing").status.code(), Status::Code::kNotFound);
}

}  // namespace
}  // namespace sculpt::server
