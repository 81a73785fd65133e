#include "sculpt/mesh/mesh_stats.h"

#include <gtest/gtest.h>

#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/draco_chunk_codec.h"
#include "unit/mesh/mesh_test_util.h"

namespace sculpt::mesh {
namespace {

TEST(MeshStatsTest, SphereIsOneClosedOutwardPieceOfGenusZero) {
  const levelset::Sculpture s = testing::Sphere(20);
  const MeshTopology t = ComputeTopology(MeshWhole(s));
  EXPECT_TRUE(t.closed_manifold()) << t.boundary_edges << " open, " << t.non_manifold_edges
                                   << " non-manifold, " << t.inconsistent_edges << " flipped";
  EXPECT_EQ(t.components, 1u);
  EXPECT_EQ(t.genus, 0);
  EXPECT_EQ(t.euler, 2);
  // Wound outward: the enclosed volume is positive and is the sculpture's tracked volume.
  EXPECT_GT(t.signed_volume, 0.0);
  EXPECT_NEAR(t.signed_volume, s.volume(), 0.01 * s.volume());
}

TEST(MeshStatsTest, TorusHasGenusOne) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 3;
  auto s = levelset::Sculpture::MakeTorus(o, {0.2, 0.1, -0.3}, 16.0, 6.0);
  ASSERT_TRUE(s.ok()) << s.status();
  const MeshTopology t = ComputeTopology(MeshWhole(*s));
  EXPECT_TRUE(t.closed_manifold());
  EXPECT_EQ(t.components, 1u);
  EXPECT_EQ(t.genus, 1);
  EXPECT_GT(t.signed_volume, 0.0);
}

TEST(MeshStatsTest, CountsAHoleAndAFlippedFace) {
  TriangleMesh m = MeshWhole(testing::Sphere(12));
  ASSERT_GT(m.face_count(), 10u);
  TriangleMesh holed = m;
  holed.indices.erase(holed.indices.begin(), holed.indices.begin() + 3);
  const MeshTopology h = ComputeTopology(holed);
  EXPECT_EQ(h.boundary_edges, 3u);
  EXPECT_EQ(h.genus, -1);
  TriangleMesh flipped = m;
  std::swap(flipped.indices[1], flipped.indices[2]);
  EXPECT_EQ(ComputeTopology(flipped).inconsistent_edges, 3u);
}

TEST(MeshStatsTest, TwoSpheresAreTwoComponents) {
  TriangleMesh a = MeshWhole(testing::Sphere(8));
  TriangleMesh both = a;
  const uint32_t offset = static_cast<uint32_t>(a.vertex_count());
  for (size_t i = 0; i < a.positions.size(); ++i) {
    both.positions.push_back(a.positions[i] + (i % 3 == 0 ? 40.0f : 0.0f));
  }
  for (uint32_t i : a.indices) both.indices.push_back(i + offset);
  const MeshTopology t = ComputeTopology(both);
  EXPECT_EQ(t.components, 2u);
  EXPECT_EQ(t.genus, 0);
  EXPECT_NEAR(t.signed_volume, 2 * SignedVolume(a), 1e-6 * t.signed_volume);
}

// The viewers' Draco chunks, decoded and put together, enclose the object's volume with
// positive sign (they were inside out: three.js drew the far inside of the object).
TEST(MeshStatsTest, DecodedChunksAreWoundOutwardAndCloseUp) {
  const levelset::Sculpture s = testing::CutSphere(30);
  DracoChunkOptions o;
  auto frame = FrameAround(s, 4);
  ASSERT_TRUE(frame.ok()) << frame.status();
  o.frame = *frame;
  TriangleMesh all;
  for (const ChunkKey& key : AllChunks(s)) {
    auto chunk = MeshChunk(s, key);
    ASSERT_TRUE(chunk.ok()) << chunk.status();
    if (chunk->mesh.empty()) continue;
    auto encoded = EncodeChunk(chunk->mesh, o);
    ASSERT_TRUE(encoded.ok()) << encoded.status();
    auto decoded = DecodeChunk(encoded->bytes);
    ASSERT_TRUE(decoded.ok()) << decoded.status();
    EXPECT_GT(SignedVolume(chunk->mesh), 0.0) << "chunk " << key.x << "," << key.y << "," << key.z;
    testing::Append(decoded->mesh, &all);
  }
  const MeshTopology t = ComputeTopology(WeldByPosition(all));
  EXPECT_EQ(t.boundary_edges, 0u);
  EXPECT_EQ(t.non_manifold_edges, 0u);
  EXPECT_EQ(t.inconsistent_edges, 0u);
  EXPECT_EQ(t.components, 1u);
  const double whole = SignedVolume(MeshWhole(s));
  EXPECT_GT(t.signed_volume, 0.0);
  EXPECT_NEAR(t.signed_volume, whole, 0.005 * whole);
  EXPECT_NEAR(whole, s.volume(), 0.01 * s.volume());
}

}  // namespace
}  // namespace sculpt::mesh
