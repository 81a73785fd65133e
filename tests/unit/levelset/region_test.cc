// Replication primitives: replay equals apply, leaf records round-trip exactly, partial
// replicas converge over their region, and bad records are refused.
#include "sculpt/levelset/region.h"

#include <gtest/gtest.h>
#include <zstd.h>

#include <cstring>
#include <random>

#include "sculpt/levelset/edit.h"

namespace sculpt::levelset {
namespace {

Sculpture Sphere(double r = 20) {
  SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  o.name = "clay";
  return std::move(Sculpture::MakeSphere(o, {0, 0, 0}, r)).value();
}

std::vector<EditRequest> Stroke(Vec3 from, Vec3 to, int poses, EditKind kind = EditKind::kPress) {
  std::vector<EditRequest> reqs;
  for (int i = 0; i < poses; ++i) {
    const double t = poses == 1 ? 0 : double(i) / (poses - 1);
    EditRequest r;
    r.kind = kind;
    r.tool.kind = ToolKind::kSphere;
    r.tool.size = {3, 3, 3};
    r.tool.center = from + (to - from) * t;
    r.speed = 30;
    r.dt = 1.0 / 120;
    reqs.push_back(r);
  }
  return reqs;
}

TEST(RegionTest, ReplayOnACloneIsBitIdentical) {
  Sculpture server = Sphere();
  Sculpture replica = server.Clone();
  const EditSettings s;
  for (int k = 0; k < 6; ++k) {
    const auto reqs = Stroke({20.0 - k, -5.0 + k, 0}, {19.0 - k, 5.0 + k, 2}, 4,
                             k % 3 == 2 ? EditKind::kAdd : EditKind::kPress);
    const ReplayState state = CaptureReplayState(server);
    auto a = ApplyEdits(server, reqs, s);
    ASSERT_TRUE(a.ok()) << a.status().ToString();
    auto b = ReplayEdits(replica, reqs, s, state);
    ASSERT_TRUE(b.ok()) << b.status().ToString();
    EXPECT_EQ(a->dirty_leaves, b->dirty_leaves);
    EXPECT_EQ(LeavesHash(server, a->dirty_leaves), LeavesHash(replica, b->dirty_leaves));
  }
  EXPECT_EQ(server.StateHash(), replica.StateHash());
  EXPECT_EQ(server.volume(), replica.volume());
}

TEST(RegionTest, LeafRecordsOfEveryCellRebuildTheRegionExactly) {
  Sculpture server = Sphere();
  const VoxelBox box{{-30, -30, -30}, {30, 30, 30}};
  LeafRecordStats st;
  const std::string bytes = EncodeLeafRecords(server, OccupiedLeafCells(server, box), nullptr, 3,
                                              &st);
  EXPECT_GT(st.leaves, 100u);
  EXPECT_GT(st.uniform, 0u);  // the inside tiles
  EXPECT_LT(st.compressed_bytes, st.raw_bytes);
  SculptureOptions o;
  o.half_width = 4;
  Sculpture replica = std::move(MakeEmptySculpture(o)).value();
  auto r = ApplyLeafRecords(replica, bytes);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(RegionHash(server, box), RegionHash(replica, box));
  EXPECT_NEAR(replica.ComputeVolume(), server.ComputeVolume(), 1e-6 * server.ComputeVolume());
}

TEST(RegionTest, PartialReplicaReplaysEditsInsideItsRegion) {
  Sculpture server = Sphere();
  const EditSettings s;
  const VoxelBox interest{{10, -12, -12}, {30, 12, 12}};
  const VoxelBox held = interest.Dilated(12);
  SculptureOptions o;
  o.half_width = 4;
  Sculpture replica = std::move(MakeEmptySculpture(o)).value();
  ASSERT_TRUE(ApplyLeafRecords(replica, EncodeLeafRecords(server, OccupiedLeafCells(server, held),
                                                          nullptr)).ok());
  int replayed = 0;
  for (int k = 0; k < 5; ++k) {
    const auto reqs = Stroke({20, -4.0 + 2 * k, 0}, {19.5, -3.0 + 2 * k, 1}, 3);
    const EditFootprint f = FootprintOf(server, reqs, s);
    const ReplayState state = CaptureReplayState(server);
    auto a = ApplyEdits(server, reqs, s);
    ASSERT_TRUE(a.ok());
    const VoxelBox fb{f.min, f.max};
    ASSERT_TRUE(held.Contains(fb)) << "footprint must fit the held region in this test";
    auto b = ReplayEdits(replica, reqs, s, state);
    ASSERT_TRUE(b.ok()) << b.status().ToString();
    EXPECT_EQ(LeavesHash(server, a->dirty_leaves), LeavesHash(replica, b->dirty_leaves));
    ++replayed;
  }
  EXPECT_EQ(replayed, 5);
  EXPECT_EQ(RegionHash(server, interest), RegionHash(replica, interest));
}

TEST(RegionTest, VersionedDeltaResyncsAStaleFullReplica) {
  Sculpture server = Sphere();
  Sculpture replica = server.Clone();
  LeafVersions versions;
  const EditSettings s;
  uint64_t seq = 0;
  for (int k = 0; k < 8; ++k) {
    const auto reqs = Stroke({0, 20.0 - 0.5 * k, -3.0 + k}, {2, 19.5 - 0.5 * k, -2.0 + k}, 2,
                             k == 5 ? EditKind::kSubtract : EditKind::kPress);
    auto a = ApplyEdits(server, reqs, s);
    ASSERT_TRUE(a.ok());
    seq += reqs.size();
    versions.Record(a->dirty_leaves, seq);
  }
  ASSERT_NE(server.StateHash(), replica.StateHash());
  const auto cells = versions.NewerThan(0);
  ASSERT_FALSE(cells.empty());
  auto r = ApplyLeafRecords(replica, EncodeLeafRecords(server, cells, &versions));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->max_version, seq);
  EXPECT_EQ(server.StateHash(), replica.StateHash());
  EXPECT_TRUE(versions.NewerThan(seq).empty());
}

TEST(RegionTest, BadRecordsAreRefusedAndChangeNothing) {
  Sculpture server = Sphere(10);
  std::string good = EncodeLeafRecords(server, OccupiedLeafCells(server, {{-16, -16, -16},
                                                                          {16, 16, 16}}),
                                       nullptr);
  Sculpture replica = Sphere(10);
  const uint64_t h = replica.StateHash();
  std::mt19937 rng(7);
  int refused = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::string bad = good;
    if (trial == 0) bad.resize(5);
    else if (trial == 1) bad[0] = static_cast<char>(0xFF);
    else bad[8 + rng() % (bad.size() - 8)] ^= static_cast<char>(1 + rng() % 255);
    auto r = ApplyLeafRecords(replica, bad);
    ASSERT_FALSE(r.ok()) << "trial " << trial;  // zstd's content checksum catches every flip
    ++refused;
    EXPECT_EQ(replica.StateHash(), h);
  }
  EXPECT_EQ(refused, 200);
  EXPECT_FALSE(ApplyLeafRecords(replica, "").ok());
}

// A uniform record becomes an inactive tile, so its value must be +-background like every other
// inactive value. Found by the leaf_records fuzz target: a uniform 0.3 was written as a tile and
// the replica was no longer a valid level set (CheckLevelSet: a tile not equal to +-background).
TEST(RegionTest, RejectsUniformValueOtherThanBackground) {
  auto records = [](float uniform) {
    std::string raw = "SLR1";
    const uint32_t n = 1;
    const int32_t origin[3] = {64, 64, 64};
    const uint64_t version = 0;
    raw.append(reinterpret_cast<const char*>(&n), sizeof n);
    raw.append(reinterpret_cast<const char*>(origin), sizeof origin);
    raw.append(reinterpret_cast<const char*>(&version), sizeof version);
    raw.push_back(0);  // a uniform record
    raw.append(reinterpret_cast<const char*>(&uniform), sizeof uniform);
    std::string out(8 + ZSTD_compressBound(raw.size()), '\0');
    const uint64_t raw_size = raw.size();
    std::memcpy(out.data(), &raw_size, 8);
    out.resize(8 + ZSTD_compress(out.data() + 8, out.size() - 8, raw.data(), raw.size(), 1));
    return out;
  };
  Sculpture replica = Sphere(10);  // voxel 1, half-width 4: background 4
  const uint64_t h = replica.StateHash();
  auto bad = ApplyLeafRecords(replica, records(0.3f));
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Status::Code::kDataLoss);
  ASSERT_NE(bad.status().violation(), nullptr);
  EXPECT_EQ(bad.status().violation()->field, "leaf records: uniform value of record 0");
  EXPECT_EQ(replica.StateHash(), h);
  auto inside = ApplyLeafRecords(replica, records(-4.0f));
  ASSERT_TRUE(inside.ok()) << inside.status().ToString();
  EXPECT_TRUE(replica.CheckLevelSet(8).ok());
}

// Recovery from a snapshot plus the log tail must start from the tracked volume the live
// server held, not a recomputation (they differ in the last bits, and compensation aims at
// their difference from the reference).
TEST(RegionTest, SavedFileKeepsTheTrackedVolumeBitForBit) {
  Sculpture live = Sphere();
  const EditSettings s;
  for (int k = 0; k < 5; ++k) {
    ASSERT_TRUE(ApplyEdits(live, Stroke({20.0 - k, 0, 0}, {19.0 - k, 3, 1}, 3), s).ok());
  }
  ASSERT_NE(live.volume(), live.ComputeVolume());  // the two differ: the test can fail
  auto bytes = live.SerializeVdb();
  ASSERT_TRUE(bytes.ok());
  auto loaded = Sculpture::DeserializeVdb(*bytes);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_EQ(loaded->volume(), live.volume());
  EXPECT_EQ(loaded->reference_volume(), live.reference_volume());
  // And the next edit gives the same state on both.
  const auto next = Stroke({10, 17, 5}, {11, 16.5, 5.5}, 3);
  ASSERT_TRUE(ApplyEdits(live, next, s).ok());
  ASSERT_TRUE(ApplyEdits(*loaded, next, s).ok());
  EXPECT_EQ(loaded->StateHash(), live.StateHash());
}

TEST(RegionTest, BoxArithmetic) {
  const VoxelBox a{{0, 0, 0}, {9, 9, 9}};
  EXPECT_EQ(a.Volume(), 1000u);
  EXPECT_TRUE(a.Contains({{1, 1, 1}, {9, 9, 9}}));
  EXPECT_FALSE(a.Contains({{1, 1, 1}, {10, 9, 9}}));
  EXPECT_TRUE(a.Intersects({{9, 9, 9}, {20, 20, 20}}));
  EXPECT_FALSE(a.Intersects({{10, 0, 0}, {20, 20, 20}}));
  EXPECT_TRUE((VoxelBox{{5, 0, 0}, {4, 0, 0}}).Empty());
  EXPECT_EQ(AllLeafCells({{0, 0, 0}, {15, 7, 7}}).size(), 2u);
  const VoxelBox huge = a.Dilated(2000000000);
  EXPECT_FALSE(huge.Empty());
  EXPECT_GT(huge.Volume(), 0u);
}

}  // namespace
}  // namespace sculpt::levelset
