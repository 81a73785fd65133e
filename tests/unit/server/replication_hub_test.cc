/// @brief Unit tests for ReplicationHub with a small sculpture and sinks that keep every frame:
/// what each kind of subscriber is sent after an edit and when it (re)loads its region, and the
/// counters of what was sent.
#include "scene/replication_hub.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/v1/sculpt.pb.h"
#include "unit/server/fake_sink.h"

namespace sculpt::server {
namespace {

using levelset::Int3;
using levelset::Sculpture;
using levelset::VoxelBox;

using testing::FakeSink;

using CellSet = std::set<std::tuple<int, int, int>>;

CellSet Cells(const std::vector<Int3>& cells) {
  CellSet s;
  for (const Int3& c : cells) s.insert({c.x, c.y, c.z});
  return s;
}

// The leaf cells a LeafDelta's records hold, read back as a replica reads them.
CellSet RecordCells(const v1::LeafDelta& d) {
  levelset::SculptureOptions o;
  o.half_width = 4;
  Sculpture replica = std::move(levelset::MakeEmptySculpture(o)).value();
  auto applied = levelset::ApplyLeafRecords(replica, d.records());
  EXPECT_TRUE(applied.ok()) << applied.status().ToString();
  return applied.ok() ? Cells(applied->cells) : CellSet{};
}

Sculpture Sphere() {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  o.name = "clay";
  return std::move(Sculpture::MakeSphere(o, {0, 0, 0}, 20)).value();
}

std::vector<levelset::EditRequest> Press(Vec3 from, Vec3 to) {
  std::vector<levelset::EditRequest> reqs;
  for (int i = 0; i < 4; ++i) {
    levelset::EditRequest r;
    r.kind = levelset::EditKind::kPress;
    r.tool.kind = levelset::ToolKind::kSphere;
    r.tool.size = {3, 3, 3};
    r.tool.center = from + (to - from) * (i / 3.0);
    r.speed = 30;
    r.dt = 1.0 / 120;
    reqs.push_back(r);
  }
  return reqs;
}

codec::ReplicaSubscription Whole(codec::ReplicaMode mode, uint64_t have_seq = 0) {
  codec::ReplicaSubscription r;
  r.object = "clay";
  r.mode = mode;
  r.have_seq = have_seq;
  return r;
}

class ReplicationHubTest : public ::testing::Test {
 protected:
  // Subscribes and expects acceptance answered before the first frame.
  void Subscribe(FakeSink& sink, const codec::ReplicaSubscription& req, uint64_t seq) {
    bool answered = false;
    hub_.Subscribe(sink.sink(), req, &sculpture_, seq, [&](Status st) {
      EXPECT_TRUE(st.ok()) << st.ToString();
      EXPECT_TRUE(sink.frames.empty()) << "answered after a frame";
      answered = true;
    });
    EXPECT_TRUE(answered);
  }
  // Applies a press stroke as the scene does and returns its changed leaves (seq recorded).
  std::vector<Int3> Edit(uint64_t seq, Vec3 from, Vec3 to) {
    auto r = levelset::ApplyEdits(sculpture_, Press(from, to), settings_);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    EXPECT_FALSE(r->dirty_leaves.empty());
    hub_.RecordVersions("clay", r->dirty_leaves, seq);
    return r->dirty_leaves;
  }

  Sculpture sculpture_ = Sphere();
  levelset::EditSettings settings_;
  ReplicationHub hub_;
};

TEST_F(ReplicationHubTest, WholeSubscriberGetsEveryChangedLeaf) {
  FakeSink a(1);
  Subscribe(a, Whole(codec::ReplicaMode::kLeafDelta), 0);
  ASSERT_EQ(a.frames.size(), 1u);  // the region
  const std::vector<Int3> dirty = Edit(1, {20, -4, 0}, {19, 4, 2});
  hub_.Replicate("clay", sculpture_, dirty, 1, 1, 7, 3, nullptr);
  ASSERT_EQ(a.frames.size(), 2u);
  const v1::ServerMessage m = a.Message(1);
  ASSERT_TRUE(m.has_leaf_delta());
  const v1::LeafDelta& d = m.leaf_delta();
  EXPECT_EQ(d.object(), "clay");
  EXPECT_EQ(d.global_seq(), 1u);
  EXPECT_EQ(d.client_id(), 7u);
  EXPECT_EQ(d.client_seq(), 3u);
  EXPECT_FALSE(d.replace_region());
  EXPECT_EQ(d.record_count(), dirty.size());
  EXPECT_EQ(RecordCells(d), Cells(dirty));
  EXPECT_EQ(d.volume(), levelset::CaptureReplayState(sculpture_).volume);
}

TEST_F(ReplicationHubTest, InterestSubscriberGetsOnlyLeavesInsideItsBoxPlusHalo) {
  FakeSink near(1);
  codec::ReplicaSubscription req = Whole(codec::ReplicaMode::kLeafDelta);
  req.interest = codec::InterestBox{{14, -4, -4}, {24, 4, 4}};
  Subscribe(near, req, 0);
  FakeSink far(2);
  req.interest = codec::InterestBox{{-24, -4, -4}, {-14, 4, 4}};
  Subscribe(far, req, 0);
  ASSERT_EQ(near.frames.size(), 1u);
  ASSERT_EQ(far.frames.size(), 1u);
  // Every leaf of the sphere "changed": what each receives is exactly what its held box
  // (interest dilated by the halo) intersects.
  const VoxelBox everything{{-40, -40, -40}, {40, 40, 40}};
  const std::vector<Int3> all = levelset::OccupiedLeafCells(sculpture_, everything);
  hub_.RecordVersions("clay", all, 1);
  hub_.Replicate("clay", sculpture_, all, 1, 1, 7, 1, nullptr);
  ASSERT_EQ(near.frames.size(), 2u);
  const VoxelBox held =
      levelset::WorldToVoxelBox(sculpture_, {14, -4, -4}, {24, 4, 4}).Dilated(kReplicaHaloVoxels);
  CellSet expected;
  for (const Int3& c : all) {
    const VoxelBox leaf{c, {c.x + 7, c.y + 7, c.z + 7}};
    if (held.Intersects(leaf)) expected.insert({c.x, c.y, c.z});
  }
  ASSERT_FALSE(expected.empty());
  ASSERT_LT(expected.size(), all.size());
  const v1::ServerMessage m = near.Message(1);
  const v1::LeafDelta& d = m.leaf_delta();
  EXPECT_EQ(RecordCells(d), expected);
  // The halo counts: some leaves sent lie outside the interest box itself.
  const VoxelBox box = levelset::WorldToVoxelBox(sculpture_, {14, -4, -4}, {24, 4, 4});
  size_t halo_only = 0;
  for (const auto& [x, y, z] : expected) {
    if (!box.Intersects(VoxelBox{{x, y, z}, {x + 7, y + 7, z + 7}})) ++halo_only;
  }
  EXPECT_GT(halo_only, 0u);
  // An edit far from a box reaches nobody holding it (leaf-delta mode, no replay form).
  const std::vector<Int3> dirty = Edit(2, {20, -4, 0}, {19, 4, 2});
  hub_.Replicate("clay", sculpture_, dirty, 2, 2, 7, 2, nullptr);
  EXPECT_EQ(near.frames.size(), 3u);
  EXPECT_EQ(far.frames.size(), 2u);  // only the "everything" delta
}

TEST_F(ReplicationHubTest, SubscriberBehindTheKnownVersionsGetsTheLeavesWrittenSince) {
  const std::vector<Int3> first = Edit(1, {20, -4, 0}, {19, 4, 2});
  const std::vector<Int3> second = Edit(2, {-20, -4, 0}, {-19, 4, 2});
  FakeSink behind(1);
  Subscribe(behind, Whole(codec::ReplicaMode::kLeafDelta, /*have_seq=*/1), 2);
  ASSERT_EQ(behind.frames.size(), 1u);
  const v1::ServerMessage m = behind.Message(0);
  const v1::LeafDelta& d = m.leaf_delta();
  EXPECT_FALSE(d.replace_region());
  EXPECT_EQ(d.global_seq(), 2u);
  CellSet newer = Cells(second);
  EXPECT_EQ(RecordCells(d), newer);
  EXPECT_EQ(d.region_min_size(), 3);
  // Older than the versions known (a replica from before a restart): its region anew.
  hub_.set_versions_floor(2);
  FakeSink stale(2);
  Subscribe(stale, Whole(codec::ReplicaMode::kLeafDelta, /*have_seq=*/1), 2);
  ASSERT_EQ(stale.frames.size(), 1u);
  EXPECT_TRUE(stale.Message(0).leaf_delta().replace_region());
  EXPECT_GT(stale.Message(0).leaf_delta().record_count(), first.size() + second.size());
}

TEST_F(ReplicationHubTest, RefusesHaveSeqAheadOfTheServerAndUnknownObjects) {
  FakeSink a(1);
  Status answer;
  hub_.Subscribe(a.sink(), Whole(codec::ReplicaMode::kReplay, 5), &sculpture_, 4,
                 [&](Status st) { answer = st; });
  EXPECT_EQ(answer.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(answer.message().find("Subscribe.have_seq=5"), std::string::npos) << answer.message();
  hub_.Subscribe(a.sink(), Whole(codec::ReplicaMode::kReplay), nullptr, 4,
                 [&](Status st) { answer = st; });
  EXPECT_EQ(answer.code(), Status::Code::kNotFound);
  codec::ReplicaSubscription wide = Whole(codec::ReplicaMode::kReplay);
  wide.interest = codec::InterestBox{{0, 0, 0}, {kMaxInterestVoxels + 1.0, 1, 1}};
  hub_.Subscribe(a.sink(), wide, &sculpture_, 4, [&](Status st) { answer = st; });
  EXPECT_EQ(answer.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(answer.message().find("Subscribe.interest.max.x"), std::string::npos);
  codec::InterestChange move;
  move.object = "clay";
  hub_.SetInterest(1, move, &sculpture_, 4, [&](Status st) { answer = st; });
  EXPECT_EQ(answer.code(), Status::Code::kFailedPrecondition);
  EXPECT_TRUE(a.frames.empty());
  EXPECT_EQ(hub_.subscriber_count(), 0u);
}

TEST_F(ReplicationHubTest, ReplayModeGetsTheEditAndLeafDeltaModeItsLeaves) {
  FakeSink replay(1);
  FakeSink leaves(2);
  Subscribe(replay, Whole(codec::ReplicaMode::kReplay), 0);
  Subscribe(leaves, Whole(codec::ReplicaMode::kLeafDelta), 0);
  v1::Stroke stroke;
  stroke.set_object("clay");
  stroke.set_client_seq(9);
  const std::string source = stroke.SerializeAsString();
  const auto reqs = Press({20, -4, 0}, {19, 4, 2});
  EditReplay form;
  form.source = &source;
  form.before = levelset::CaptureReplayState(sculpture_);
  form.footprint = levelset::FootprintOf(sculpture_, reqs, settings_);
  auto r = levelset::ApplyEdits(sculpture_, reqs, settings_);
  ASSERT_TRUE(r.ok());
  hub_.RecordVersions("clay", r->dirty_leaves, 4);
  hub_.Replicate("clay", sculpture_, r->dirty_leaves, 1, 4, 7, 9, &form);
  ASSERT_EQ(replay.frames.size(), 2u);
  const v1::ServerMessage m = replay.Message(1);
  ASSERT_TRUE(m.has_edit());
  EXPECT_EQ(m.edit().global_seq_first(), 1u);
  EXPECT_EQ(m.edit().client_id(), 7u);
  EXPECT_EQ(m.edit().stroke().client_seq(), 9u);
  EXPECT_EQ(m.edit().volume(), form.before.volume);
  EXPECT_EQ(m.edit().leaves_hash(), levelset::LeavesHash(sculpture_, r->dirty_leaves));
  EXPECT_EQ(m.edit().dirty_leaves(), r->dirty_leaves.size());
  ASSERT_EQ(leaves.frames.size(), 2u);
  EXPECT_TRUE(leaves.Message(1).has_leaf_delta());
  EXPECT_EQ(leaves.Message(1).leaf_delta().global_seq(), 4u);

  // A replay replica whose box does not hold the footprint gets the leaves instead.
  FakeSink partial(3);
  codec::ReplicaSubscription req = Whole(codec::ReplicaMode::kReplay);
  req.interest = codec::InterestBox{{-4, -4, -4}, {4, 4, 4}};
  Subscribe(partial, req, 4);
  const auto reqs2 = Press({-4, 19, 0}, {4, 19, 0});
  form.before = levelset::CaptureReplayState(sculpture_);
  form.footprint = levelset::FootprintOf(sculpture_, reqs2, settings_);
  auto r2 = levelset::ApplyEdits(sculpture_, reqs2, settings_);
  ASSERT_TRUE(r2.ok());
  hub_.RecordVersions("clay", r2->dirty_leaves, 8);
  hub_.Replicate("clay", sculpture_, r2->dirty_leaves, 5, 8, 7, 10, &form);
  ASSERT_EQ(partial.frames.size(), 2u);
  EXPECT_TRUE(partial.Message(1).has_leaf_delta());
  EXPECT_TRUE(replay.Message(2).has_edit());
}

TEST_F(ReplicationHubTest, StatsCountWhatWasSentAndFramesAreShared) {
  FakeSink a(1);
  FakeSink b(2);
  Subscribe(a, Whole(codec::ReplicaMode::kLeafDelta), 0);
  Subscribe(b, Whole(codec::ReplicaMode::kLeafDelta), 0);
  EXPECT_EQ(hub_.stats().resyncs.load(), 2u);
  const uint64_t region_bytes = a.frames[0]->size() + b.frames[0]->size();
  EXPECT_EQ(hub_.stats().leaf_delta_bytes.load(), region_bytes);
  const std::vector<Int3> dirty = Edit(1, {20, -4, 0}, {19, 4, 2});
  hub_.Replicate("clay", sculpture_, dirty, 1, 1, 7, 1, nullptr);
  ASSERT_EQ(a.frames.size(), 2u);
  ASSERT_EQ(b.frames.size(), 2u);
  EXPECT_EQ(a.frames[1], b.frames[1]);  // one frame built, shared
  EXPECT_EQ(hub_.stats().leaf_deltas.load(), 1u);
  EXPECT_EQ(hub_.stats().leaf_delta_bytes.load(), region_bytes + a.frames[1]->size());
  EXPECT_EQ(hub_.stats().broadcasts.load(), 0u);

  hub_.Unsubscribe(1);
  hub_.Replicate("clay", sculpture_, dirty, 2, 2, 7, 2, nullptr);
  EXPECT_EQ(a.frames.size(), 2u);
  EXPECT_EQ(b.frames.size(), 3u);
  EXPECT_EQ(hub_.stats().leaf_deltas.load(), 2u);

  hub_.ReportDivergence(2, codec::Divergence{"clay", 2, 1, 2});
  EXPECT_EQ(hub_.stats().divergences.load(), 1u);
}

}  // namespace
}  // namespace sculpt::server
