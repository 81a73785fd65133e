// Per-user undo and redo (issue 15) at the kernel level: an undo equals a fresh replay of the log
// without the undone edit (hash, volume and reference volume bit for bit), redo returns to the
// exact state before the undo, and the named errors.
#include "scene/edit_history.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "levelset/sculpture_grid.h"
#include "scene/paint.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"

namespace sculpt::server {
namespace {

using levelset::EditKind;
using levelset::EditRequest;
using levelset::EditSettings;
using levelset::Sculpture;

// The tests' settings pass; one that does not fails the test, which then edits with the defaults.
levelset::ValidEditSettings Valid(const EditSettings& settings) {
  auto valid = levelset::ValidEditSettings::Validate(settings);
  EXPECT_TRUE(valid.ok()) << valid.status();
  return valid.ok() ? *valid : levelset::ValidEditSettings{};
}

Sculpture Sphere(Vec3 center = {0, 0, 0}, double r = 20) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  return std::move(Sculpture::MakeSphere(o, center, r)).value();
}

std::vector<EditRequest> Stroke(Vec3 from, Vec3 to, int poses, EditKind kind = EditKind::kPress,
                                double radius = 3) {
  std::vector<EditRequest> reqs;
  for (int i = 0; i < poses; ++i) {
    const double t = poses == 1 ? 0 : double(i) / (poses - 1);
    EditRequest r;
    r.kind = kind;
    r.tool = levelset::ToolShape::Sphere(from + (to - from) * t, radius);
    r.speed = 30;
    r.dt = 1.0 / 120;
    r.amount = 0.6;
    reqs.push_back(r);
  }
  return reqs;
}

struct Logged {
  std::string author;
  std::vector<EditRequest> reqs;
  std::optional<levelset::SweepRequest> sweep;
  std::optional<codec::Paint> paint;
};

// The scene as a log: every edit goes through the history, as the pipeline will apply it.
class UndoScene {
 public:
  explicit UndoScene(Sculpture initial, EditSettings settings = {}, EditHistoryOptions opt = {})
      : initial_(initial.Clone()), live_(std::move(initial)), settings_(Valid(settings)), history_(opt) {}

  levelset::EditResult Edit(const std::string& author, std::vector<EditRequest> reqs) {
    auto r = history_.Apply(live_, ++seq_, author, reqs, settings_);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    log_.push_back({author, std::move(reqs), std::nullopt, std::nullopt});
    undone_.push_back(false);
    return r.ok() ? *r : levelset::EditResult{};
  }
  levelset::EditResult Sweep(const std::string& author, const levelset::SweepRequest& sweep) {
    auto r = history_.ApplySweep(live_, ++seq_, author, sweep);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    log_.push_back({author, {}, sweep, std::nullopt});
    undone_.push_back(false);
    return r.ok() ? *r : levelset::EditResult{};
  }
  levelset::EditResult Paint(const std::string& author, const codec::Paint& paint) {
    auto r = history_.ApplyPaint(live_, ++seq_, author, paint);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    log_.push_back({author, {}, std::nullopt, paint});
    undone_.push_back(false);
    return r.ok() ? *r : levelset::EditResult{};
  }
  UndoOutcome Undo(const std::string& author) {
    auto r = history_.Undo(live_, author);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (r.ok()) undone_[r->seq - 1] = true;
    return r.ok() ? *r : UndoOutcome{};
  }
  UndoOutcome Redo(const std::string& author) {
    auto r = history_.Redo(live_, author);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (r.ok()) undone_[r->seq - 1] = false;
    return r.ok() ? *r : UndoOutcome{};
  }
  // The log applied afresh, in order, without the edits undone now.
  Sculpture Fresh() const {
    Sculpture s = initial_.Clone();
    for (size_t i = 0; i < log_.size(); ++i) {
      if (undone_[i]) continue;
      if (log_[i].paint) {
        auto r = ApplyPaint(s, *log_[i].paint);
        EXPECT_TRUE(r.ok()) << r.status().ToString();
        continue;
      }
      auto r = log_[i].sweep ? levelset::ApplySweep(s, *log_[i].sweep)
                             : levelset::ApplyEdits(s, log_[i].reqs, settings_);
      EXPECT_TRUE(r.ok()) << r.status().ToString();
    }
    return s;
  }
  // Bit-identical to the fresh replay: voxels and tree (StateHash) and the tracked scalars.
  void ExpectEqualsFresh(const char* where) const {
    const Sculpture f = Fresh();
    EXPECT_EQ(live_.StateHash(), f.StateHash()) << where;
    EXPECT_EQ(levelset::MaterialStateHash(live_), levelset::MaterialStateHash(f)) << where;
    EXPECT_EQ(live_.volume(), f.volume()) << where;
    EXPECT_EQ(live_.reference_volume(), f.reference_volume()) << where;
    EXPECT_EQ(levelset::CaptureReplayState(live_).edits_since_reinit,
              levelset::CaptureReplayState(f).edits_since_reinit)
        << where;
  }

  Sculpture& live() { return live_; }
  EditHistory& history() { return history_; }
  const EditSettings& settings() const { return settings_; }

 private:
  Sculpture initial_;
  Sculpture live_;
  levelset::ValidEditSettings settings_;
  EditHistory history_;
  std::vector<Logged> log_;
  std::vector<bool> undone_;
  uint64_t seq_ = 0;
};

TEST(EditHistoryTest, UndoUnderAnOverlappingPressEqualsFreshReplayWithoutIt) {
  UndoScene scene(Sphere());
  const uint64_t initial = scene.live().StateHash();
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  const uint64_t after_a = scene.live().StateHash();
  scene.Edit("B", Stroke({20, 0, -2}, {19, 1, 4}, 4));
  const uint64_t after_ab = scene.live().StateHash();
  ASSERT_TRUE(scene.history().UndoTarget("A").ok());
  EXPECT_EQ(*scene.history().UndoTarget("A"), 1u);
  EXPECT_EQ(*scene.history().UndoTarget("B"), 2u);
  const UndoOutcome u = scene.Undo("A");
  EXPECT_EQ(*scene.history().RedoTarget("A"), 1u);
  EXPECT_EQ(u.seq, 1u);
  EXPECT_EQ(u.author, "A");
  EXPECT_EQ(u.replayed, 1u);
  EXPECT_EQ(u.replayed_by.at("B"), 1u);
  EXPECT_FALSE(u.dirty_leaves.empty());
  scene.ExpectEqualsFresh("after A's undo");
  // B's stroke remains: neither the sphere nor the state with A.
  EXPECT_NE(scene.live().StateHash(), initial);
  EXPECT_NE(scene.live().StateHash(), after_a);
  EXPECT_NE(scene.live().StateHash(), after_ab);
  EXPECT_EQ(scene.history().undo_depth("A"), 0u);
  EXPECT_EQ(scene.history().redo_depth("A"), 1u);
  // Redo with nothing in between: exactly the state before the undo.
  scene.Redo("A");
  EXPECT_EQ(scene.live().StateHash(), after_ab);
  scene.ExpectEqualsFresh("after A's redo");
}

TEST(EditHistoryTest, UndoUnderThirtyLaterStrokesFromThreeOthers) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -4, 0}, {19, 4, 1}, 4));
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> jitter(-4, 4);
  const char* others[3] = {"B", "C", "D"};
  const EditKind kinds[4] = {EditKind::kPress, EditKind::kAdd, EditKind::kSmooth,
                             EditKind::kSubtract};
  for (int i = 0; i < 30; ++i) {
    const Vec3 a{19.5, jitter(rng), jitter(rng)};
    const Vec3 b{19.0, jitter(rng), jitter(rng)};
    scene.Edit(others[i % 3], Stroke(a, b, 3, kinds[i % 4], 2.5));
  }
  const UndoOutcome u = scene.Undo("A");
  scene.ExpectEqualsFresh("after A's undo under 30 strokes");
  EXPECT_GE(u.replayed, 20u);  // they overlap A's stroke or read the volume it moved
  EXPECT_EQ(u.replayed_by.size(), 3u);
  uint32_t sum = 0;
  for (const auto& [who, n] : u.replayed_by) sum += n;
  EXPECT_EQ(sum, u.replayed);
}

TEST(EditHistoryTest, UndoRedoAlternatingAHundredTimesKeepsHashAndVolume) {
  // Small strokes: each step replays B's (the kernel's cost), 100 steps in all.
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -2, 0}, {19, 2, 1}, 2, EditKind::kPress, 2));
  scene.Edit("B", Stroke({20, 0, -1}, {19, 1, 2}, 2, EditKind::kPress, 2));
  scene.Edit("C", Stroke({0, 20, 0}, {1, 19, 3}, 2, EditKind::kAdd, 2));
  const uint64_t with = scene.live().StateHash();
  const double volume_with = scene.live().volume();
  scene.Undo("A");
  scene.ExpectEqualsFresh("first undo");
  const uint64_t without = scene.live().StateHash();
  const double volume_without = scene.live().volume();
  for (int i = 0; i < 50; ++i) {
    scene.Redo("A");
    ASSERT_EQ(scene.live().StateHash(), with) << "redo " << i;
    ASSERT_LE(std::abs(scene.live().volume() - volume_with), 1e-6 * volume_with);
    scene.Undo("A");
    ASSERT_EQ(scene.live().StateHash(), without) << "undo " << i;
    ASSERT_LE(std::abs(scene.live().volume() - volume_without), 1e-6 * volume_without);
  }
  // In fact bit for bit.
  EXPECT_EQ(scene.live().volume(), volume_without);
  scene.ExpectEqualsFresh("after 101 undos and redos");
}

TEST(EditHistoryTest, TwoAuthorsUndoingInTheSameRegion) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  scene.Edit("B", Stroke({20, 0, -2}, {19, 1, 4}, 4));
  scene.Edit("A", Stroke({19, -2, 2}, {19, 2, -2}, 4, EditKind::kSmooth));
  scene.Edit("B", Stroke({20, 2, 0}, {20, -2, 0}, 4, EditKind::kAdd));
  scene.Edit("A", Stroke({19, 0, 0}, {18, 0, 2}, 3));
  scene.Undo("B");  // B's add, under A's last press
  scene.ExpectEqualsFresh("B undoes its add");
  scene.Undo("A");  // A's last press
  scene.ExpectEqualsFresh("A undoes its last press");
  scene.Undo("B");  // B's first press, under A's smooth
  scene.ExpectEqualsFresh("B undoes its press");
  scene.Redo("A");
  scene.ExpectEqualsFresh("A redoes its last press");
  scene.Undo("A");
  scene.Undo("A");  // the smooth
  scene.ExpectEqualsFresh("A undoes its smooth");
  scene.Redo("B");
  scene.ExpectEqualsFresh("B redoes its press");
}

TEST(EditHistoryTest, UndoOfAPressThatCutOffAnIslandWhichWasRemoved) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  Sculpture bar = std::move(Sculpture::MakeCapsule(o, {-20, 0, 0}, {20, 0, 0}, 3)).value();
  EditSettings s;
  s.islands = levelset::IslandPolicy::kRemoveSmall;
  s.min_island_volume = 1000;
  UndoScene scene(std::move(bar), s);
  const double reference0 = scene.live().reference_volume();
  // A presses through the bar near its end: the tip is cut off and removed.
  const levelset::EditResult cut = scene.Edit("A", Stroke({14, 0, -6}, {14, 0, 6}, 5, EditKind::kPress, 4));
  ASSERT_GE(cut.islands_removed, 1);
  ASSERT_LT(scene.live().reference_volume(), reference0);
  // B works on the bar where the cut was, then A undoes.
  scene.Edit("B", Stroke({11, 0, 3}, {11, 0, -3}, 4, EditKind::kAdd, 2.5));
  scene.Edit("C", Stroke({-10, 3, 0}, {-10, 2, 0}, 3));
  const UndoOutcome u = scene.Undo("A");
  scene.ExpectEqualsFresh("undo of the cut");
  // The tip is back, and the reference volume no longer counts the removal.
  EXPECT_LT(scene.live().SampleWorld({20, 0, 0}), 0.0);
  EXPECT_GE(u.replayed, 1u);
  scene.Redo("A");
  scene.ExpectEqualsFresh("redo of the cut");
  EXPECT_GT(scene.live().SampleWorld({20, 0, 0}), 0.0);
}

TEST(EditHistoryTest, SweepsAreUndoneAndReplayedLikeStrokes) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  levelset::SweepRequest block;  // a 8 x 8 square extruded 4 voxels out of the sphere at +x
  block.plane.origin = {18, -4, -4};
  block.plane.u = {0, 1, 0};
  block.plane.v = {0, 0, 1};
  block.outline = {{0, 0}, {8, 0}, {8, 8}, {0, 8}};
  block.depth = 5;
  scene.Sweep("B", block);
  scene.Edit("C", Stroke({23, 0, 0}, {22, 1, 1}, 3));
  const UndoOutcome a = scene.Undo("A");  // under B's sweep and C's press
  EXPECT_EQ(a.replayed, 2u);
  scene.ExpectEqualsFresh("a press undone under a sweep");
  const UndoOutcome b = scene.Undo("B");  // the sweep itself
  EXPECT_EQ(b.replayed_by.count("C"), 1u);
  scene.ExpectEqualsFresh("a sweep undone");
  const auto entries = scene.history().Entries("B");
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_TRUE(entries[0].sweep);
  EXPECT_TRUE(entries[0].undone);
  // Across a snapshot of the history too.
  auto again = EditHistory::Parse(scene.history().Serialize());
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(again->Serialize(), scene.history().Serialize());
  scene.Redo("B");
  scene.Redo("A");
  scene.ExpectEqualsFresh("both redone");
}

TEST(EditHistoryTest, FarEditsWithoutCompensationAreNotReplayed) {
  UndoScene scene(Sphere({0, 0, 0}, 30));
  scene.Edit("A", Stroke({30, -3, 0}, {29, 3, 1}, 4));
  scene.Edit("B", Stroke({-30, 0, 0}, {-30, 2, 0}, 3, EditKind::kAdd));
  scene.Edit("C", Stroke({-29, 0, 8}, {-29, 2, 8}, 3, EditKind::kSubtract));
  const UndoOutcome u = scene.Undo("A");
  EXPECT_EQ(u.replayed, 0u);
  scene.ExpectEqualsFresh("far CSG edits carried over by their scalars alone");
  // A compensated press far away reads the tracked volume A moved: it is replayed.
  scene.Redo("A");
  scene.Edit("D", Stroke({0, 0, 30}, {0, 2, 29}, 3));
  const UndoOutcome v = scene.Undo("A");
  EXPECT_EQ(v.replayed, 1u);
  EXPECT_EQ(v.replayed_by.count("D"), 1u);
  scene.ExpectEqualsFresh("far compensated press replayed");
}

// Internal nodes of 128^3 voxels (the leaves' parents) in the tree.
size_t Node1Count(const Sculpture& s) {
  std::vector<const openvdb::FloatTree::RootNodeType::ChildNodeType::ChildNodeType*> nodes;
  levelset::internal::GridOf(s).tree().getNodes(nodes);
  return nodes.size();
}

TEST(EditHistoryTest, UndoRemovesTheNodesAnEditAllocated) {
  // The sphere's band ends just below x = 128; an add there allocates a new 128^3 node, which an
  // undo must take away again for the tree (and its hash) to be the one without the add.
  UndoScene scene(Sphere({105, 10, 10}, 15));
  const size_t nodes = Node1Count(scene.live());
  scene.Edit("A", Stroke({121, 10, 10}, {122, 12, 10}, 2, EditKind::kAdd, 4));
  ASSERT_EQ(Node1Count(scene.live()), nodes + 1);
  scene.Undo("A");
  EXPECT_EQ(Node1Count(scene.live()), nodes);
  scene.ExpectEqualsFresh("undo of an add that allocated a node");
}

TEST(EditHistoryTest, DirtyLeavesBringAReplicaToTheSameState) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  scene.Edit("B", Stroke({20, 0, -2}, {19, 1, 4}, 4));
  Sculpture replica = scene.live().Clone();
  const UndoOutcome u = scene.Undo("A");
  const std::string bytes = levelset::EncodeLeafRecords(scene.live(), u.dirty_leaves, nullptr);
  ASSERT_TRUE(levelset::ApplyLeafRecords(replica, bytes).ok());
  levelset::RestoreReplayState(replica, u.state);
  EXPECT_EQ(levelset::LeavesHash(replica, u.dirty_leaves),
            levelset::LeavesHash(scene.live(), u.dirty_leaves));
  EXPECT_EQ(replica.StateHash(), scene.live().StateHash());
  EXPECT_EQ(replica.reference_volume(), scene.live().reference_volume());
}

TEST(EditHistoryTest, AReplicaHoldingPartOfTheUndoneRegionConverges) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -4, 0}, {19, 4, 1}, 4));
  scene.Edit("B", Stroke({20, 0, -2}, {19, 1, 4}, 4));
  // The replica's interest covers only the half of the strokes with y >= 0.
  const levelset::VoxelBox interest{{0, 0, -32}, {40, 40, 32}};
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  auto replica = levelset::MakeEmptySculpture(o);
  ASSERT_TRUE(replica.ok());
  const auto cells = levelset::AllLeafCells(interest);
  ASSERT_TRUE(levelset::ApplyLeafRecords(
                  *replica, levelset::EncodeLeafRecords(scene.live(), cells, nullptr), interest)
                  .ok());
  ASSERT_EQ(levelset::RegionHash(*replica, interest), levelset::RegionHash(scene.live(), interest));
  const UndoOutcome u = scene.Undo("A");
  bool outside = false;
  for (const levelset::Int3& c : u.dirty_leaves) outside = outside || c.y < 0;
  ASSERT_TRUE(outside);  // the undone region reaches beyond the replica's interest
  const std::string delta = levelset::EncodeLeafRecords(scene.live(), u.dirty_leaves, nullptr);
  ASSERT_TRUE(levelset::ApplyLeafRecords(*replica, delta, interest).ok());
  EXPECT_EQ(levelset::RegionHash(*replica, interest), levelset::RegionHash(scene.live(), interest));
  scene.ExpectEqualsFresh("partial replica case");
}

TEST(EditHistoryTest, UndoAfterARestartFromASnapshotEqualsUndoWithoutIt) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  scene.Edit("B", Stroke({20, 0, -2}, {19, 1, 4}, 4));
  scene.Edit("A", Stroke({0, 20, 0}, {1, 19, 3}, 3));
  scene.Undo("A");  // a redo pending across the restart too
  // The snapshot: the object (with its tracked scalars) and the history beside it.
  auto vdb = scene.live().SerializeVdb();
  ASSERT_TRUE(vdb.ok());
  const std::string bytes = scene.history().Serialize();
  auto restarted = Sculpture::DeserializeVdb(*vdb);
  ASSERT_TRUE(restarted.ok());
  auto history = EditHistory::Parse(bytes);
  ASSERT_TRUE(history.ok()) << history.status().ToString();
  EXPECT_EQ(history->Serialize(), bytes);
  EXPECT_EQ(history->size(), scene.history().size());
  auto after_restart = history->Undo(*restarted, "A");
  ASSERT_TRUE(after_restart.ok()) << after_restart.status().ToString();
  const UndoOutcome live = scene.Undo("A");
  EXPECT_EQ(after_restart->dirty_leaves, live.dirty_leaves);
  EXPECT_EQ(restarted->StateHash(), scene.live().StateHash());
  EXPECT_EQ(restarted->reference_volume(), scene.live().reference_volume());
  scene.ExpectEqualsFresh("undo after a restart");
  ASSERT_TRUE(history->Redo(*restarted, "A").ok());
  scene.Redo("A");
  EXPECT_EQ(restarted->StateHash(), scene.live().StateHash());
}

TEST(EditHistoryTest, RejectsTruncatedHistory) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  const std::string bytes = scene.history().Serialize();
  for (size_t cut : {size_t{0}, size_t{3}, size_t{20}, bytes.size() / 2, bytes.size() - 1}) {
    auto h = EditHistory::Parse(std::string_view(bytes).substr(0, cut));
    ASSERT_FALSE(h.ok()) << cut;
    EXPECT_EQ(h.status().code(), Status::Code::kDataLoss) << cut;
  }
  EXPECT_TRUE(EditHistory::Parse(bytes).ok());
}

// Random strokes, undos and redos by three authors in one region, checked against a fresh
// replay of the log after every undo and redo. SCULPT_UNDO_SEED and SCULPT_UNDO_STEPS pick
// another or a longer sequence.
void RandomEditsUndosAndRedos(const EditSettings& settings, uint64_t seed) {
  if (const char* e = std::getenv("SCULPT_UNDO_SEED")) seed = std::strtoull(e, nullptr, 10);
  std::mt19937 rng(static_cast<uint32_t>(seed));
  std::uniform_real_distribution<double> u(-5, 5);
  std::uniform_int_distribution<int> pick(0, 9);
  const char* authors[3] = {"A", "B", "C"};
  const EditKind kinds[5] = {EditKind::kPress, EditKind::kAdd, EditKind::kSmooth,
                             EditKind::kSubtract, EditKind::kPress};
  UndoScene scene(Sphere(), settings);
  int ops = 0;
  int steps = 24;
  if (const char* e = std::getenv("SCULPT_UNDO_STEPS")) steps = std::atoi(e);
  for (int step = 0; step < steps; ++step) {
    const std::string who = authors[rng() % 3];
    const int what = pick(rng);
    if (what < 6) {
      const Vec3 a{19.5, u(rng), u(rng)};
      scene.Edit(who, Stroke(a, a + Vec3{-0.5, u(rng) / 3, u(rng) / 3}, 2, kinds[rng() % 5], 2.5));
    } else if (what < 8 && scene.history().undo_depth(who) > 0) {
      scene.Undo(who);
      scene.ExpectEqualsFresh(("undo at step " + std::to_string(step)).c_str());
      ++ops;
    } else if (scene.history().redo_depth(who) > 0) {
      scene.Redo(who);
      scene.ExpectEqualsFresh(("redo at step " + std::to_string(step)).c_str());
      ++ops;
    }
    if (::testing::Test::HasFailure()) break;
  }
  EXPECT_GT(ops, 3);
}

TEST(EditHistoryTest, RandomEditsUndosAndRedosEqualFreshReplays) {
  RandomEditsUndosAndRedos(EditSettings{}, 7);
}

// Scalars an edit reads beyond the volume: the reinitialisation counter (every 2nd edit), and
// islands removed with their volume taken off the reference.
TEST(EditHistoryTest, RandomEditsUndosAndRedosWithCountedReinitAndIslands) {
  EditSettings s;
  s.reinit_every_k = 2;
  s.islands = levelset::IslandPolicy::kRemoveSmall;
  s.min_island_volume = 50;
  RandomEditsUndosAndRedos(s, 8);
}

TEST(EditHistoryTest, RejectsUndoWithNothingToUndo) {
  UndoScene scene(Sphere());
  auto r = scene.history().Undo(scene.live(), "A");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("author=\"A\""), std::string::npos);
  EXPECT_EQ(scene.history().UndoTarget("A").status().code(), Status::Code::kFailedPrecondition);
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  scene.Undo("A");
  const uint64_t h = scene.live().StateHash();
  auto again = scene.history().Undo(scene.live(), "A");
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_EQ(scene.live().StateHash(), h);
}

TEST(EditHistoryTest, RejectsRedoWithNothingToRedo) {
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  auto r = scene.history().Redo(scene.live(), "A");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kFailedPrecondition);
  // A new edit after an undo ends the redo chain, as in every editor.
  scene.Undo("A");
  scene.Edit("A", Stroke({0, 20, 0}, {1, 19, 3}, 4));
  EXPECT_EQ(scene.history().Redo(scene.live(), "A").status().code(),
            Status::Code::kFailedPrecondition);
}

TEST(EditHistoryTest, RejectsUndoBeyondDepth) {
  EditHistoryOptions opt;
  opt.depth_per_author = 3;
  ASSERT_TRUE(ValidateEditHistoryOptions(opt).ok());
  UndoScene scene(Sphere(), EditSettings{}, opt);
  for (int i = 0; i < 5; ++i) {
    scene.Edit("A", Stroke({20, -6.0 + 3 * i, 0}, {19, -5.0 + 3 * i, 1}, 2));
  }
  EXPECT_EQ(scene.history().undo_depth("A"), 3u);
  for (int i = 0; i < 3; ++i) scene.Undo("A");
  auto r = scene.history().Undo(scene.live(), "A");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kOutOfRange);
  EXPECT_NE(r.status().message().find("depth_per_author=3"), std::string::npos);
  scene.ExpectEqualsFresh("three undone, two out of reach");
}

TEST(EditHistoryTest, RejectsBadOptions) {
  EditHistoryOptions o;
  o.depth_per_author = 0;
  const Status s = ValidateEditHistoryOptions(o);
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("depth_per_author"), std::string::npos);
}

TEST(EditHistoryTest, KeepsOnlyWhatUndoNeeds) {
  EditHistoryOptions opt;
  opt.depth_per_author = 4;
  UndoScene scene(Sphere(), EditSettings{}, opt);
  for (int i = 0; i < 12; ++i) {
    const double a = 0.5 * i;
    scene.Edit("A", Stroke({20 * std::cos(a), 20 * std::sin(a), 0},
                           {19 * std::cos(a), 19 * std::sin(a), 2}, 3));
  }
  // Only the author's last four edits can be undone, so only they are held.
  EXPECT_EQ(scene.history().size(), 4u);
  // A step holds the leaves its stroke wrote (2 KiB each), not the object.
  const uint64_t per_step = scene.history().MemoryBytes() / scene.history().size();
  EXPECT_LT(per_step, 400u * 1024);
  EXPECT_GT(per_step, 10u * 1024);
  const auto entries = scene.history().Entries("A");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_EQ(entries.back().seq, 12u);
  EXPECT_TRUE(entries.back().undoable);
}

TEST(EditHistoryTest, AnEditThatCannotBeUndoneClearsTheHistory) {
  EditSettings global;
  global.compensation = levelset::CompensationRegion::kGlobal;
  UndoScene scene(Sphere());
  scene.Edit("A", Stroke({20, -3, 0}, {19, 3, 1}, 4));
  PreparedEdit p = scene.history().Prepare(scene.live(), Stroke({0, 20, 0}, {0, 19, 1}, 2), global);
  EXPECT_FALSE(p.not_undoable.empty());
  auto res = levelset::ApplyEdits(scene.live(), p.requests, global);
  ASSERT_TRUE(res.ok());
  scene.history().Commit(std::move(p), 2, "B", *res, scene.live());
  auto r = scene.history().Undo(scene.live(), "A");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("compensation=global"), std::string::npos);
}

TEST(EditHistoryRefusalTest, NothingToUndoOrRedoNamesTheAuthor) {
  const EditHistory h;
  const Status undo = h.UndoTarget("7").status();
  EXPECT_EQ(undo.code(), Status::Code::kFailedPrecondition);
  EXPECT_EQ(undo.message(), "undo: author=\"7\" has nothing to undo");
  ASSERT_NE(undo.violation(), nullptr) << undo;
  EXPECT_EQ(undo.violation()->field, "author");
  EXPECT_EQ(undo.violation()->value, "\"7\"");
  EXPECT_EQ(undo.violation()->allowed_range, "authors with an edit to undo");
  const Status redo = h.RedoTarget("7").status();
  EXPECT_EQ(redo.code(), Status::Code::kFailedPrecondition);
  ASSERT_NE(redo.violation(), nullptr) << redo;
  EXPECT_EQ(redo.violation()->field, "author");
  EXPECT_EQ(redo.violation()->allowed_range, "authors with an undone edit to redo");
}

}  // namespace
}  // namespace sculpt::server

namespace sculpt::server {
namespace {

// A sphere with three declared materials (material 0 everywhere until painted).
Sculpture PaintedSphere() {
  Sculpture s = Sphere();
  EXPECT_TRUE(
      levelset::SetMaterials(
          s, {{"clay", {0.6, 0.4, 0.3}}, {"gold", {0.9, 0.8, 0.1}}, {"jade", {0.1, 0.7, 0.4}}})
          .ok());
  return s;
}

codec::Paint PaintAt(Vec3 at, uint32_t material, double radius = 4, double weight = 0.7) {
  codec::Paint p;
  p.object = "clay";
  p.tool = levelset::ToolKind::kSphere;
  p.tool_size = {radius, radius, radius};
  p.position = at;
  p.material = material;
  p.weight = weight;
  return p;
}

// The paint hard case of issue 15: A paints, B paints over it, A presses there, A undoes its
// paint. B's paint and A's press stay; the fractions (and voxels) equal a fresh replay without
// A's paint; redo returns to the exact state.
TEST(EditHistoryPaintTest, UndoOfAPaintUnderAnOverlappingPaintEqualsFreshReplayWithoutIt) {
  UndoScene scene(PaintedSphere());
  const uint64_t blank = levelset::MaterialStateHash(scene.live());
  const levelset::EditResult a = scene.Paint("A", PaintAt({20, 0, 0}, 1));
  EXPECT_FALSE(a.dirty_leaves.empty());
  EXPECT_NE(levelset::MaterialStateHash(scene.live()), blank);
  scene.Paint("B", PaintAt({19, 2, 1}, 2));
  scene.Edit("B", Stroke({20, -2, 0}, {19, 2, 1}, 3));
  const uint64_t sdf = scene.live().StateHash();
  const uint64_t fractions = levelset::MaterialStateHash(scene.live());
  EXPECT_EQ(*scene.history().UndoTarget("A"), 1u);
  const UndoOutcome u = scene.Undo("A");
  EXPECT_EQ(u.seq, 1u);
  EXPECT_EQ(u.replayed, 2u) << "B's paint and B's press read what A's paint wrote";
  EXPECT_NE(levelset::MaterialStateHash(scene.live()), fractions);
  scene.ExpectEqualsFresh("undo of A's paint");
  scene.Redo("A");
  EXPECT_EQ(scene.live().StateHash(), sdf);
  EXPECT_EQ(levelset::MaterialStateHash(scene.live()), fractions);
  scene.ExpectEqualsFresh("redo of A's paint");
}

// Level-set edits on a painted object stay undoable: the pre-image holds the fractions the
// press carried, so undo puts back the paint under it exactly.
TEST(EditHistoryPaintTest, UndoOfAPressOnAPaintedObjectRestoresTheCarriedFractions) {
  UndoScene scene(PaintedSphere());
  scene.Paint("B", PaintAt({20, 0, 0}, 2, 5, 1.0));
  const uint64_t painted = levelset::MaterialStateHash(scene.live());
  const uint64_t sdf = scene.live().StateHash();
  scene.Edit("A", Stroke({21, -2, 0}, {21, 2, 0}, 3, EditKind::kAdd));
  EXPECT_NE(levelset::MaterialStateHash(scene.live()), painted) << "the add carried paint out";
  scene.Paint("B", PaintAt({21, 1, 0}, 1));
  scene.Undo("A");
  scene.ExpectEqualsFresh("undo of A's add under B's second paint");
  scene.Undo("B");
  scene.ExpectEqualsFresh("undo of B's second paint");
  EXPECT_EQ(scene.live().StateHash(), sdf);
  EXPECT_EQ(levelset::MaterialStateHash(scene.live()), painted);
  for (int i = 0; i < 10; ++i) {
    scene.Redo("A");
    scene.Undo("A");
  }
  EXPECT_EQ(levelset::MaterialStateHash(scene.live()), painted) << "alternation drifted";
  EXPECT_TRUE(scene.history().cleared_reason().empty()) << scene.history().cleared_reason();
}

// The history kept beside a snapshot holds the paints and the fractions of every pre-image: a
// restart undoes a paint as the live server does.
TEST(EditHistoryPaintTest, APaintIsUndoneAfterARestartFromASnapshotAsWithout) {
  UndoScene scene(PaintedSphere());
  scene.Paint("A", PaintAt({20, 0, 0}, 1));
  scene.Edit("B", Stroke({20, -2, 0}, {19, 2, 1}, 3));
  scene.Paint("B", PaintAt({19, 1, 0}, 2));
  auto vdb = scene.live().SerializeVdb();
  ASSERT_TRUE(vdb.ok());
  const std::string bytes = scene.history().Serialize();
  auto restarted = Sculpture::DeserializeVdb(*vdb);
  ASSERT_TRUE(restarted.ok());
  ASSERT_EQ(levelset::MaterialStateHash(*restarted), levelset::MaterialStateHash(scene.live()));
  auto history = EditHistory::Parse(bytes);
  ASSERT_TRUE(history.ok()) << history.status().ToString();
  EXPECT_EQ(history->Serialize(), bytes);
  const std::vector<HistoryEntry> entries = history->Entries();
  ASSERT_EQ(entries.size(), 3u);
  EXPECT_EQ(entries[0].kind_name, "paint");
  EXPECT_TRUE(entries[0].paint);
  EXPECT_EQ(entries[1].kind_name, "press");
  auto after_restart = history->Undo(*restarted, "A");
  ASSERT_TRUE(after_restart.ok()) << after_restart.status().ToString();
  scene.Undo("A");
  EXPECT_EQ(restarted->StateHash(), scene.live().StateHash());
  EXPECT_EQ(levelset::MaterialStateHash(*restarted), levelset::MaterialStateHash(scene.live()));
  scene.ExpectEqualsFresh("paint undone after a restart");
}

}  // namespace
}  // namespace sculpt::server
